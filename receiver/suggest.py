"""Suggestions for one-line input errors: "did you mean" for a mistyped config key or choice (difflib), and
the refusal of a binary file (a recording) given where a text config is expected."""
from __future__ import annotations

import difflib
import os

from .errors import UserError

#: bytes looked at to tell a binary file from text
_PEEK = 1 << 16


def did_you_mean(word, options) -> str:
    """``" (did you mean 'x'?)"`` for the closest of ``options`` to ``word``, or "" when none is close."""
    opts = [str(o) for o in options]
    m = difflib.get_close_matches(str(word), opts, n=1, cutoff=0.6)
    if not m:                     # a different case or separator: 'PLL_BW_HZ', 'pll-bw-hz'
        norm = {o.lower().replace("-", "_"): o for o in opts}
        hit = norm.get(str(word).lower().replace("-", "_"))
        m = [hit] if hit else []
    return f" (did you mean '{m[0]}'?)" if m else ""


def looks_binary(data: bytes) -> bool:
    """NUL bytes, or bytes that are not UTF-8 text (the cut at the end of the peek excepted)."""
    if b"\x00" in data:
        return True
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        return exc.start < len(data) - 4
    return False


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
