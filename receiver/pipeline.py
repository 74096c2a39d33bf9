"""The receiver pipeline: acquire -> scalar tracking -> (vector handover) -> navigation, chunk by chunk.

``run(cfg)`` streams the input in chunks of ``CHUNK_S`` seconds.  Per chunk every channel runs all its
epochs in that chunk (one compiled call per channel with the built-in loops), the records go to the HDF5
writer and the navigation engine, and the engine produces the fixes of the navigation epochs that all
channels have passed.  Missing PRNs are re-acquired periodically, a few per attempt.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from .acquisition import reject_cross_correlations, search
from .errors import UserError
from .source.io import SampleReader
from .source.metadata import apply_metadata
from .config import RECEIVER_SCHEMA
from .runfile.writer import RunWriter
from .runfile.record import EPOCH_DTYPE
from .gnss.registry import get_signal
from .tracking.carrier import make_carrier_loop
from .tracking.scalar import Channel

CHUNK_S = 0.5
OVERLAP_S = 0.03
REACQ_PER_ATTEMPT = 4


@dataclass
class RunSummary:
    output: str
    duration_s: float
    wall_s: float
    tracked: list = field(default_factory=list)
    mean_cn0: dict = field(default_factory=dict)
    n_fixes: int = 0
    first_fix_s: float | None = None
    mean_llh: tuple | None = None
    scatter_m: tuple | None = None     # (east, north, up) standard deviation
    parity_failures: int = 0

    @property
    def realtime_factor(self) -> float:
        return self.duration_s / self.wall_s if self.wall_s > 0 else float("inf")

    def text(self) -> str:
        lines = [f"output          {self.output}",
                 f"signal          {self.duration_s:.1f} s processed in {self.wall_s:.1f} s "
                 f"(real-time factor {self.realtime_factor:.1f}x)",
                 f"tracked         {len(self.tracked)} satellites: "
                 + " ".join(f"G{p:02d}({self.mean_cn0[p]:.1f})" for p in self.tracked)]
        if self.mean_cn0:
            lines.append(f"mean C/N0       {np.mean(list(self.mean_cn0.values())):.1f} dB-Hz")
        if self.n_fixes:
            lat, lon, h = self.mean_llh
            lines += [f"first fix       {self.first_fix_s:.2f} s after the first sample",
                      f"fixes           {self.n_fixes}",
                      f"mean position   lat {lat:.7f} lon {lon:.7f} h {h:.2f} m",
                      "scatter (1 sd)  E {:.2f} N {:.2f} U {:.2f} m".format(*self.scatter_m)]
        else:
            lines.append("fixes           none")
        return "\n".join(lines)


def default_output_path(cfg, input_path: str) -> str:
    if cfg.output.path:
        return cfg.output.path
    stem = os.path.splitext(os.path.basename(input_path))[0]
    return f"{stem}.h5"


def _progress(total_s: float, quiet: bool):
    if quiet or not sys.stderr.isatty():
        return None
    from tqdm import tqdm
    return tqdm(total=round(total_s, 1), unit="s", desc="tracking", leave=False,
                bar_format="{desc} {bar} {n:.1f}/{total:.1f} s [{elapsed}<{remaining}]")


def open_input(cfg) -> SampleReader:
    i = cfg.input
    if not i.path:
        raise UserError("no input file: set input.path in the config or pass --input")
    apply_metadata(i, {k: v.default for k, v in RECEIVER_SCHEMA["input"].items()},
                   get_signal(cfg.signal).carrier_hz)           # SigMF .sigmf-meta beside the file
    return SampleReader(i.path, i.format, i.sample_rate_hz, i.skip_s, i.duration_s, i.iq_swap,
                        header_bytes=i.header_bytes, bit_order=i.bit_order, encoding=i.encoding)


def acquire(cfg, reader: SampleReader, start: int, prns) -> list:
    a = cfg.acquisition
    # the search needs T_coh x K; the fine Doppler estimate uses up to 200 ms (20 blocks of 10 ms)
    n = max(int(round(a.coherent_ms * a.noncoherent * 1e-3 * reader.fs)), int(0.2 * reader.fs))
    block = reader.read(start, n)
    if len(block) < n:
        raise UserError("input too short for acquisition "
                        f"({len(block) / reader.fs * 1e3:.0f} ms available, {n / reader.fs * 1e3:.0f} needed)")
    res = search(block, start, reader.fs, cfg.input.if_hz, prns, a.coherent_ms, a.noncoherent,
                  a.doppler_max_hz, a.doppler_step_hz, a.pfa, a.threshold, signal=get_signal(cfg.signal))
    return reject_cross_correlations(res, a.coherent_ms)


def _maybe_handover(cfg, channels, nav, start, fs, n_fixes, quiet=False):
    """Vector-loop handover hook: returns a vector tracker once vector.start_s is reached (or 5 s after
    the first fix), else None.  The tracker's ``process(block, start)`` returns
    ({prn: EPOCH_DTYPE records}, FIX_DTYPE fixes with mode=1) and drives the channels' NCOs."""
    from .tracking.vector import handover
    if quiet:
        return handover(cfg, channels, nav, start, fs, log=lambda msg: None)
    return handover(cfg, channels, nav, start, fs)


