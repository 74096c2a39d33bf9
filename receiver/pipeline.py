"""The receiver pipeline: acquire -> scalar tracking -> (vector handover) -> navigation, chunk by chunk.

``run(cfg)`` streams the input in chunks of ``CHUNK_S`` seconds.  Per chunk every channel runs all its
epochs in that chunk (one compiled call per channel with the built-in loops), the records go to the HDF5
writer and the navigation engine, and the engine produces the fixes of the navigation epochs that all
channels have passed.  The channels' lifecycle (acquisition, loss of signal, hot/warm re-acquisition around
the prediction, cold re-acquisition of missing PRNs) belongs to receiver.tracking.channels.ChannelManager;
the navigation engine keeps each satellite's memory (ephemeris, transmit-time reference) across losses.
"""
from __future__ import annotations

import functools
import logging
import os
import sys
import time
from dataclasses import dataclass

import numpy as np

from .acquisition.stage import acquire
from . import _malloc, interrupt, threads
from .stagetimes import stage
from .errors import UserError, warn
from .source.io import SampleReader
from .source.prefetch import PrefetchingReader
from .source.metadata import apply_metadata
from .source.decimate import DecimatingReader, plan
from .schema import RECEIVER_SCHEMA, plugins_attr, run_signals, signal_prns  # noqa: F401 (run_signals: re-exported)
from .runfile.provenance import provenance_async
from .runfile.background import BackgroundWriter
from .runfile.writer import RunWriter, chunk_rows_for
from .runfile.record import EPOCH_DTYPE, IONO_BROADCAST
from .dualband import DualBand, band_signal, band_signals, core_signals, open_band_input
from .gnss.registry import get_signal
from .gnss.satid import MIXED
from .tracking.carrier import make_carrier_loop
from .tracking.channels import ChannelManager
from .tracking.gal_channels import GalChannelManager
from .tracking.table import ChannelTable
from .summary import RunSummary

CHUNK_S = 0.5
OVERLAP_S = 0.03


def default_output_path(cfg, input_path: str) -> str:
    """``output.path`` if set, else the input file's stem + ``.h5`` in the current directory."""
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


def open_input(cfg, name: str | None = None, plan_chip_rate: float | None = None) -> SampleReader:
    """The input stages of signal ``name`` (default: the run's first signal).  A run over several signals
    opens one per signal over the same file: the first signal is at input.if_hz, every other at if_hz + its
    carrier - the first's (one front-end LO); ``plan_chip_rate`` (the fastest signal's chip rate) gives every
    signal's resampling stage the same rate, so sample indices mean the same instant in all of them."""
    i = cfg.input
    if not i.path:
        raise UserError("no input file: set input.path in the config or pass --input")
    sigs = core_signals(cfg)
    first, sig = get_signal(sigs[0]), get_signal(name or sigs[0])
    apply_metadata(i, {k: v.default for k, v in RECEIVER_SCHEMA["input"].items() if hasattr(v, "default")},
                   first.carrier_hz)                            # SigMF .sigmf-meta beside the file
    own = (i.signal_files or {}).get(sig.name)                  # a file of its own (input.signal_files)
    reader = SampleReader(own["path"] if own else i.path, i.format, i.sample_rate_hz, i.skip_s, i.duration_s,
                          i.iq_swap, header_bytes=i.header_bytes, bit_order=i.bit_order, encoding=i.encoding)
    if own:
        if_hz = float(own.get("if_hz", 0.0))
    else:
        if_hz = i.if_hz + (sig.carrier_hz - first.carrier_hz)
    if sig is not first and not (abs(if_hz) < reader.fs / 2 and (if_hz > 0 or reader.format.complex)):
        raise UserError(f"signal {sig.name} would sit at IF {if_hz / 1e6:+.3f} MHz (input.if_hz + its carrier - "
                        f"{first.name}'s), outside the {reader.fs / 1e6:g} MS/s band: a wider recording "
                        f"(input.sample_rate_hz) centred between the signals is needed")
    reader.if_hz = if_hz              # the IF the stages below see (0 after the decimating stage)
    chip_rate = sig.chip_rate
    l, m = plan(i.decimate, reader.fs, plan_chip_rate or chip_rate)
    if (l, m) != (1, 1):                                          # mix to 0 Hz, filter, resample
        reader = DecimatingReader(reader, l, m, if_hz, chip_rate)
    c = i.conditioning
    if c.dc_removal or c.tone_detection or c.pulse_blanking or c.pulse_detection:      # the input conditioning stage
        from .source.conditioning import ConditionedReader
        # the decimating stage mixed input.if_hz to 0 Hz: the front end's DC is now at -IF
        reader = ConditionedReader(reader, c, dc_hz=-reader.input_if_hz if isinstance(reader, DecimatingReader)
                                   else 0.0)
    return reader


