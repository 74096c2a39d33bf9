"""``gnssrx probe FILE``: which format, sample rate and IF find satellites in a recording."""
from __future__ import annotations

import os

import click

from ..errors import UserError

#: a broadcast ephemeris needs subframes 1-3 (18 s) after the first subframe start (up to 6 s) and the
#: bit / frame sync before it: ~30 s of tracking in practice
EPHEMERIS_S = 30.0


def _fmt_hz(v: float) -> str:
    return f"{v:.0f}" if abs(v - round(v)) < 1e-6 else f"{v:g}"


def report_lines(r, show_path: str) -> list[str]:
    """The lines ``gnssrx probe`` prints for a :class:`~receiver.probe.search.ProbeResult`."""
    from ..source.io import FORMATS
    out = [f"gnssrx probe: {show_path} ({os.path.getsize(r.path):,} bytes)"]
    out += [f"  bytes: {e}" for e in r.stats.evidence]
    b = r.best
    if b is None:
        out.append(f"no reading of the file found a satellite ({r.tried} format / rate / IF combinations "
                   f"tried in {r.elapsed_s:.1f} s)")
        out += [f"  {n}" for n in r.notes]
        out.append("  check: the sample rate (give it with --rate HZ), that the file holds GPS L1 samples, "
                   "the antenna (a sky view) and the front end's gain")
        return out
    keys = r.config()
    cplx = FORMATS[b.cand.fmt].complex
    sign = {True: ", spectrum inverted", False: "", None: ", spectrum sign not determined"}[r.iq_swap]
    if_txt = f"{keys['if_hz'] / 1e6:g} MHz" if keys["if_hz"] else "0 (complex baseband)"
    out.append(f"found: {b.cand.label()} at {b.fs / 1e6:g} MS/s, IF {if_txt}{sign}: "
               f"{len(b.found)} satellite{'s' * (len(b.found) != 1)} ({r.tried} reading{'s' * (r.tried != 1)} tried, "
               f"{r.elapsed_s:.1f} s)")
    out.append(f"  {'PRN':>4} {'doppler_hz':>10} {'C/N0~':>6} {'metric':>6}")
    for s in b.found:
        weak = "" if b.confirmed or s.metric >= 1.5 else "  (weak, not confirmed: the file is too short)"
        dop = -s.doppler_hz if r.iq_swap else s.doppler_hz
        out.append(f"  {s.prn:4d} {dop:10.0f} {s.cn0_dbhz_est:6.1f} {s.metric:6.1f}{weak}")
    if r.swap_note:
        out.append(f"  sign: {r.swap_note}")
    if abs(r.offset_hz) > 3000:
        off = -r.offset_hz if r.iq_swap else r.offset_hz
        out.append(f"  every satellite is about {off / 1e3:+.1f} kHz off: the front end's oscillator (the "
                   f"receiver's acquisition.lo_search_hz covers up to 25 kHz; input.if_hz: {_fmt_hz(round(off, -2))} "
                   f"removes it)")
    out += [f"  {n}" for n in r.notes]
    dur = r.duration_s
    if dur < EPHEMERIS_S:
        out.append(f"  the file holds {dur:.3g} s: too short to decode a broadcast ephemeris (~{EPHEMERIS_S:.0f} s); "
                   f"a fix needs navigation.ephemeris (a RINEX navigation file of the day) or `gnssrx snapshot`")
    out.append("config (YAML):")
    out.append("input:")
    out.append(f"  path: {show_path}")
    for k, v in keys.items():
        val = _fmt_hz(v) if k in ("sample_rate_hz", "if_hz") else ("true" if v is True else v)
        out.append(f"  {k}: {val}")
    sets = " ".join(f"--set input.{k}={_fmt_hz(v) if isinstance(v, float) else ('true' if v is True else v)}"
                    for k, v in keys.items())
    out.append(f"or: gnssrx run CONFIG --input {show_path} {sets}")
    del cplx
    return out


@click.command()
@click.argument("file", type=str)
@click.option("--rate", type=float, default=None, metavar="HZ",
              help="the sample rate, when known (default: try the common front-end rates)")
@click.option("--header-bytes", type=click.IntRange(min=0), default=0, show_default=True,
              help="bytes before the first sample")
@click.option("--max-seconds", type=click.FloatRange(min=1.0), default=30.0, show_default=True,
              help="give up searching after this long")
@click.option("--verbose", "-v", is_flag=True, help="list every reading tried")
def probe(file, rate, header_bytes, max_seconds, verbose):
    """Find the format, sample rate and IF of a recording: byte statistics, then a short acquisition over
    the candidate readings; prints the input config lines to use.  Exit 0 when satellites were found,
    1 when none."""
    from .search import probe as do_probe
    if rate is not None and not 1e5 <= rate <= 1e9:
        raise UserError(f"--rate {rate:g}: a sample rate in Hz between 1e5 and 1e9 is expected (e.g. 4e6)")
    log = (lambda m: click.echo(m, err=True)) if verbose else None
    r = do_probe(file, rate=rate, header_bytes=header_bytes, max_s=max_seconds, log=log)
    click.echo("\n".join(report_lines(r, file)))
    if r.best is None:
        raise SystemExit(1)
