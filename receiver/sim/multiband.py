"""GPS L1 + L5 recordings on one receiver clock: ``simulate_l1_l5`` writes the L1 C/A file as
:func:`receiver.sim.simulate.simulate` does and, beside it, ``<stem>_l5.bin`` holding the GPS L5 Q5 pilot of
the same satellites (IS-GPS-705 codes: Q5 + NH20, I5 + NH10), each file with its own truth
(``<stem>_l5.truth.h5``).

One clock: both files come from the same scenario, so the receiver clock (bias, drift, noise: seeded by
``time.seed`` on the same 1-ms grid), the trajectory and the satellite geometry are the same; sample 0 of
both files is the clock reading ``time.tow_s``, and sample n of each is ``n / fs`` of that file later (the
files differ only in rate, IF and format: ``l5.*``).  The thermal noise of the L5 file is an independent
stream.

Ionosphere: the true L1 group delay is ``atmosphere.iono_scale`` times the broadcast Klobuchar delay; on L5
it is (f_L1 / f_L5)^2 = 1.793 times the L1 delay; the code is delayed and the carrier advanced by it
(the simulator's conventions).  Satellite clock: the L1 C/A clock of the ephemeris (af0.. + relativity -
TGD) on both bands, i.e. inter-signal corrections ISC_L1CA = ISC_L5Q5 = 0.

Signal: Q5 (NH20) and I5 (NH10 x pseudo-random 100-sps symbols: CNAV is not modelled) in quadrature, each at
the pilot C/N0 (L1 C/N0 + ``l5.cn0_offset_db``).  Not modelled: CNAV, QZSS L5, frequency-dependent
scintillation.
"""
from __future__ import annotations

import math
import os
import types

import numpy as np
import yaml

from ..errors import UserError
from ..gnss.l5_codes import L5_PRNS, nh_signs
from ..gnss.signals import L1_HZ
from ..gnss.signals_l5 import GPS_L5
from ..safeio import TMP_SUFFIX, OutputLock, check_output, write_error_message
from .outputs import output_paths, remove_files
from .scenario import load_scenario

#: L5 group delay / L1 group delay of the same ionosphere
GAMMA_15 = (L1_HZ / GPS_L5.carrier_hz) ** 2


def l5_path(out_path) -> str:
    """The L5 file's name beside the L1 file ``out_path`` (``x.bin`` -> ``x_l5.bin``)."""
    p = os.fspath(out_path)
    stem, ext = os.path.splitext(p)
    return stem + "_l5" + (ext or ".bin")