def _vector_handover(cfg, parts, table, nav, fs, quiet=False):
    """Vector-loop handover state (owned by the run): ``.step(start)`` returns a vector tracker once
    vector.start_s is reached (or 5 s after the first fix), else None.  The tracker's
    ``process(blocks, start)`` (the chunk of every signal's stream, in the order of ``parts``) returns
    ({key: EPOCH_DTYPE records}, FIX_DTYPE fixes, mode 1 or 2 = coast) and drives the channels' NCOs;
    ``tracker.reinit_needed`` asks for a fall-back to scalar tracking.  The tracker sees the run's channel
    table (receiver.tracking.table.ChannelTable: every channel manager's channels by satellite key)."""
    from .tracking.vector import Handover
    return Handover(cfg, table, nav, fs, log=(lambda msg: None) if quiet else None,
                    signals=[(p.signal, p.reader.if_hz) for p in parts])


def _assisted_ephemerides(path, sigs):
    """navigation.ephemeris (assisted mode): the RINEX records of the run's systems, keyed like its channels
    (one signal: its PRNs -- a BeiDou B1I run the BeiDou records, BDT, a Galileo E1 run the Galileo I/NAV
    ones; several signals: satellite keys,
    receiver.gnss.satid.sat_key, from a mixed RINEX 3 file), and the header's Klobuchar set (GPS's first)."""
    from .gnss.rinex import read_rinex_nav_for
    return read_rinex_nav_for(path, [get_signal(n).system for n in sigs])


@interrupt.deferred()      # SIGINT/SIGTERM only set a flag; the chunk loop stops at the next chunk
def run(cfg, quiet: bool = False, log=None, reads=()) -> RunSummary:
    """Run the receiver on cfg.input.path; write cfg.output.path (HDF5).
    ``reads``: further files the command reads (the config file): the output must not be one of them.
    ``log``: a callable for progress messages (default: this module's logger).  The standard outputs
    (RINEX/NMEA/KML/GPX/report, ``output.*``) are written by the caller from the closed run file
    (:func:`receiver.export.export_all`): the CLI and the batch runner do."""
    if log is None:
        log = logging.getLogger(__name__).info
    car = cfg.tracking.carrier
    for name in (car.auto_weak, car.auto_strong) if car.variant == "auto" else (car.variant,):
        make_carrier_loop(name, cfg.tracking, check=True)              # validate early (plugins too)
    if cfg.vector.enabled:
        from .tracking.vector import make_filter
        make_filter(cfg.vector.variant, cfg.vector)                    # (the vector filter too)
    prov = provenance_async()           # git / package versions on a thread while the input opens
    with stage("open input"):
        sigs = core_signals(cfg)
        plan_chip = max(get_signal(n).chip_rate for n in sigs)
        readers = [open_input(cfg, n, plan_chip if len(sigs) > 1 else None) for n in sigs]
        band_reader = [open_band_input(cfg, n) for n in band_signals(cfg)] or None
        reader = readers[0]
        out_path = default_output_path(cfg, cfg.input.path)
        check_meaning(cfg, reader)
        ephemerides, iono = None, None
        if cfg.navigation.enabled and cfg.navigation.ephemeris:
            ephemerides, iono = _assisted_ephemerides(cfg.navigation.ephemeris, sigs)
    fs, if_hz = reader.fs, reader.if_hz
    with stage("write"):
        writer = _writer(cfg, reader, out_path, fs, if_hz, reads, prov)
    if threads.threads() > 1:
        writer = BackgroundWriter(writer)      # HDF5 appends overlap tracking (same file, same order)
    ok = False
    try:
        summary = _run(cfg, readers, writer, ephemerides, iono, quiet, log, band_reader)
        summary.output = out_path
        _nonfinite(reader, writer, summary)
        ok = True
        return summary
    finally:
        with stage("write"):
            writer.close(ok)


