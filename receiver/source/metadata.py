"""Metadata files beside a recording: SigMF ``.sigmf-meta`` (plain JSON, no dependency) and PocketSDR ``.tag``.

For an input ``<stem>.sigmf-data`` or ``<stem>.<ext>`` the file ``<stem>.sigmf-meta`` is read when present:

  global.core:datatype        -> input.format (SigMF names are format aliases, receiver/source/io.py);
                                 ``gnssrx:format``/``gnssrx:bit_order``/``gnssrx:encoding`` (written by
                                 ``gnssrx simulate`` for packed formats, which SigMF has no name for) win
  global.core:sample_rate     -> input.sample_rate_hz
  captures[0].core:frequency  -> input.if_hz = carrier - frequency (the signal's carrier relative to the
                                 recording's centre; for real data, the frequency mapped to 0 Hz)
  captures[0].core:datetime   -> input.start_gps_week / start_gps_tow_s (UTC + leap seconds)
  captures[0].core:sample_start, global.gnssrx:header_bytes -> input.header_bytes (bytes)

PocketSDR ``<file>.tag`` (the input's full name plus ``.tag``; written by PocketSDR's ``pocket_dump`` /
``pocket_trk`` IF logs): text lines ``KEY = value`` --

  FMT   INT8 (one int8 per sample; with IQ = 1 a real signal), INT8X2 (int8 I, Q pairs whose Q has the
        opposite sign: read with input.iq_swap, a spectral inversion up to a constant phase), CS8 / CS16
        (int8 / int16 I, Q); the multi-channel raw front-end formats RAW8/RAW16/RAW16I/RAW32 are an error
  F_S   sample rate (MHz)                         -> input.sample_rate_hz
  F_LO  LO frequency of each RF channel (MHz)     -> input.if_hz = carrier - F_LO (0: not known)
  IQ    1 = real (I) sampling, 2 = I/Q sampling   -> the real or I/Q format
  BITS  bits per sample (informational)
  TIME  start of the recording, GPS time, ``yyyy/mm/dd hh:mm:ss.sss`` -> input.start_gps_week / _tow_s
  PROG  the program that wrote it

``gnssrx simulate`` writes a ``.tag`` beside recordings in the formats PocketSDR names (int8_real -> INT8,
int8_iq -> CS8, int16_iq -> CS16).

A config key left at its default takes the metadata's value; a key set to another value that disagrees
with the metadata is an error (one line), and so is a .tag that disagrees with a .sigmf-meta.
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
    """Path of the SigMF metadata file beside a recording (``<stem>.sigmf-meta``)."""
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


TAG_EXT = ".tag"
# PocketSDR FMT -> (our format for IQ = 1, for IQ = 2, iq_swap)
TAG_FORMATS = {"INT8": ("int8_real", "int8_iq", True), "INT8X2": ("int8_iq", "int8_iq", True),
               "CS8": ("int8_iq", "int8_iq", False), "CS16": ("int16_iq", "int16_iq", False)}
TAG_RAW = ("RAW8", "RAW16", "RAW16I", "RAW32")
# our format -> (FMT, IQ, BITS) written by the simulator
TAG_WRITE = {"int8_real": ("INT8", 1, 8), "int8_iq": ("CS8", 2, 8), "int16_iq": ("CS16", 2, 16)}


def tag_path(data_path) -> str:
    """Path of the PocketSDR tag file of a recording (``<data path>.tag``)."""
    return os.fspath(data_path) + TAG_EXT


def read_tag(path) -> dict | None:
    """Input keys from the PocketSDR tag ``<path>.tag`` (module doc), None without a file."""
    tp = tag_path(path)
    if not os.path.isfile(tp):
        return None
    try:
        with open(tp, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except (OSError, UnicodeDecodeError):
        raise UserError(f"PocketSDR tag {tp} cannot be read as text") from None
    kv = {}
    for line in lines:
        if "=" in line:
            k, v = line.split("=", 1)
            kv[k.strip().upper()] = v.strip()
    fmt = kv.get("FMT", "")
    if fmt in TAG_RAW:
        raise UserError(f"PocketSDR tag {tp}: FMT {fmt} is a multi-channel raw front-end format (not "
                        f"supported: split it into per-channel files)")
    if fmt not in TAG_FORMATS:
        raise UserError(f"PocketSDR tag {tp}: FMT '{fmt}' is not one of {', '.join(TAG_FORMATS)}")

    def first(key, conv):
        if key not in kv:
            return None
        try:
            return conv(kv[key].split(",")[0])
        except ValueError:
            raise UserError(f"PocketSDR tag {tp}: {key} = '{kv[key]}' is not a number") from None

    iq = first("IQ", int) or 2
    real_fmt, iq_fmt, swap = TAG_FORMATS[fmt]
    out = {"format": real_fmt if iq == 1 else iq_fmt, "iq_swap": swap and iq == 2}
    fs = first("F_S", float)
    if fs:
        out["sample_rate_hz"] = fs * 1e6
    out["_lo_hz"] = (first("F_LO", float) or 0.0) * 1e6
    if "TIME" in kv:
        try:
            t = _dt.datetime.strptime(kv["TIME"][:23], "%Y/%m/%d %H:%M:%S.%f" if "." in kv["TIME"]
                                      else "%Y/%m/%d %H:%M:%S")
        except ValueError:
            raise UserError(f"PocketSDR tag {tp}: TIME '{kv['TIME']}' is not yyyy/mm/dd hh:mm:ss") from None
        sec = (t - GPS_EPOCH).total_seconds()           # PocketSDR tags are in GPS time
        week = int(sec // WEEK_S)
        out["start_gps_week"], out["start_gps_tow_s"] = week, sec - week * WEEK_S
    return out


def write_tag(data_path, fmt: str, sample_rate_hz: float, if_hz: float, carrier_hz: float,
              start_week: int | None = None, start_tow_s: float | None = None, tag: str | None = None):
    """Write the PocketSDR tag of a recording in int8_real / int8_iq / int16_iq (else nothing; returns the
    path or None)."""
    f = resolve_format(fmt)
    if f.name not in TAG_WRITE:
        return None
    name, iq, bits = TAG_WRITE[f.name]
    lines = ["PROG = gnssrx"]
    if start_week is not None and start_tow_s is not None:
        t = GPS_EPOCH + _dt.timedelta(seconds=start_week * WEEK_S + start_tow_s)
        lines.append("TIME = " + t.strftime("%Y/%m/%d %H:%M:%S.%f")[:23])
    lines += [f"FMT  = {name}", f"F_S  = {sample_rate_hz * 1e-6:.9g}",
              f"F_LO = {(carrier_hz - if_hz) * 1e-6:.12g}", f"IQ   = {iq}", f"BITS = {bits}"]
    tp = tag or tag_path(data_path)
    with open(tp, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return tp


def read_metadata(path, carrier_hz: float) -> tuple[dict, dict]:
    """Input keys from the SigMF metadata and the PocketSDR tag beside ``path``: (keys, key -> the file
    that gave it).  A tag that disagrees with the SigMF metadata is an error."""
    meta, src = {}, {}
    sig = read_sigmf(path, carrier_hz)
    for k, v in (sig or {}).items():
        meta[k], src[k] = v, meta_path(path)
    tag = read_tag(path)
    if tag:
        lo = tag.pop("_lo_hz")
        if lo > 0:
            tag["if_hz"] = round(carrier_hz - lo, 6)
        for k, v in tag.items():
            if k in meta and not _same(k, meta[k], v):
                raise UserError(f"{tag_path(path)} ({k} {v!r}) disagrees with {meta_path(path)} ({meta[k]!r})")
            meta.setdefault(k, v)
            src.setdefault(k, tag_path(path))
    return meta, src


def _same(key, cur, value) -> bool:
    if key == "start_gps_tow_s":
        return cur is not None and abs(float(cur) - float(value)) <= 1.0      # a hint: datetime resolution
    if isinstance(value, (str, bool)) or key == "start_gps_week":
        return cur == value
    return cur is not None and math.isclose(float(cur), float(value), rel_tol=1e-9, abs_tol=1e-3)


def apply_metadata(inp, defaults: dict, carrier_hz: float) -> dict:
    """Fill the input section ``inp`` (a config Section) from the metadata beside ``inp.path``.

    ``defaults`` holds the schema defaults of the input keys: a key at its default takes the metadata's
    value; any other value must agree with it (UserError naming the key).  Returns the metadata used.
    """
    meta, src = read_metadata(inp.path, carrier_hz)
    if not meta:
        return {}
    for key, value in meta.items():
        cur = inp[key]
        if key == "format":
            cur = resolve_format(cur).name
        if _same(key, cur, value):
            continue
        if cur == defaults.get(key):
            inp._values[key] = value          # sections are read-only to users; this fills in the input
            continue
        raise UserError(f"config key 'input.{key}' = {cur!r} disagrees with {src[key]} "
                        f"({value!r}); remove the key or fix the metadata")
    if "if_hz" in meta and abs(float(inp.if_hz)) > float(inp.sample_rate_hz) / 2:
        _off_band(meta["if_hz"], float(inp.sample_rate_hz), carrier_hz, src["if_hz"])
    return meta


def _off_band(if_hz: float, fs: float, carrier_hz: float, src: str):
    """The metadata's centre frequency puts the configured signal's carrier outside the recorded band:
    most often the recording holds another signal (the config's ``signal`` left at gps_l1ca)."""
    from ..gnss.registry import SIGNALS
    centre = carrier_hz - if_hz
    fits = [n for n, s in SIGNALS.items() if abs(s.carrier_hz - centre) <= fs / 2 and s.carrier_hz != carrier_hz]
    hint = f"set signal: {fits[0]} (its carrier is inside the band)" if fits else "check the metadata"
    raise UserError(f"{src} centres the recording at {centre * 1e-6:.6f} MHz: the signal's carrier "
                    f"{carrier_hz * 1e-6:.6f} MHz is {if_hz * 1e-6:+.3f} MHz away, outside the recorded "
                    f"+/-{fs * 0.5e-6:.3f} MHz; {hint}")
