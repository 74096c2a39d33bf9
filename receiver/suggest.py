"""Suggestions for one-line input errors: "did you mean" for a mistyped config key or choice (difflib), and
the refusal of a binary file (a recording) given where a text config is expected."""
from __future__ import annotations

import difflib
import os

import numpy as np

from .errors import UserError

#: bytes looked at to tell a binary file from text
_PEEK = 1 << 16


def did_you_mean(word, options, prefix: str = "") -> str:
    """``" (did you mean 'x'?)"`` for the closest of ``options`` to ``word``, or "" when none is close;
    ``prefix`` (a dotted section, 'tracking.') is put before the suggestion, not compared."""
    opts = [str(o) for o in options]
    m = difflib.get_close_matches(str(word), opts, n=1, cutoff=0.6)
    if not m:                     # a different case or separator: 'PLL_BW_HZ', 'pll-bw-hz'
        norm = {o.lower().replace("-", "_"): o for o in opts}
        hit = norm.get(str(word).lower().replace("-", "_"))
        m = [hit] if hit else []
    return f" (did you mean '{prefix}{m[0]}'?)" if m else ""


def looks_binary(data: bytes) -> bool:
    """NUL bytes, or many control characters or bytes >= 0x80 that are not UTF-8: samples, not text (a
    text in another encoding -- Latin-1 -- has a few high bytes among printable ASCII; read_utf8 names
    it)."""
    if not data:
        return False
    if b"\x00" in data:
        return True
    b = np.frombuffer(data, "u1")
    control = ((b < 0x20) & ~((b == 9) | (b == 10) | (b == 13) | (b == 12))).mean()
    try:
        data.decode("utf-8")
        return control > 0.05
    except UnicodeDecodeError:
        return control > 0.05 or (b >= 0x80).mean() > 0.3


def refuse_binary(path, what: str = "file") -> None:
    """A UserError when ``path`` holds binary data; for a config: it looks like a recording."""
    try:
        with open(os.fspath(path), "rb") as fh:
            head = fh.read(_PEEK)
    except OSError:
        return                    # the caller reports unreadable files
    if not looks_binary(head):
        return
    if "config" in what:
        raise UserError(f"{what} {os.fspath(path)} looks like a recording (binary), not a YAML config: pass it "
                        f"with --input / input.path")
    raise UserError(f"{what} {os.fspath(path)} holds binary data, not text")


def check_list_item(item, key: str, required: tuple, allowed: tuple, what: str) -> None:
    """One entry ``key`` (e.g. ``impairments.tones[0]``) of a list of mappings in a config: a mapping holding
    ``required``, no key outside ``allowed`` (with a did-you-mean); else a one-line :class:`UserError`
    ("must be a mapping with ``what``")."""
    if not isinstance(item, dict) or any(k not in item for k in required):
        raise UserError(f"config key '{key}' must be a mapping with {what}")
    unknown = set(item) - set(allowed)
    if unknown:
        raise UserError(f"unknown config key '{key}.{sorted(unknown)[0]}'" + did_you_mean(sorted(unknown)[0], allowed))