def _writer(cfg, reader, out_path, fs, if_hz, reads, prov):
    return RunWriter(out_path, cfg.to_yaml(), {
        "input_path": os.path.abspath(reader.path), "sample_rate_hz": fs, "if_hz": if_hz,
        "first_sample": reader.first, "n_samples": reader.n_samples,
        "resample": getattr(reader, "resample", "1/1"), "input_sample_rate_hz": cfg.input.sample_rate_hz,
        "input_if_hz": cfg.input.if_hz,
        "command": " ".join(sys.argv), "system": _run_system(cfg), "signals": ",".join(core_signals(cfg)),
        **({"band_signal": band_signal(cfg)} if band_signal(cfg) else {}),
        **_plugins(cfg), **prov(reader.path)}, reads=_reads(cfg, out_path, reader, reads),
        compression=cfg.output.compression, channel_rate_hz=cfg.output.channel_rate_hz,
        round_columns=cfg.output.round_columns,
        chunk_rows=chunk_rows_for(reader.duration_s, cfg.output.channel_rate_hz))


def _plugins(cfg) -> dict:
    """Run-file attribute ``plugins`` (name, version, origin and parameters of each plugin the config uses;
    absent when it uses none)."""
    text = plugins_attr(cfg)
    return {"plugins": text} if text else {}


def _run_system(cfg) -> str:
    """Run-file ``system``: the RINEX letter of the run's signal, or M for several signals (satellite keys,
    receiver.gnss.satid.sat_key)."""
    sigs = core_signals(cfg)
    return get_signal(sigs[0]).system if len(sigs) == 1 else MIXED


def check_meaning(cfg, reader):
    """Checks of meaning (receiver.config.validate_receiver: IF, PRN list) and those that need the input
    file: vector.start_s inside the processed span (else a warning)."""
    from .schema import validate_receiver
    validate_receiver(cfg)
    v = cfg.vector
    if v.enabled and v.start_s is not None and v.start_s >= reader.duration_s:
        warn(f"vector.start_s={v.start_s:g} s is after the end of the processed span "
             f"({reader.duration_s:.3f} s): the run stays scalar")


def _reads(cfg, out_path, reader, extra) -> list:
    """The files the run reads (the output must be none of them); the standard outputs written beside
    the run file (output.rinex, nmea, ...) must not overwrite one of them either."""
    from .runfile.outputs import KINDS, _enabled, output_paths
    from .safeio import _samefile
    reads = [reader.path, cfg.navigation.ephemeris, *extra,
             *(v.get("path") for v in (cfg.input.signal_files or {}).values() if isinstance(v, dict))]
    paths = output_paths(out_path)
    for kind in KINDS:
        if _enabled(cfg.output, kind):
            for key in (("obs", "nav") if kind == "rinex" else (kind,)):
                for r in reads:
                    if r and os.path.exists(paths[key]) and _samefile(paths[key], r):
                        raise UserError(f"output.{kind} would overwrite {r}, which the run reads")
    return reads


def _nonfinite(reader, writer, summary):
    """NaN/Inf input samples (zeroed by the reader): summary line, run-file attribute, warning."""
    summary.nonfinite_samples = reader.n_nonfinite
    writer.set_attrs("/", {"nonfinite_samples": reader.n_nonfinite})
    if reader.n_nonfinite:
        warn(f"{reader.n_nonfinite} non-finite input samples (NaN/Inf) were replaced by zeros")


def _run(cfg, readers, writer, ephemerides, iono, quiet, log, band_reader=None) -> RunSummary:
    reader = readers[0]
    fs = reader.fs
    t_wall = time.perf_counter()
    acq_start = reader.first + int(round(cfg.acquisition.start_s * fs))
    readers = [PrefetchingReader(r) for r in readers]
    try:
        return _chunks(cfg, readers, writer, quiet, log, acq_start, t_wall, ephemerides, iono, band_reader)
    finally:
        for r in readers:
            r.close()


@dataclass
class _Part:
    """One signal of the run: its input stages and channel manager; ``key`` maps its PRNs to the run's
    satellite keys (the run's channel table: identity in a one-signal run)."""
    signal: object
    reader: object
    table: ChannelTable
    manager: object = None

    def key(self, prn: int) -> int:
        return self.table.key(self.signal.system, prn)