def run(cfg, quiet: bool = False, log=print) -> RunSummary:
    """Run the receiver on cfg.input.path; write cfg.output.path (HDF5)."""
    make_carrier_loop(cfg.tracking.carrier.variant, cfg.tracking)     # validate early
    if cfg.vector.enabled:
        from .tracking.vector import make_filter
        make_filter(cfg.vector.variant, cfg.vector)                    # (the vector filter too)
    reader = open_input(cfg)
    out_path = default_output_path(cfg, cfg.input.path)
    ephemerides, iono = None, None
    if cfg.navigation.enabled and cfg.navigation.ephemeris:
        from .gnss.rinex import read_rinex_nav
        ephemerides, iono = read_rinex_nav(cfg.navigation.ephemeris)
    fs, if_hz = reader.fs, cfg.input.if_hz
    writer = RunWriter(out_path, cfg.to_yaml(), {
        "input_path": os.path.abspath(reader.path), "sample_rate_hz": fs, "if_hz": if_hz,
        "first_sample": reader.first, "n_samples": reader.n_samples,
        "command": " ".join(sys.argv)})
    ok = False
    try:
        summary = _run(cfg, reader, writer, ephemerides, iono, quiet, log)
        summary.output = out_path
        ok = True
        return summary
    finally:
        writer.close(ok)
        if ok:  # standard outputs (receiver/export): RINEX/NMEA/KML/GPX/report from the closed run file
            from .export import export_all
            export_all(out_path, cfg.output, log=None if quiet else log)


