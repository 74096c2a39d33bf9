"""Dual-frequency recordings on one receiver clock: GPS L1 + L5 and Galileo E1 + E5a.

GPS L1 + L5: ``simulate_l1_l5`` writes the L1 C/A file as
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

Galileo E1 + E5a (``e5a.enabled``, a ``signal: gal_e1`` scenario): ``simulate_l1_l5`` writes, beside the E1 file,
``<stem>_e5a.bin`` holding E5a-Q (CS100_n of the PRN, aligned to the satellite's 100-ms epochs) and E5a-I
(CS20_1 x pseudo-random 50-sps symbols: F/NAV is not modelled) of every Galileo satellite, on the same clock,
the ionosphere (f_E1 / f_E5a)^2 times the E1 one.  Group delays (ICD 5.1.5): the I/NAV word type 5 of the E1
file carries BGD(E1,E5a) of each satellite (data/gal_nominal_constellation.yaml); the E1 signal leaves with the
E1 single-frequency clock dt(E1) = dt(E1,E5b) - BGD(E1,E5b) (the I/NAV clock, Eq. 15), the E5a signal with the
E5a single-frequency clock of the E1/E5a pair, dt(E5a) = dt(E1,E5a) - gamma BGD(E1,E5a) (Eq. 16) where
dt(E1,E5a) = dt(E1) + BGD(E1,E5a) (Eq. 15 for that pair): the E5a clock is dt(E1) + (1 - gamma) BGD(E1,E5a)
(:func:`e5a_clock_offset_s`).  Not modelled: F/NAV, E5b, the AltBOC side band structure (E5a is a QPSK signal of
its own, as a receiver filtering E5a alone sees it).
"""
from __future__ import annotations

import math
import os
import types

import numpy as np
import yaml

from ..errors import UserError
from ..gnss.l5_codes import nh_signs
from ..gnss.signals import L1_HZ
from ..gnss.signals_l5 import GPS_L5
from ..gnss.signals_gal_e5a import GAL_E5A
from ..safeio import TMP_SUFFIX, OutputLock, check_output, write_error_message
from .outputs import output_paths, remove_files
from .scenario import load_scenario

#: L5 group delay / L1 group delay of the same ionosphere
GAMMA_15 = (L1_HZ / GPS_L5.carrier_hz) ** 2
#: E5a group delay / E1 group delay of the same ionosphere (the same number: E1 = L1, E5a = L5)
GAMMA_E1E5A = (L1_HZ / GAL_E5A.carrier_hz) ** 2


def e5a_clock_offset_s(bgd_e1e5a_s: float) -> float:
    """The E5a single-frequency satellite clock minus the E1 one (s) of a satellite broadcasting
    BGD(E1,E5a): (1 - gamma) BGD (ICD Eqs. 15-16 with dt(E1,E5a) = dt(E1) + BGD(E1,E5a)).  Besides the
    ionosphere, the E5a pseudorange is then c (gamma - 1) BGD longer than the E1 one."""
    return (1.0 - GAMMA_E1E5A) * bgd_e1e5a_s