def _chunks(cfg, readers, writer, quiet, log, acq_start, t_wall, ephemerides, iono, band_reader=None) -> RunSummary:
    run = _ChunkLoop(cfg, readers, writer, quiet, acq_start, ephemerides, iono)
    if band_reader is not None:
        run.dual = DualBand(cfg, band_signals(cfg), band_reader, run)
    run.loop()
    return run.summary(t_wall)


class _ChunkLoop:
    """One run's chunk loop: set-up (navigation engine, one channel manager per signal, the first
    acquisition), the loop over chunks (read, track -- scalar channels on the pool or the vector tracker --,
    write, navigation, channel lifecycle) and the run's summary."""

    def __init__(self, cfg, readers, writer, quiet, acq_start, ephemerides, iono):
        from .navigation.engine import NavigationEngine
        self.cfg, self.readers, self.writer, self.iono = cfg, readers, writer, iono
        self.acq_start = acq_start
        reader = self.reader = readers[0]
        fs = self.fs = reader.fs
        if_hz = reader.if_hz
        self.notes = []
        week_hint = cfg.input.start_gps_week
        self.dual = None                            # a second band (BAND_SIGNALS): receiver/dualband.py
        sigs = [get_signal(n) for n in core_signals(cfg)]
        multi = self.multi = len(sigs) > 1
        nav = self.nav = None
        if cfg.navigation.enabled:                  # L1 C/A: LNAV; B1I: D1/D2 (gnss/bds_nav.py)
            nav = self.nav = NavigationEngine(
                cfg.navigation, fs, if_hz, reader.first, ephemerides, iono, week_hint, cfg.input.start_gps_tow_s,
                signal=sigs[0], signals={g.system: (g, r.if_hz) for g, r in zip(sigs, readers)} if multi else None)
            pres = cfg.tracking.presence
            if pres.window_ms > 0:
                from .navigation.channel import PRESENCE_MARGIN_DB
                nav.presence_cn0 = pres.min_cn0_dbhz + PRESENCE_MARGIN_DB
        self.parts = []
        table = self.table = ChannelTable(multi)     # every signal's channels by the run's satellite key
        for sig, rd in zip(sigs, readers):
            part = _Part(sig, rd, table)
            manager = GalChannelManager if sig.system == "E" else ChannelManager     # Galileo E1: 4-ms codes
            part.manager = manager(cfg, rd, table.signal_view(nav, sig.system), fs, rd.if_hz, sig,
                                   functools.partial(acquire, signal=sig), table.signal_view(writer, sig.system),
                                   prns=signal_prns(cfg, sig.name))
            table.add(sig.system, part.manager.channels)
            self.parts.append(part)
        with stage("acquisition"):
            for part in self.parts:
                p_notes = [] if multi else self.notes
                part.manager.start(acq_start, p_notes)
                self.notes += [f"{ln} [{part.signal.name}]" for ln in p_notes] if multi else []
        self.cn0_sum: dict[int, list] = {}
        self.n_fixes, self.first_fix, self.fix_ecef = 0, None, []
        self.iono_counts, self.iono_from = {}, None
        self.chunk = int(CHUNK_S * fs)
        self.overlap = int(OVERLAP_S * fs)
        self.vector = None
        self.vfixes = None
        self.handover = _vector_handover(cfg, self.parts, table, nav, fs, quiet) if cfg.vector.enabled else None
        self.bar = _progress(reader.duration_s, quiet)

    def finish_chunk(self, end):
        """The chunk's navigation epochs up to sample ``end`` (fixes, observables) and their bookkeeping;
        ``end`` None: the epochs still held by navigation.lookahead_s (the end of the input)."""
        writer, reader, fs = self.writer, self.reader, self.fs
        with stage("navigation"):
            if self.nav.fixed_lag is not None and (self.handover is not None or self.dual is not None):
                self.nav.fixed_lag = None       # vector and dual-band runs: their own fixes (causal)
                self.notes.append("navigation.lookahead_s not used: a " +
                                  ("vector" if self.handover is not None else "dual-band") +
                                  " run's fixes stay causal")
            fixes, obs = self.nav.update(end) if end is not None else self.nav.flush()
        with stage("write"):
            if self.vector is None:
                writer.append_fixes(fixes)
            else:
                fixes = self.vfixes     # the summary counts the fixes that were written
            writer.append_observables(obs)
        if self.dual is not None:
            with stage("navigation"):
                self.dual.epochs(fixes, obs)
        if len(fixes):
            self.n_fixes += len(fixes)
            if self.first_fix is None:
                self.first_fix = float(fixes["time_s"][0]) - reader.first / fs
            codes, counts = np.unique(fixes["iono_params"], return_counts=True)
            for c, k in zip(codes.tolist(), counts.tolist()):
                self.iono_counts[c] = self.iono_counts.get(c, 0) + k
            bc = np.flatnonzero(fixes["iono_params"] == IONO_BROADCAST)
            if self.iono_from is None and len(bc):
                self.iono_from = float(fixes["time_s"][bc[0]]) - reader.first / fs
            self.fix_ecef.append(fixes["ecef"])

    def loop(self):
        """Every chunk from the acquisition start to the end of the input."""
        # Scalar tracking on several threads: a chunk's navigation epochs (nav.update, the fixes) are computed
        # on this thread while the pool tracks the next chunk.  The navigation engine's calls keep their order
        # (records of chunk k, channel manager, epochs of chunk k, records of chunk k+1, ...) and so do the
        # writer's: the same run file as one thread computing them in turn.  Not with the vector tracker (its
        # handover reads the last fix before the chunk).
        nav, reader, chunk = self.nav, self.reader, self.chunk
        defer = nav is not None and self.handover is None and threads.threads() > 1
        pending = None                          # end sample of the chunk whose navigation epochs are due
        start = self.acq_start
        trim_every = max(1, round(_malloc.TRIM_EVERY_S / CHUNK_S))
        n_chunks = 0
        while start < reader.end:
            interrupt.check()                       # SIGINT/SIGTERM: stop between compiled calls
            n_chunks += 1
            if n_chunks % trim_every == 0:
                _malloc.trim()                      # freed chunk buffers back to the kernel (flat RSS)
            pending = self._track_chunk(start, pending)
            if nav is not None:
                if defer:
                    pending = start + chunk
                else:
                    self.finish_chunk(start + chunk)
            start += chunk
            if self.bar is not None:
                self.bar.update(round(min(chunk, reader.end - start + chunk) / self.fs, 3))
        if pending is not None:
            self.finish_chunk(pending)
        if nav is not None and nav.fixed_lag is not None:
            self.finish_chunk(None)
        if self.bar is not None:
            self.bar.refresh()          # draw the final count: tqdm skips updates closer than its interval
            self.bar.close()

    def _track_chunk(self, start, pending):
        """Read, track and write the chunk at ``start``, feed the navigation engine, run the channel
        lifecycle; the previous chunk's deferred navigation epochs (``pending``) are computed while the pool
        tracks.  Returns what is still pending."""
        readers, writer, nav, chunk, overlap = self.readers, self.writer, self.nav, self.chunk, self.overlap
        with stage("read input"):               # (one input stage per signal: the same span of samples)
            if threads.threads() > 1:           # the next chunk is read ahead on a background thread
                blocks = [r.chunk(start, chunk + overlap, start + chunk) for r in readers]
            else:
                blocks = [r.read(start, chunk + overlap) for r in readers]
        if self.vector is None and self.handover is not None:
            self.vector = self.handover.step(start)
        if self.vector is not None:
            with stage("vector tracking"):
                block_recs, self.vfixes = self.vector.process(blocks, start)
            with stage("write"):
                writer.append_fixes(self.vfixes)
                writer.append_vector_log(self.vector.last_diag)
        else:
            # the channels run in parallel (compiled epoch loop without the GIL; receiver/threads.py)
            with stage("tracking"):
                # (a channel behind the chunk start was offered the end of the input already: the last
                # chunk of a file that ends just past a chunk boundary)
                items = [(part.key(prn), ch, blk) for part, blk in zip(self.parts, blocks)
                         for prn, ch in part.manager.channels.items() if ch.next_sample >= start]
                job = threads.submit_ordered(lambda it, s0=start: it[1].process(it[2], s0), items)
            if pending is not None:             # the previous chunk's epochs, while the pool tracks
                self.finish_chunk(pending)
                pending = None
            with stage("tracking"):
                block_recs = {key: r for (key, _, _), r in zip(items, job())}
        for part in self.parts:
            for prn, ch in list(part.manager.channels.items()):
                key = part.key(prn)
                recs = block_recs.get(key, np.zeros(0, EPOCH_DTYPE))
                with stage("write"):
                    writer.append_channel(key, recs)
                if len(recs):
                    c = recs["cn0_dbhz"][recs["pll_lock"] > 0]
                    if len(c):
                        acc = self.cn0_sum.setdefault(key, [0.0, 0])
                        acc[0] += float(c.sum())
                        acc[1] += len(c)
                part.manager.note(prn, recs)
                if nav is not None:
                    with stage("navigation"):
                        nav.add_records(key, recs, ch.bit_offset, ch.dll_hold_s)
        if self.vector is not None and self.vector.reinit_needed:
            self.vector = self.handover.fall_back(self.vector, start + chunk)   # scalar channels, hand over again
        # channel lifecycle: lost channels -> re-acquisition around the prediction; cold search of the rest.
        # Before the chunk's navigation epochs: a satellite found again inside the chunk just tracked (its
        # channel catches up to the chunk end) enters the epochs after its pull-in, not only the next chunk's
        if start + chunk + overlap < self.reader.end:
            with stage("re-acquisition"):
                for part in self.parts:
                    part.manager.after_chunk(start, start + chunk)
        if self.dual is not None:
            with stage("tracking"):
                self.dual.chunk(start, chunk)
        return pending

    def summary(self, t_wall) -> RunSummary:
        """The run's summary; the run file's closing attributes, ephemerides and ionosphere written."""
        cfg, reader, writer, nav, iono, parts = self.cfg, self.reader, self.writer, self.nav, self.iono, self.parts
        wall = time.perf_counter() - t_wall
        s = RunSummary(output="", duration_s=reader.duration_s, wall_s=wall, system=_run_system(cfg))
        s.mean_cn0 = {p: v[0] / v[1] for p, v in sorted(self.cn0_sum.items()) if v[1]}
        s.tracked = sorted(s.mean_cn0)
        s.n_fixes = self.n_fixes
        s.first_fix_s = self.first_fix
        s.iono_counts, s.iono_broadcast_from_s = self.iono_counts, self.iono_from
        s.reacquisitions = sum(v["reacquisitions"] for part in parts for v in part.manager.summary().values())
        s.false_locks = {part.key(p): v["false_locks"] for part in parts
                         for p, v in part.manager.summary().items() if v["false_locks"]}
        for part in parts:
            if hasattr(part.reader, "resample"):      # the decimating input stage
                s.notes.append(part.reader.describe() + (f" [{part.signal.name}]" if self.multi else ""))
        if hasattr(reader, "summary_lines"):         # the input conditioning stage
            s.notes += reader.summary_lines()
            reader.write(writer)
        s.notes += self.notes
        if self.dual is not None:
            s.notes += self.dual.finish()
        if nav is not None:
            s.parity_failures = sum(ch.decoder.parity_failures for ch in nav.channels.values())
            # every satellite decoded during the run (navigation memory, not only the channels still tracking)
            writer.write_ephemerides(nav.decoded_ephemerides())
            # the RINEX header's set (its GPS-UTC terms even without ION ALPHA / BETA), else the decoded one
            bc = nav.broadcast_iono()
            from_bds = any(ch.decoder.iono_utc is bc and ch.signal.system == "C" for ch in nav.channels.values())
            writer.write_iono_utc(iono if iono is not None else bc,
                                  "rinex" if iono is not None else ("d1/d2" if from_bds else "lnav"))
            if nav.iono_fallback is not None:               # /navigation/iono_params 2: this set
                from .gnss.atmosphere import FALLBACK_KLOBUCHAR_SOURCE
                writer.set_attrs("navigation", {
                    "iono_fallback_alpha": np.asarray(nav.iono_fallback.alpha, float),
                    "iono_fallback_beta": np.asarray(nav.iono_fallback.beta, float),
                    "iono_fallback_source": FALLBACK_KLOBUCHAR_SOURCE})
        if self.fix_ecef:
            from .gnss.geodesy import ecef2enu, ecef2lla
            e = np.concatenate(self.fix_ecef)
            mean = e.mean(axis=0)
            lat, lon, h = ecef2lla(mean)
            s.mean_llh = (float(lat), float(lon), float(h))
            s.scatter_m = tuple(float(v) for v in ecef2enu(e, mean).std(axis=0))
        writer.set_attrs("/", {"wall_time_s": wall, "realtime_factor": s.realtime_factor,
                               "n_fixes": self.n_fixes})
        return s