def _run(cfg, reader, writer, ephemerides, iono, quiet, log) -> RunSummary:
    from .navigation.engine import NavigationEngine
    fs, if_hz = reader.fs, cfg.input.if_hz
    t_wall = time.perf_counter()
    acq_start = reader.first + int(round(cfg.acquisition.start_s * fs))
    results = acquire(cfg, reader, acq_start, cfg.acquisition.prns)
    writer.write_acquisition(results, {"fs": fs, "pfa": cfg.acquisition.pfa})
    detected = sorted([r for r in results if r.detected], key=lambda r: -r.metric)
    channels: dict[int, Channel] = {}
    for r in detected[:cfg.tracking.max_channels]:
        channels[r.prn] = Channel(r.prn, r.doppler_hz, r.code_phase_chips, r.sample_index,
                                  cfg.tracking, fs, if_hz, channel_id=len(channels),
                                  signal=get_signal(cfg.signal))
    week_hint = cfg.input.start_gps_week
    nav = None
    if cfg.navigation.enabled and cfg.signal == "gps_l1ca":      # no B1I navigation decoding
        nav = NavigationEngine(cfg.navigation, fs, if_hz, reader.first, ephemerides, iono, week_hint,
                               cfg.input.start_gps_tow_s)
    cn0_sum: dict[int, list] = {}
    n_fixes, first_fix, fix_ecef = 0, None, []
    chunk = int(CHUNK_S * fs)
    overlap = int(OVERLAP_S * fs)
    next_reacq = acq_start + int(cfg.tracking.reacquire_s * fs)
    rr = 0
    vector = None
    bar = _progress(reader.duration_s, quiet)
    start = acq_start
    while start < reader.end:
        block = reader.read(start, chunk + overlap)
        if vector is None and cfg.vector.enabled:
            vector = _maybe_handover(cfg, channels, nav, start, fs, n_fixes, quiet)
        if vector is not None:
            block_recs, vfixes = vector.process(block, start)
            writer.append_fixes(vfixes)
            writer.append_vector_log(vector.last_diag)
        else:
            block_recs = {prn: ch.process(block, start) for prn, ch in channels.items()}
        for prn, ch in list(channels.items()):
            recs = block_recs.get(prn, np.zeros(0, EPOCH_DTYPE))
            writer.append_channel(prn, recs)
            if len(recs):
                c = recs["cn0_dbhz"][recs["pll_lock"] > 0]
                if len(c):
                    acc = cn0_sum.setdefault(prn, [0.0, 0])
                    acc[0] += float(c.sum())
                    acc[1] += len(c)
            if nav is not None:
                nav.add_records(prn, recs, ch.bit_offset)
            if ch.lost:
                del channels[prn]
                if nav is not None:
                    nav.drop(prn)
        if nav is not None:
            fixes, obs = nav.update(start + chunk)
            if vector is None:
                writer.append_fixes(fixes)
            else:
                fixes = vfixes          # the summary counts the fixes that were written
            writer.append_observables(obs)
            if len(fixes):
                n_fixes += len(fixes)
                if first_fix is None:
                    first_fix = float(fixes["time_s"][0]) - reader.first / fs
                fix_ecef.append(fixes["ecef"])
        # periodic re-acquisition of missing PRNs (a few per attempt)
        if start >= next_reacq and len(channels) < cfg.tracking.max_channels:
            missing = [p for p in cfg.acquisition.prns if p not in channels]
            if missing:
                pick = [missing[(rr + k) % len(missing)] for k in range(min(REACQ_PER_ATTEMPT,
                                                                               len(missing)))]
                rr += REACQ_PER_ATTEMPT
                if start + chunk + overlap < reader.end:
                    res = acquire(cfg, reader, start + chunk, pick)
                    writer.write_acquisition(res, {"fs": fs})
                    for r in res:
                        if r.detected and len(channels) < cfg.tracking.max_channels:
                            channels[r.prn] = Channel(r.prn, r.doppler_hz, r.code_phase_chips,
                                                      r.sample_index, cfg.tracking, fs, if_hz,
                                                      channel_id=len(channels),
                                                      signal=get_signal(cfg.signal))
            next_reacq = start + int(cfg.tracking.reacquire_s * fs)
        start += chunk
        if bar is not None:
            bar.update(round(min(chunk, reader.end - start + chunk) / fs, 3))
    if bar is not None:
        bar.close()
    wall = time.perf_counter() - t_wall
    s = RunSummary(output="", duration_s=reader.duration_s, wall_s=wall)
    s.mean_cn0 = {p: v[0] / v[1] for p, v in sorted(cn0_sum.items()) if v[1]}
    s.tracked = sorted(s.mean_cn0)
    s.n_fixes = n_fixes
    s.first_fix_s = first_fix
    if nav is not None:
        s.parity_failures = sum(ch.decoder.parity_failures for ch in nav.channels.values())
        writer.write_ephemerides({p: ch.decoder.ephemeris for p, ch in nav.channels.items()
                                  if ch.decoder.ephemeris is not None})     # the decoded ones
        writer.write_iono_utc(nav.iono(), "rinex" if iono is not None else "lnav")
    if fix_ecef:
        from .gnss.geodesy import ecef2enu, ecef2lla
        e = np.concatenate(fix_ecef)
        mean = e.mean(axis=0)
        lat, lon, h = ecef2lla(mean)
        s.mean_llh = (float(lat), float(lon), float(h))
        s.scatter_m = tuple(float(v) for v in ecef2enu(e, mean).std(axis=0))
    writer.set_attrs("/", {"wall_time_s": wall, "realtime_factor": s.realtime_factor,
                           "n_fixes": n_fixes})
    return s
