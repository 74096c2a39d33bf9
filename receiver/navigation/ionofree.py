"""Dual-frequency observables and the ionosphere-free fix (GPS L1/L5, Galileo E1/E5a, or both together), from
the navigation engine's epochs and the second bands' channels (receiver.tracking.aided.AidedBand).

L5 pseudorange: at the epoch's receiver instant the L5 channel's code phase gives the satellite's transmit
time modulo 1 ms (both codes start at whole milliseconds of the satellite clock); the L1 pseudorange of the
same epoch gives the whole milliseconds (the two differ by the ionospheric and hardware delays, metres, far
from the 0.5-ms ambiguity).  ``P5 = c (rx_tow - t_tx,L5)``: unsmoothed L5 code.

Ionosphere-free combination (gamma = (f_L1 / f_L5)^2 = 1.793): ``P_IF = (gamma P1 - P5) / (gamma - 1)``
(= 2.261 P1 - 1.261 P5), removing the first-order ionosphere of both bands; the fix is the L1 solver's
least squares on P_IF with the ionospheric model off, the troposphere, weighting and mask as configured.
Satellite clock: the L1 LNAV ephemeris of the same satellite (af0.., relativity, - TGD).  IS-GPS-705 gives
the L1/L5 ionosphere-free clock as that minus (ISC_L5I5 - gamma ISC_L1CA) / (1 - gamma) terms from CNAV, not
decoded here: the inter-signal corrections are taken as 0 (each ns of them is up to ~0.4-0.7 m here).

Galileo E1/E5a (the same frequencies, the same combination; E5a-Q code at whole milliseconds of the satellite
clock as the E1 code's 4-ms periods are): the E1 channel's I/NAV clock is the E1/E5b one, dt(E1,E5b), and the
navigation engine's satellite clock is the E1 single-frequency one, dt(E1) = dt(E1,E5b) - BGD(E1,E5b) (ICD Eq.
15).  The ionosphere-free E1/E5a combination needs dt(E1,E5a) = dt(E1) + BGD(E1,E5a) (Eq. 15 for the E1/E5a
pair; BGD(E1,E5a) = (TR_E1 - TR_E5a) / (1 - gamma), Eq. 14, is in the same I/NAV word type 5): the fix is
computed on ``P_IF + c BGD(E1,E5a)`` with the E1 clock (:func:`if_clock_correction_s`), no F/NAV needed.

Several pairs (GPS L1/L5 and Galileo E1/E5a): one least-squares fix over both systems' ionosphere-free
pseudoranges, with the inter-system clock bias column that the combined single-frequency fix uses.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..gnss.ephemeris import select
from ..gnss.signals import C_LIGHT, L1_HZ
from ..gnss.geodesy import ecef2lla
from ..runfile.record import FIX_DTYPE, IONO_NONE, OBS_DTYPE
from .pvt import NavSolver, Observation

_SOLVER_KEYS = ("elevation_mask_deg", "weighting", "cn0_ref_dbhz", "troposphere", "residual_threshold_m",
                "max_pdop")


def gamma(f2_hz: float) -> float:
    """(f_L1 / f2)^2: the ionospheric group delay on f2 over the one on L1."""
    return (L1_HZ / f2_hz) ** 2


def ionofree(p1, p2, g: float):
    """The ionosphere-free pseudorange of P1 (L1) and P2 (the band with delay ratio ``g``)."""
    return (g * np.asarray(p1) - np.asarray(p2)) / (g - 1.0)


def if_clock_correction_s(eph, band_signal) -> float:
    """The ionosphere-free pair's satellite clock minus the single-frequency one the navigation engine applies
    (s): Galileo E5a, BGD(E1,E5a) of the E1 channel's I/NAV (``eph.bgd_e1e5a``; module docstring); GPS L5, 0
    (ISCs not decoded)."""
    if band_signal.name == "gal_e5a":
        return float(getattr(eph, "bgd_e1e5a", 0.0))
    return 0.0


def band_pseudorange(pr1: float, rx_tow: float, code_phase_chips: float, chip_rate: float) -> float:
    """The second band's pseudorange at receiver time ``rx_tow`` from its code phase (chips into the
    1-ms code period) and the L1 pseudorange ``pr1`` of the same instant (whole milliseconds)."""
    tx1 = rx_tow - pr1 / C_LIGHT
    frac1 = tx1 % 1e-3
    d = (code_phase_chips / chip_rate - frac1 + 0.5e-3) % 1e-3 - 0.5e-3
    return (rx_tow - (tx1 + d)) * C_LIGHT


class DualFrequency:
    """Per navigation epoch: the band's observables and the ionosphere-free fix.

    nav_cfg: the receiver's ``navigation`` section; bands: a list of (AidedBand, key) with ``key(prn)`` the
    run's satellite key of the band's PRN (the navigation engine's observables are keyed by it); store: the
    navigation engine (ephemerides)."""

    def __init__(self, nav_cfg, bands, store):
        cfg = SimpleNamespace(**{k: getattr(nav_cfg, k) for k in _SOLVER_KEYS}, ionosphere="none")
        self.solver = NavSolver(cfg)
        self.bands = [SimpleNamespace(band=b, key=k, system=b.signal.system, g=gamma(b.signal.carrier_hz),
                                      lam=C_LIGHT / b.signal.carrier_hz) for b, k in bands]
        self.store = store
        self.x0 = None
        self.window = max(int(round(nav_cfg.smoothing_s * nav_cfg.rate_hz)), 1) if nav_cfg.smoothing_s > 0 else 1
        self.hatch = {}                      # satellite key -> (time_s, smoothed P5, carrier range, epochs)

    def epochs(self, fixes: np.ndarray, obs) -> tuple:
        """([OBS_DTYPE rows of each band], ionosphere-free FIX_DTYPE rows) of the engine's epochs ``fixes`` with
        their L1 / E1 observables ``obs``."""
        obs = np.asarray(obs, OBS_DTYPE) if len(obs) else np.zeros(0, OBS_DTYPE)
        out_obs, out_fix = [[] for _ in self.bands], []
        for f in fixes:
            rows = obs[obs["time_s"] == f["time_s"]]
            rx_tow = f["gps_tow"] + f["clock_bias_m"] / C_LIGHT
            pr, b_obs = {}, []
            for bd in self.bands:
                o, p = self._band_obs(bd, rows, rx_tow)
                b_obs.append(o)
                pr.update(p)
            fix = self._fix(int(f["gps_week"]), rx_tow, rows, pr)
            used = set(fix.prns) if fix is not None else set()
            for k, o in enumerate(b_obs):
                for r in o:
                    r["used_in_fix"] = 1 if r["prn"] in used else 0
                out_obs[k].extend(o)
            if fix is not None:
                lat, lon, h = ecef2lla(fix.ecef)
                out_fix.append((fix.gps_week, fix.gps_tow, f["time_s"], fix.ecef, fix.velocity_ecef,
                                fix.clock_bias_m, fix.clock_drift_mps, fix.n_sats, fix.pdop, fix.hdop, fix.vdop,
                                fix.gdop, 0, float(lat), float(lon), float(h), IONO_NONE))
        return [np.array(o, OBS_DTYPE) for o in out_obs], np.array(out_fix, FIX_DTYPE)

    def _band_obs(self, bd, rows, rx_tow):
        """The band ``bd``'s observables at the epoch of the L1 / E1 ``rows`` ({key: (P2, band)})."""
        out, pr = [], {}
        keys = {bd.key(p): p for p in bd.band.recs}
        sig = bd.band.signal
        for r in rows:
            key = int(r["prn"])
            prn = keys.get(key)
            if prn is None:
                continue
            m = bd.band.measure_at(prn, float(r["time_s"]))
            if m is None:
                continue
            p5 = band_pseudorange(float(r["pseudorange_m"]), rx_tow, m["chips"], sig.chip_rate)
            p5 = self._smooth(key, float(r["time_s"]), p5, -bd.lam * m["nco_cycles"])
            pr[key] = (p5, bd)
            o = r.copy()
            o["pseudorange_m"], o["cn0_dbhz"], o["residual_m"] = p5, m["cn0_dbhz"], np.nan
            o["doppler_hz"] = m["doppler_hz"]
            o["pseudorange_rate_mps"] = -o["doppler_hz"] * bd.lam
            o["carrier_phase_cycles"] = m["carrier_cycles"]
            o["lock_time_s"] = m["lock_time_s"]
            o["half_cycle_resolved"] = 1 if m["half_cycle_resolved"] else 0
            out.append(o)
        return out, pr

    def _smooth(self, prn, t, p5, carrier_m):
        """Hatch filter of the band's code with its carrier over navigation.smoothing_s (restarted after a gap
        of more than 1 s: the channel lost lock or was not measured)."""
        h = self.hatch.get(prn)
        if h is None or t - h[0] > 1.0 or t <= h[0]:
            self.hatch[prn] = (t, p5, carrier_m, 1)
            return p5
        n = min(h[3] + 1, self.window)
        s = p5 / n + (1.0 - 1.0 / n) * (h[1] + carrier_m - h[2])
        self.hatch[prn] = (t, s, carrier_m, n)
        return s

    def _fix(self, week, rx_tow, rows, pr5):
        obs = []
        ephs = self.store.ephemerides(rx_tow)
        for r in rows:
            p = int(r["prn"])
            if p not in pr5:
                continue
            p2, bd = pr5[p]
            p_if = float(ionofree(r["pseudorange_m"], p2, bd.g))
            eph = ephs.get(p) if ephs else None
            if isinstance(eph, (list, tuple)):
                eph = select(eph, rx_tow, week)
            if eph is not None:
                p_if += C_LIGHT * if_clock_correction_s(eph, bd.band.signal)
            obs.append(Observation(prn=p, tx_tow=rx_tow - p_if / C_LIGHT, doppler_hz=float(r["doppler_hz"]),
                                   cn0_dbhz=float(r["cn0_dbhz"]), system=bd.system))
        if len(obs) < 4 + len({o.system for o in obs}) - 1:
            return None
        fix = self.solver.fix(week, rx_tow, obs, ephs, None, x0=self.x0)
        if fix is not None:
            self.x0 = fix.ecef
        return fix