def l5_path(out_path, tag: str = "l5") -> str:
    """The band file's name beside the L1 / E1 file ``out_path`` (``x.bin`` -> ``x_l5.bin``; tag e5a:
    ``x_e5a.bin``)."""
    p = os.fspath(out_path)
    stem, ext = os.path.splitext(p)
    return stem + "_" + tag + (ext or ".bin")


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
    ahead), each at the pilot's amplitude (IS-GPS-705: equal power); none for a satellite of another system."""
    if p not in sim.band_keys:
        return
    n0 = len(sig)
    type(sim)._sat_rows(sim, b, p, s, sig)               # the Q5 row, as for any 1-ms signal
    if len(sig) == n0:
        return
    _, chips_blk, ph, amp, _, _ = sig[-1]
    ms0 = int(math.floor(s.chips_total[0] / s.code_n))
    dsign = sim.nav[p].signs_i(sim.m_ref + ms0, int(chips_blk[-1] // s.code_n) + 2)
    sig.append((p, chips_blk, ph + 0.25, amp, dsign, sim.i5_codes[p]))


class _E5aSigns:
    """Per-millisecond signs of Galileo satellite ``prn``'s E5a components: E5a-Q (``signs``) CS100_prn,
    aligned to the satellite's 100-ms epochs; E5a-I (``signs_i``) CS20_1 x 50-sps symbols, pseudo-random (a fixed
    function of PRN, seed and symbol index: F/NAV is not modelled)."""

    def __init__(self, prn: int, seed: int):
        self.cs100, self.cs20 = GAL_E5A.secondary(prn), GAL_E5A.data_secondary(prn)
        self.prn, self.seed = prn, seed

    def signs(self, ms_abs0, count):
        """E5a-Q signs of satellite-time ms ``ms_abs0`` .. ``ms_abs0 + count - 1``."""
        return self.cs100[(np.int64(ms_abs0) + np.arange(count)) % 100]

    def signs_i(self, ms_abs0, count):
        """E5a-I signs of the same milliseconds."""
        ms = np.int64(ms_abs0) + np.arange(count, dtype=np.int64)
        h = ((ms // 20) * np.int64(0x9E3779B1) + np.int64(self.prn) * np.int64(0x85EBCA77)
             + np.int64(self.seed) * np.int64(0xC2B2AE3D) + np.int64(0x5A5A)) & np.int64(0xFFFFFFFF)
        h = ((h ^ (h >> 15)) * np.int64(0x2C1B3C6D)) & np.int64(0xFFFFFFFF)
        sym = (1.0 - 2.0 * ((h >> 11) & 1)).astype(np.float32)
        return sym * self.cs20[ms % 20]


def _e5a_rows(sim, b, p, s, sig):
    """The E5a simulator's kernel rows of satellite p: E5a-Q (the truth's carrier phase) and E5a-I (a quarter
    cycle ahead), each at the pilot's amplitude; none for a satellite of another system.  (The simulator counts
    a Galileo satellite's chips from a 4-ms boundary, ``m_ref_gal``: the 1-ms periods of E5a are numbered from
    4 m_ref_gal.)"""
    if p not in sim.band_keys or not (b.n_samp > 0 and np.any(s.amp > 0)):
        return
    code_n, chips_total = s.code_n, s.chips_total
    ms0 = int(math.floor(chips_total[0] / code_n))
    chips_blk = chips_total - ms0 * code_n
    count = int(chips_blk[-1] // code_n) + 2
    ms_abs = 4 * sim.m_ref_gal + ms0
    ph = s.if_hz * b.t_rel + s.carr
    a32 = s.amp.astype(np.float32)
    sig.append((p, chips_blk, ph, a32, sim.nav[p].signs(ms_abs, count), sim.codes[p]))
    sig.append((p, chips_blk, ph + 0.25, a32, sim.nav[p].signs_i(ms_abs, count), sim.i5_codes[p]))


def _e5a_geometry(sim, b):
    """The E1 simulator's geometry with each Galileo satellite's clock moved to its E5a clock
    (e5a_clock_offset_s of its broadcast BGD(E1,E5a))."""
    type(sim)._block_geometry(sim, b)
    for p, q in b.geo.items():
        if p in sim.e5a_clock_offset:
            q["clk"] = q["clk"] + sim.e5a_clock_offset[p]


def _as_band(sim, signal, system: str, factor: float, gamma: float, cn0_offset_db: float, rows, signs):
    """Turn a simulator of the base signal (built on the band's front-end settings) into the band's: its
    satellites of ``system`` (``band_keys``; the others of a recording of several signals stay silent, as
    the visibility and blockage of all are drawn as in the base file, and are left out of the truth) carry
    ``signal`` (primary codes, ``signs(prn)`` per ms, kernel rows ``rows``), ionosphere ``factor x gamma``."""
    keys = [p for p in sim.prns if sim.sat_sig[p][0].system == system]
    other = [sim.sat_sig[p][1] for p in keys if sim.sat_sig[p][1] not in signal.prns]
    if other:
        raise UserError(f"{signal.name}: satellite {system}{other[0]:02d} has no {signal.name} code here: set "
                        f"constellation.exclude_prns"
                        + (" or constellation.qzss: false" if system == "G" else ""))
    if not keys:
        raise UserError(f"{signal.name}: no satellite of system {system} in the recording")
    sim.band_keys = set(keys)
    sim.truth_prns = keys
    sim.signals, sim.signal = [signal], signal
    sim.sat_sig = {p: (signal, sim.sat_sig[p][1], sim.if_hz) for p in sim.prns}
    sim.codes = {p: signal.code(sim.sat_sig[p][1]) for p in keys}
    sim.i5_codes = {p: signal.data_code(sim.sat_sig[p][1]) for p in keys}
    sim.nav = {p: signs(sim.sat_sig[p][1]) for p in keys}
    sim._sat_rows = types.MethodType(rows, sim)
    sim.iono_scale = {p: factor * gamma for p in sim.prns}
    base = sim.cn0
    sim.cn0 = lambda prn, t_rel, el_deg: base(prn, t_rel, el_deg) + cn0_offset_db


def _as_e5a(sim, factor: float, cn0_offset_db: float, seed: int):
    """Turn a Galileo E1 simulator (or one of several signals with gal_e1) built on the E5a front-end settings
    into the E5a one."""
    _as_band(sim, GAL_E5A, "E", factor, GAMMA_E1E5A, cn0_offset_db, _e5a_rows, lambda prn: _E5aSigns(prn, seed))
    sim.e5a_clock_offset = {p: e5a_clock_offset_s(sim.ephs[p].bgd_e1e5a) for p in sim.band_keys}
    sim._block_geometry = types.MethodType(_e5a_geometry, sim)
    sim.rng = np.random.default_rng(np.random.SeedSequence([seed, 1, 5, 1]))      # own noise stream


def _as_l5(sim, factor: float, cn0_offset_db: float, seed: int):
    """Turn a GPS L1 C/A simulator (or one of several signals with gps_l1ca) built on the L5 front-end settings
    into the L5 Q5 one."""
    _as_band(sim, GPS_L5, "G", factor, GAMMA_15, cn0_offset_db, _l5_rows, lambda prn: _L5Signs(prn, seed))
    sim.rng = np.random.default_rng(np.random.SeedSequence([seed, 1, 5]))      # own noise stream


#: the band of each scenario section: (tag, band signal name, base signal name, the conversion of a base simulator)
_BANDS = {"l5": ("l5", "gps_l5", "gps_l1ca", _as_l5), "e5a": ("e5a", "gal_e5a", "gal_e1", _as_e5a)}


def band_keys(sc) -> list:
    """The scenario's enabled band sections (``l5``, ``e5a``)."""
    return [k for k in _BANDS if getattr(sc, k).enabled]


def simulate_l1_l5(sc, out_path, reads, progress, simulator, scale_ionosphere) -> dict:
    """Write the L1 / E1 recording and beside it one band file per enabled band (l5.enabled: GPS L5;
    e5a.enabled: Galileo E5a; both in a recording of gps_l1ca and gal_e1), each with its truth, and the
    receiver fragment naming them all.  ``simulator``, ``scale_ionosphere``: receiver.sim.simulate's simulator
    class and ionosphere scaling (passed in: that module calls this one).  Returns the L1 paths plus ``l5_if``
    and ``l5_truth`` (E5a: ``e5a_if``, ``e5a_truth``)."""
    _Simulator, _remove = simulator, remove_files
    names = list(sc.signals or []) or [sc.signal]
    bands = band_keys(sc)
    for key in bands:
        tag, band_name, base_name, _ = _BANDS[key]
        if base_name not in names:
            raise UserError(f"{key}.enabled: the {band_name} file is the second band of {base_name}: the scenario's "
                            f"signal (or signals) must include {base_name}")
    if "l5" in bands and sc.constellation.source not in ("embedded", "rinex"):
        raise UserError("l5.enabled: constellation.source must give GPS orbits (embedded or rinex)")
    factor = sc.atmosphere.iono_scale
    paths1 = output_paths(out_path)
    sim1 = _Simulator(sc)
    scale_ionosphere(sim1, factor)
    band_runs = []                               # (key, its config section, paths, simulator)
    for key in bands:
        tag, band_name, base_name, convert = _BANDS[key]
        b = getattr(sc, key)
        scb = load_scenario(sc, [f"frontend.sample_rate_hz={b.sample_rate_hz!r}", f"frontend.if_hz={b.if_hz!r}",
                                 f"frontend.format={b.format}"])
        simb = _Simulator(scb)
        convert(simb, factor, b.cn0_offset_db, sc.time.seed)
        band_runs.append((key, b, output_paths(l5_path(out_path, tag)), simb))
    all_paths = [paths1] + [r[2] for r in band_runs]
    for paths in all_paths:
        for kind, p in paths.items():
            check_output(p, reads, what="output")
    locks = [OutputLock(paths["if"]).acquire() for paths in all_paths]
    tmps = [{k: v + TMP_SUFFIX for k, v in paths.items()} for paths in all_paths]
    try:
        try:
            sim1.run(paths1, progress, tmps[0])
            for (_, _, paths, simb), tmp in zip(band_runs, tmps[1:]):
                simb.run(paths, progress, tmp)
        except OSError as exc:
            raise UserError(write_error_message("output", paths1["if"], exc)) from None
        _fragment(tmps[0]["yaml"], [(_BANDS[k][1], b, paths["if"]) for k, b, paths, _ in band_runs])
        for paths, tmp in list(zip(all_paths, tmps))[::-1]:          # the L1 / E1 file last
            for k in ("truth", "yaml", "sigmf", "tag", "if"):
                if k == "tag" and not os.path.exists(tmp[k]):
                    _remove([paths[k]])
                    continue
                os.replace(tmp[k], paths[k])
    except BaseException:
        _remove([v for tmp in tmps for v in tmp.values()])
        raise
    finally:
        for lk in locks:
            lk.release()
    out = dict(paths1)
    for key, _, paths, _ in band_runs:
        out[f"{_BANDS[key][0]}_if"], out[f"{_BANDS[key][0]}_truth"] = paths["if"], paths["truth"]
    return out


def _fragment(path, bands):
    """The L1 / E1 file's receiver fragment: its signals and the bands' (``bands``: (signal name, scenario
    section, file) each), the band files in input.signal_files."""
    with open(path) as f:
        head = [ln for ln in f.read().splitlines() if ln.startswith("#")]
    with open(path) as f:
        frag = yaml.safe_load(f)
    frag["input"]["signal_files"] = {name: {"path": os.path.basename(file), "format": b.format,
                                            "sample_rate_hz": float(b.sample_rate_hz), "if_hz": float(b.if_hz)}
                                     for name, b, file in bands}
    base = list(frag.pop("signals", None) or [frag.get("signal", "gps_l1ca")])
    frag = {"signals": base + [name for name, _, _ in bands], **frag}
    with open(path, "w") as f:
        f.write("\n".join(head) + "\n")
        yaml.safe_dump(frag, f, sort_keys=False)
