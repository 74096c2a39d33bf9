"""A second frequency band in a run (``signals: [gps_l1ca, gps_l5]`` with the L5 file in
``input.signal_files``): the L5 channels aided by the L1 ones (receiver.tracking.aided.AidedBand), the L5
observables and the ionosphere-free fixes (receiver.navigation.ionofree.DualFrequency), written beside the
L1 run's tables:

* ``/acquisition_l5``: every L5 search (time, PRN, aided, detected, statistic, threshold, code phase, Doppler);
* ``/observables_l5``: OBS_DTYPE rows of the L5 pseudoranges at the navigation epochs;
* ``/navigation_ionofree``: FIX_DTYPE rows of the L1/L5 ionosphere-free fixes (the L1-only fixes stay in
  ``/navigation``, computed as without the second band).

The L1 part of the run is that of an L1-only run: the band only reads the L1 channels' state.
"""
from __future__ import annotations

from .acquisition.config import BAND_SIGNALS
from .errors import UserError
from .gnss.registry import get_signal
from .navigation.ionofree import DualFrequency
from .schema import run_signals
from .source.io import SampleReader
from .tracking.aided import AidedBand


def core_signals(cfg) -> list:
    """The run's signals acquired, tracked and navigated on the first signal's sample clock (all but
    BAND_SIGNALS)."""
    return [n for n in run_signals(cfg) if n not in BAND_SIGNALS]


def band_signal(cfg):
    """The run's second-band signal name (one of BAND_SIGNALS), or None."""
    return next((n for n in run_signals(cfg) if n in BAND_SIGNALS), None)


def open_band_input(cfg, name: str) -> SampleReader:
    """The input stage of second-band signal ``name``: its own file of input.signal_files with its own format,
    rate and IF (no decimation or conditioning stage), spanning the same time as input.path."""
    i = cfg.input
    own = (i.signal_files or {}).get(name)
    if not own:
        raise UserError(f"config key 'input.signal_files.{name}': signal {name} is read from a file of its own "
                        f"(e.g. {{{name}: {{path: l5.bin, format: int8_iq, sample_rate_hz: 20.46e6, if_hz: 0}}}})")
    reader = SampleReader(own["path"], own.get("format", i.format), own.get("sample_rate_hz", i.sample_rate_hz),
                          i.skip_s, i.duration_s, i.iq_swap, header_bytes=i.header_bytes, bit_order=i.bit_order,
                          encoding=i.encoding)
    reader.if_hz = float(own.get("if_hz", 0.0))
    return reader


class DualBand:
    """The run's second band, signal ``name`` read by ``reader``, driven by the chunk loop ``loop``
    (receiver.pipeline._ChunkLoop)."""

    def __init__(self, cfg, name, reader, loop):
        self.name = name
        sig = get_signal(self.name)
        self.tag = self.name.split("_")[-1]              # gps_l5 -> l5: the run-file table suffix
        a = cfg.acquisition
        self.band = AidedBand(cfg.tracking, reader, sig, loop.fs, loop.reader.first, aiding=a.band_aiding,
                              n_ms=a.band_ms)
        self.loop = loop
        self.dual = DualFrequency(cfg.navigation, self.band, loop.nav) if loop.nav is not None else None
        self.cn0 = {}
        self.n_fixes = 0

    def chunk(self, start: int, n: int):
        """Track the band over the L1 chunk at ``start`` (``n`` samples), then search for the satellites
        the L1 channels track that the band does not."""
        recs = self.band.process(start, n, self.loop.overlap)
        for prn, r in recs.items():
            c = r["cn0_dbhz"][r["pll_lock"] > 0]
            if len(c):
                acc = self.cn0.setdefault(prn, [0.0, 0])
                acc[0] += float(c.sum())
                acc[1] += len(c)
        self.band.start(self.loop.parts[0].manager.channels, start + n)
        self.loop.writer.append_band(f"acquisition_{self.tag}", self.band.take_searches())

    def epochs(self, fixes, obs):
        """The band's observables and the ionosphere-free fixes of the navigation epochs ``fixes``."""
        if self.dual is None or not len(fixes):
            return
        o, f = self.dual.epochs(fixes, obs)
        self.loop.writer.append_band(f"observables_{self.tag}", o)
        self.loop.writer.append_band("navigation_ionofree", f)
        self.n_fixes += len(f)

    def finish(self) -> list:
        """Summary lines."""
        mean = {p: v[0] / v[1] for p, v in sorted(self.cn0.items()) if v[1]}
        lines = [f"{self.name:<15} {len(mean)} satellites tracked: "
                 + " ".join(f"G{p:02d}({c:.1f})" for p, c in mean.items())]
        if self.dual is not None:
            lines.append(f"ionosphere-free {self.n_fixes} L1/{self.tag.upper()} fixes (/navigation_ionofree)")
        return lines
