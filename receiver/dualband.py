"""Second frequency bands in a run (``signals: [gps_l1ca, gps_l5]`` with the L5 file in
``input.signal_files``; ``[gal_e1, gal_e5a]`` with the E5a file; both pairs in one run, ``[gps_l1ca, gal_e1,
gps_l5, gal_e5a]``): each band's channels aided by the same satellites' L1 / E1 channels
(receiver.tracking.aided.AidedBand), the band observables and the ionosphere-free fixes
(receiver.navigation.ionofree.DualFrequency), written beside the L1 run's tables:

* ``/acquisition_l5`` (``/acquisition_e5a``): every band search (time, PRN, aided, detected, statistic,
  threshold, code phase, Doppler);
* ``/observables_l5`` (``/observables_e5a``): OBS_DTYPE rows of the band at the navigation epochs (pseudorange,
  the band channel's carrier phase, Doppler, C/N0, lock time, pilot half-cycle state);
* ``/navigation_ionofree``: FIX_DTYPE rows of the ionosphere-free fixes of all the run's pairs together (the
  single-frequency fixes stay in ``/navigation``, computed as without the second bands).

The L1 part of the run is that of an L1-only run: the bands only read the L1 / E1 channels' state.
"""
from __future__ import annotations

from .acquisition.config import BAND_BASE, BAND_SIGNALS
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


def band_signals(cfg) -> list:
    """The run's second-band signal names (BAND_SIGNALS), in the order of ``signals``."""
    return [n for n in run_signals(cfg) if n in BAND_SIGNALS]


def band_signal(cfg):
    """The run's second-band signal names joined by commas (run-file attribute ``band_signal``), or None."""
    return ",".join(band_signals(cfg)) or None


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


class _Band:
    """One second band: its signal ``name``, run-file table suffix ``tag`` (gps_l5 -> l5, gal_e5a -> e5a),
    the aiding signal's part of the chunk loop ``part`` and the channels ``band`` (AidedBand)."""

    def __init__(self, cfg, name, reader, loop):
        self.name = name
        self.tag = name.split("_")[-1]
        self.part = next(p for p in loop.parts if p.signal.name == BAND_BASE[name])
        a = cfg.acquisition
        self.band = AidedBand(cfg.tracking, reader, get_signal(name), loop.fs, loop.reader.first,
                              aiding=a.band_aiding, n_ms=a.band_ms, base=self.part.signal)
        self.cn0 = {}


class DualBand:
    """The run's second bands, signals ``names`` read by ``readers``, driven by the chunk loop ``loop``
    (receiver.pipeline._ChunkLoop)."""

    def __init__(self, cfg, names, readers, loop):
        self.bands = [_Band(cfg, n, r, loop) for n, r in zip(names, readers)]
        self.loop = loop
        self.dual = DualFrequency(cfg.navigation, [(b.band, b.part.key) for b in self.bands],
                                  loop.nav) if loop.nav is not None else None
        self.n_fixes = 0

    def chunk(self, start: int, n: int):
        """Track every band over the L1 chunk at ``start`` (``n`` samples), then search for the satellites
        the L1 / E1 channels track that the band does not."""
        for b in self.bands:
            recs = b.band.process(start, n, self.loop.overlap)
            for prn, r in recs.items():
                c = r["cn0_dbhz"][r["pll_lock"] > 0]
                if len(c):
                    acc = b.cn0.setdefault(prn, [0.0, 0])
                    acc[0] += float(c.sum())
                    acc[1] += len(c)
            b.band.start(b.part.manager.channels, start + n)
            self.loop.writer.append_band(f"acquisition_{b.tag}", b.band.take_searches())

    def epochs(self, fixes, obs):
        """The bands' observables and the ionosphere-free fixes of the navigation epochs ``fixes``."""
        if self.dual is None or not len(fixes):
            return
        per_band, f = self.dual.epochs(fixes, obs)
        for b, o in zip(self.bands, per_band):
            self.loop.writer.append_band(f"observables_{b.tag}", o)
        self.loop.writer.append_band("navigation_ionofree", f)
        self.n_fixes += len(f)

    def finish(self) -> list:
        """Summary lines."""
        lines = []
        for b in self.bands:
            mean = {p: v[0] / v[1] for p, v in sorted(b.cn0.items()) if v[1]}
            lines.append(f"{b.name:<15} {len(mean)} satellites tracked: "
                         + " ".join(f"{b.band.signal.system}{p:02d}({c:.1f})" for p, c in mean.items()))
        if self.dual is not None:
            pairs = "+".join(("L1" if b.part.signal.system == "G" else "E1") + "/" + b.tag.upper() for b in self.bands)
            lines.append(f"ionosphere-free {self.n_fixes} {pairs} fixes (/navigation_ionofree)")
        return lines
