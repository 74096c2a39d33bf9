"""What a run or an acquisition that finds nothing (or no fix) should check, with the evidence: the byte
statistics of receiver/probe/stats.py against the configured format (cheap: 1 MiB of the file), the
spectrum of a block read as configured, and the run file's acquisition and channels."""
from __future__ import annotations

import os

from ..source.io import FORMATS, resolve_format
from .stats import byte_stats, spectrum_centre

#: tracking time a broadcast ephemeris needs (subframes 1-3 after bit and frame sync)
EPHEMERIS_S = 30.0


def family_of(fmt: str) -> str:
    """The byte-statistics family (receiver/probe/stats.py) of a format name."""
    f = resolve_format(fmt)
    if f.integer:
        return "int4"
    if f.kind == "packed":
        return f"packed{f.bits}"
    if f.kind == "float":
        return "float32"
    if f.kind == "uint":
        return "uint8"
    return f"int{8 * f.dtype(0).itemsize}"


def format_mismatch(path, fmt: str, header_bytes: int = 0) -> str | None:
    """One sentence when the file's bytes contradict ``fmt`` (None when they agree or cannot tell)."""
    try:
        st = byte_stats(path, header_bytes)
    except OSError:
        return None
    if st.family == "unknown" or st.family == family_of(fmt):
        return None
    kinds = " or ".join(dict.fromkeys(c.fmt for c in st.candidates)) if st.candidates else st.family
    return (f"input.format {fmt} does not fit the file's bytes: {st.evidence[0]}; try {kinds} "
            f"(`gnssrx probe {path}` checks the rate and IF too)")


def spectrum_hint(reader, fmt: str) -> str | None:
    """Real IF read as I/Q puts the band at +/- fs/2; I/Q read as real is mostly harmless to tell apart."""
    try:
        x = reader.read(reader.first, 1 << 17)
    except Exception:  # noqa: BLE001 - a hint must never fail the command
        return None
    if not FORMATS[resolve_format(fmt).name].complex or len(x) < 4096:
        return None
    _, width = spectrum_centre(x)
    if width > 0.6:
        return (f"read as I/Q ({fmt}) the signal's band sits at +/- half the sample rate (spread {width:.2f}): "
                f"a real IF recording ({fmt.replace('_iq', '_real')} with input.if_hz) looks like this")
    return None


def no_satellite_lines(cfg, reader=None) -> list[str]:
    """What to check when acquisition found no satellite."""
    i = cfg.input
    out = ["no satellite found: check input.format, input.sample_rate_hz and input.if_hz"]
    if i.path and os.path.isfile(i.path):
        m = format_mismatch(i.path, i.format, i.header_bytes)
        if m:
            out.append("  " + m)
        elif reader is not None:
            s = spectrum_hint(reader, i.format)
            if s:
                out.append("  " + s)
        out.append(f"  `gnssrx probe {i.path}` tries the formats, rates and IFs that fit the file "
                   f"(configured: {i.format}, {i.sample_rate_hz / 1e6:g} MS/s, IF {i.if_hz / 1e6:g} MHz)")
    return out


def no_fix_lines(summary, ephemeris_file: str | None = None) -> list[str]:
    """Why a run has no fix: what was acquired, tracked, and how long the file is; ``ephemeris_file``: the
    run's navigation.ephemeris (assisted mode)."""
    if summary.n_fixes:
        return []
    try:
        from ..export.info import run_facts
        info = run_facts(summary.output)
    except Exception:  # noqa: BLE001 - the explanation must never fail the run
        return []
    det = info.get("acquisition", {}).get("detected_prns", [])
    chans = info.get("channels", {})
    dur = summary.duration_s
    lines = []
    if not det:
        return lines                         # no_satellite_lines says what to check
    locked = [n for n, c in chans.items() if "mean_cn0_dbhz" in c]
    what = (f"why no fix      acquired {len(det)} satellite{'s' * (len(det) != 1)} ({' '.join(map(str, det))}), "
            f"{len(chans)} channel{'s' * (len(chans) != 1)} opened, {len(locked)} locked")
    lines.append(what)
    if ephemeris_file and len(locked) >= 5:
        lines.append(f"                assisted ({ephemeris_file}): no set of transmit times fitted one position; "
                     f"check that input.start_gps_week / start_gps_tow_s give the first sample's GPS time "
                     f"to within 10 ms and that the file's ephemerides are of that day")
    elif dur < EPHEMERIS_S and not info.get("ephemerides"):
        lines.append(f"                the file holds {dur:.3g} s: a broadcast ephemeris needs ~{EPHEMERIS_S:.0f} s of "
                     f"tracking (and a channel needs tracking.pull_in_ms before it counts as tracked); give "
                     f"navigation.ephemeris (a RINEX navigation file of the day) or use `gnssrx snapshot`")
    elif not info.get("ephemerides"):
        lines.append("                no ephemeris was decoded (weak signals or parity failures): see "
                     "`gnssrx info` and navigation.ephemeris")
    elif len(info["ephemerides"]) < 4:
        lines.append(f"                ephemerides of only {len(info['ephemerides'])} satellites were decoded: a fix "
                     f"needs 4")
    return lines


def explain_no_fix(cfg, summary) -> list[str]:
    """Lines for the end of a run without a fix (nothing when it has fixes)."""
    if summary.n_fixes:
        return []
    lines = no_fix_lines(summary, getattr(getattr(cfg, "navigation", None), "ephemeris", None))
    if lines:
        return lines
    try:
        from ..export.info import run_facts
        det = run_facts(summary.output).get("acquisition", {}).get("detected_prns", [])
    except Exception:  # noqa: BLE001 - the explanation must never fail the run
        return []
    return [] if det else no_satellite_lines(cfg)


def warn_format(cfg) -> None:
    """A warning when the configured format contradicts the file's bytes (the run goes on)."""
    from ..errors import warn
    i = cfg.input
    if i.path and os.path.isfile(i.path):
        m = format_mismatch(i.path, i.format, i.header_bytes)
        if m:
            warn(m)