class _L5Signs:
    """Per-millisecond signs of satellite ``prn``'s L5 components: Q5 (``signs``) NH20, aligned to the
    satellite's 20-ms epochs; I5 (``signs_i``) NH10 x 100-sps symbols, pseudo-random (a fixed function of PRN,
    seed and symbol index: CNAV is not modelled)."""

    def __init__(self, prn: int, seed: int):
        self.nh20, self.nh10 = nh_signs(20), nh_signs(10)
        self.prn, self.seed = prn, seed

    def signs(self, ms_abs0, count):
        """Q5 signs of satellite-time ms ``ms_abs0`` .. ``ms_abs0 + count - 1``."""
        return self.nh20[(np.int64(ms_abs0) + np.arange(count)) % 20]

    def signs_i(self, ms_abs0, count):
        """I5 signs of the same milliseconds."""
        ms = np.int64(ms_abs0) + np.arange(count, dtype=np.int64)
        h = ((ms // 10) * np.int64(0x9E3779B1) + np.int64(self.prn) * np.int64(0x85EBCA77)
             + np.int64(self.seed) * np.int64(0xC2B2AE3D)) & np.int64(0xFFFFFFFF)
        h = ((h ^ (h >> 15)) * np.int64(0x2C1B3C6D)) & np.int64(0xFFFFFFFF)
        sym = (1.0 - 2.0 * ((h >> 11) & 1)).astype(np.float32)
        return sym * self.nh10[ms % 10]


def _l5_rows(sim, b, p, s, sig):
    """The L5 simulator's kernel rows of satellite p: Q5 (the truth's carrier phase) and I5 (a quarter cycle
    ahead), each at the pilot's amplitude (IS-GPS-705: equal power)."""
    n0 = len(sig)
    type(sim)._sat_rows(sim, b, p, s, sig)               # the Q5 row, as for any 1-ms signal
    if len(sig) == n0:
        return
    _, chips_blk, ph, amp, _, _ = sig[-1]
    ms0 = int(math.floor(s.chips_total[0] / s.code_n))
    dsign = sim.nav[p].signs_i(sim.m_ref + ms0, int(chips_blk[-1] // s.code_n) + 2)
    sig.append((p, chips_blk, ph + 0.25, amp, dsign, sim.i5_codes[p]))


def _as_l5(sim, factor: float, cn0_offset_db: float, seed: int):
    """Turn a GPS L1 C/A simulator built on the L5 front-end settings into the L5 Q5 one."""
    other = [p for p in sim.prns if p not in L5_PRNS]
    if other:
        raise UserError(f"l5.enabled: satellite {other[0]} has no L5 code here (GPS PRN 1-32 only): set "
                        "constellation.qzss: false or constellation.exclude_prns")
    sim.signals, sim.signal = [GPS_L5], GPS_L5
    sim.sat_sig = {p: (GPS_L5, p, sim.if_hz) for p in sim.prns}
    sim.codes = {p: GPS_L5.code(p) for p in sim.prns}
    sim.i5_codes = {p: GPS_L5.data_code(p) for p in sim.prns}
    sim.nav = {p: _L5Signs(p, seed) for p in sim.prns}
    sim._sat_rows = types.MethodType(_l5_rows, sim)
    sim.iono_scale = {p: factor * GAMMA_15 for p in sim.prns}
    base = sim.cn0
    sim.cn0 = lambda prn, t_rel, el_deg: base(prn, t_rel, el_deg) + cn0_offset_db
    sim.rng = np.random.default_rng(np.random.SeedSequence([seed, 1, 5]))      # own noise stream


def simulate_l1_l5(sc, out_path, reads, progress, simulator, scale_ionosphere) -> dict:
    """Write the L1 and L5 recordings (and their truth and fragment files) of scenario ``sc`` (l5.enabled).
    ``simulator``, ``scale_ionosphere``: receiver.sim.simulate's simulator class and ionosphere scaling
    (passed in: that module calls this one).  Returns the L1 paths plus ``l5_if`` and ``l5_truth``."""
    _Simulator, _remove = simulator, remove_files
    if sc.signals or sc.signal != "gps_l1ca":
        raise UserError("l5.enabled: the L1 + L5 recording is a GPS L1 C/A scenario (signal: gps_l1ca, "
                        "no signals list)")
    if sc.constellation.source not in ("embedded", "rinex"):
        raise UserError("l5.enabled: constellation.source must give GPS orbits (embedded or rinex)")
    l5 = sc.l5
    paths1, paths5 = output_paths(out_path), output_paths(l5_path(out_path))
    factor = sc.atmosphere.iono_scale
    sim1 = _Simulator(sc)
    scale_ionosphere(sim1, factor)
    sc5 = load_scenario(sc, [f"frontend.sample_rate_hz={l5.sample_rate_hz!r}", f"frontend.if_hz={l5.if_hz!r}",
                             f"frontend.format={l5.format}"])
    sim5 = _Simulator(sc5)
    _as_l5(sim5, factor, l5.cn0_offset_db, sc.time.seed)
    for paths in (paths1, paths5):
        for kind, p in paths.items():
            check_output(p, reads, what="output")
    locks = [OutputLock(paths1["if"]).acquire(), OutputLock(paths5["if"]).acquire()]
    tmp1 = {k: v + TMP_SUFFIX for k, v in paths1.items()}
    tmp5 = {k: v + TMP_SUFFIX for k, v in paths5.items()}
    try:
        try:
            sim1.run(paths1, progress, tmp1)
            sim5.run(paths5, progress, tmp5)
        except OSError as exc:
            raise UserError(write_error_message("output", paths1["if"], exc)) from None
        _fragment(tmp1["yaml"], paths5["if"], l5)
        for paths, tmp in ((paths5, tmp5), (paths1, tmp1)):
            for k in ("truth", "yaml", "sigmf", "tag", "if"):
                if k == "tag" and not os.path.exists(tmp[k]):
                    _remove([paths[k]])
                    continue
                os.replace(tmp[k], paths[k])
    except BaseException:
        _remove([*tmp1.values(), *tmp5.values()])
        raise
    finally:
        for lk in locks:
            lk.release()
    return {**paths1, "l5_if": paths5["if"], "l5_truth": paths5["truth"]}


def _fragment(path, l5_file, l5):
    """The L1 file's receiver fragment: both signals, the L5 file in input.signal_files."""
    with open(path) as f:
        head = [ln for ln in f.read().splitlines() if ln.startswith("#")]
    with open(path) as f:
        frag = yaml.safe_load(f)
    frag["input"]["signal_files"] = {"gps_l5": {"path": os.path.basename(l5_file), "format": l5.format,
                                                "sample_rate_hz": float(l5.sample_rate_hz),
                                                "if_hz": float(l5.if_hz)}}
    frag = {"signals": ["gps_l1ca", "gps_l5"], **frag}
    with open(path, "w") as f:
        f.write("\n".join(head) + "\n")
        yaml.safe_dump(frag, f, sort_keys=False)
