"""Metadata files beside a recording: SigMF ``.sigmf-meta`` (plain JSON, no dependency).

For an input ``<stem>.sigmf-data`` or ``<stem>.<ext>`` the file ``<stem>.sigmf-meta`` is read when present:

  global.core:datatype        -> input.format (SigMF names are format aliases, receiver/source/io.py);
                                 ``gnssrx:format``/``gnssrx:bit_order``/``gnssrx:encoding`` (written by
                                 ``gnssrx simulate`` for packed formats, which SigMF has no name for) win
  global.core:sample_rate     -> input.sample_rate_hz
  captures[0].core:frequency  -> input.if_hz = carrier - frequency (the signal's carrier relative to the
                                 recording's centre; for real data, the frequency mapped to 0 Hz)
  captures[0].core:datetime   -> input.start_gps_week / start_gps_tow_s (UTC + leap seconds)
  captures[0].core:sample_start, global.gnssrx:header_bytes -> input.header_bytes (bytes)

A config key left at its default takes the metadata's value; a key set to another value that disagrees
with the metadata is an error (one line).
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import os

from ..errors import UserError
from ..gnss.time import GPS_EPOCH, WEEK_S, leap_seconds_at
from .io import ALIASES, FORMATS, bits_per_sample, resolve_format

SIGMF_EXT = ".sigmf-meta"
SIGMF_VERSION = "1.0.0"
# our format -> SigMF datatype (packed formats: raw bytes plus gnssrx:format)
SIGMF_DATATYPE = {ours: sig for sig, ours in ALIASES.items() if "_" in sig or sig in ("ci8", "cu8", "ri8")}


def meta_path(data_path) -> str:
    p = os.fspath(data_path)
    stem = p[:-len(".sigmf-data")] if p.endswith(".sigmf-data") else os.path.splitext(p)[0]
    return stem + SIGMF_EXT


def _utc_to_gps(text: str) -> tuple[int, float]:
    try:
        t = _dt.datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        raise UserError(f"SigMF core:datetime '{text}' is not an ISO 8601 time") from None
    if t.tzinfo is not None:
        t = t.astimezone(_dt.timezone.utc).replace(tzinfo=None)
    sec = (t - GPS_EPOCH).total_seconds()
    sec += leap_seconds_at(GPS_EPOCH + _dt.timedelta(seconds=sec))
    week = int(sec // WEEK_S)
    return week, sec - week * WEEK_S


def read_sigmf(path, carrier_hz: float) -> dict | None:
    """Input keys from the SigMF metadata beside ``path`` ({} keys absent), None without a file."""
    mp = meta_path(path)
    if not os.path.isfile(mp):
        return None
    try:
        with open(mp) as fh:
            meta = json.load(fh)
        g = meta["global"]
        caps = meta.get("captures") or [{}]
    except (OSError, ValueError, KeyError, TypeError):
        raise UserError(f"SigMF metadata {mp} is not valid JSON with a 'global' object") from None
    out = {}
    fmt = g.get("gnssrx:format") or g.get("core:datatype")
    if fmt is not None:
        if fmt not in FORMATS and fmt not in ALIASES:
            raise UserError(f"SigMF metadata {mp}: datatype '{fmt}' is not supported (one of "
                            f"{', '.join(SIGMF_DATATYPE.values())})")
        out["format"] = resolve_format(fmt).name
    for key in ("bit_order", "encoding"):
        if f"gnssrx:{key}" in g:
            out[key] = g[f"gnssrx:{key}"]
    if "core:sample_rate" in g:
        out["sample_rate_hz"] = float(g["core:sample_rate"])
    c0 = caps[0] if isinstance(caps, list) and caps else {}
    if "core:frequency" in c0:
        out["if_hz"] = round(carrier_hz - float(c0["core:frequency"]), 6)
    if "core:datetime" in c0:
        out["start_gps_week"], out["start_gps_tow_s"] = _utc_to_gps(str(c0["core:datetime"]))
    header = int(g.get("gnssrx:header_bytes", 0))
    if c0.get("core:sample_start") and "format" in out:
        header += int(c0["core:sample_start"]) * bits_per_sample(out["format"]) // 8
    if header:
        out["header_bytes"] = header
    return out


def write_sigmf(data_path, fmt: str, sample_rate_hz: float, if_hz: float, carrier_hz: float,
                start_week: int | None = None, start_tow_s: float | None = None, description: str = "",
                bit_order: str = "msb_first", encoding: str = "sign_magnitude", version: str = "",
                meta: str | None = None) -> str:
    """Write ``<stem>.sigmf-meta`` (or ``meta``) for a recording; returns its path."""
    f = resolve_format(fmt)
    g = {"core:datatype": SIGMF_DATATYPE.get(f.name, "ru8"), "core:sample_rate": float(sample_rate_hz),
         "core:version": SIGMF_VERSION, "core:description": description,
         "core:recorder": f"gnssrx simulate {version}".strip()}
    if f.name not in SIGMF_DATATYPE:
        g["gnssrx:format"] = f.name
        if not f.integer:
            g["gnssrx:bit_order"], g["gnssrx:encoding"] = bit_order, encoding
    cap = {"core:sample_start": 0, "core:frequency": float(carrier_hz - if_hz)}
    if start_week is not None and start_tow_s is not None:
        gps = GPS_EPOCH + _dt.timedelta(seconds=start_week * WEEK_S + start_tow_s)
        utc = gps - _dt.timedelta(seconds=leap_seconds_at(gps))
        cap["core:datetime"] = utc.strftime("%Y-%m-%dT%H:%M:%S.%f") + "Z"
    mp = meta or meta_path(data_path)
    with open(mp, "w") as fh:
        json.dump({"global": g, "captures": [cap], "annotations": []}, fh, indent=2)
        fh.write("\n")
    return mp


def apply_metadata(inp, defaults: dict, carrier_hz: float) -> dict:
    """Fill the input section ``inp`` (a config Section) from the metadata beside ``inp.path``.

    ``defaults`` holds the schema defaults of the input keys: a key at its default takes the metadata's
    value; any other value must agree with it (UserError naming the key).  Returns the metadata used.
    """
    meta = read_sigmf(inp.path, carrier_hz)
    if not meta:
        return {}
    for key, value in meta.items():
        cur = inp[key]
        if key == "format":
            cur = resolve_format(cur).name
        same = (cur == value if isinstance(value, str) or key == "start_gps_week"
                else cur is not None and math.isclose(float(cur), float(value), rel_tol=1e-9, abs_tol=1e-3))
        if key == "start_gps_tow_s" and cur is not None:
            same = abs(float(cur) - float(value)) <= 1.0          # a hint: datetime resolution
        if same:
            continue
        if cur == defaults.get(key):
            inp._values[key] = value          # sections are read-only to users; this fills in the input
            continue
        raise UserError(f"config key 'input.{key}' = {cur!r} disagrees with {meta_path(inp.path)} "
                        f"({value!r}); remove the key or fix the metadata")
    return meta
