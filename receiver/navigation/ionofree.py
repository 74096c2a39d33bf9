"""Dual-frequency observables and the L1/L5 ionosphere-free fix (GPS), from the L1 navigation engine's
epochs and the second band's channels (receiver.tracking.aided.AidedBand).

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
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..gnss.signals import C_LIGHT, L1_HZ
from ..gnss.geodesy import ecef2lla
from ..runfile.record import FIX_DTYPE, IONO_NONE, OBS_DTYPE
from .pvt import NavSolver, Observation

_SOLVER_KEYS = ("elevation_mask_deg", "weighting", "troposphere", "residual_threshold_m", "max_pdop")


def gamma(f2_hz: float) -> float:
    """(f_L1 / f2)^2: the ionospheric group delay on f2 over the one on L1."""
    return (L1_HZ / f2_hz) ** 2


def ionofree(p1, p2, g: float):
    """The ionosphere-free pseudorange of P1 (L1) and P2 (the band with delay ratio ``g``)."""
    return (g * np.asarray(p1) - np.asarray(p2)) / (g - 1.0)


def band_pseudorange(pr1: float, rx_tow: float, code_phase_chips: float, chip_rate: float) -> float:
    """The second band's pseudorange at receiver time ``rx_tow`` from its code phase (chips into the
    1-ms code period) and the L1 pseudorange ``pr1`` of the same instant (whole milliseconds)."""
    tx1 = rx_tow - pr1 / C_LIGHT
    frac1 = tx1 % 1e-3
    d = (code_phase_chips / chip_rate - frac1 + 0.5e-3) % 1e-3 - 0.5e-3
    return (rx_tow - (tx1 + d)) * C_LIGHT


class DualFrequency:
    """Per navigation epoch: the band's observables and the ionosphere-free fix.

    nav_cfg: the receiver's ``navigation`` section; band: an AidedBand; store: the navigation engine
    (ephemerides)."""

    def __init__(self, nav_cfg, band, store):
        cfg = SimpleNamespace(**{k: getattr(nav_cfg, k) for k in _SOLVER_KEYS}, ionosphere="none")
        self.solver = NavSolver(cfg)
        self.band, self.store = band, store
        self.g = gamma(band.signal.carrier_hz)
        self.lam = C_LIGHT / band.signal.carrier_hz
        self.x0 = None
        self.window = max(int(round(nav_cfg.smoothing_s * nav_cfg.rate_hz)), 1) if nav_cfg.smoothing_s > 0 else 1
        self.hatch = {}                      # prn -> (time_s, smoothed P5, carrier range, epochs)

    def epochs(self, fixes: np.ndarray, obs) -> tuple:
        """(band OBS_DTYPE rows, ionosphere-free FIX_DTYPE rows) of the engine's epochs ``fixes`` with their
        L1 observables ``obs``."""
        obs = np.asarray(obs, OBS_DTYPE) if len(obs) else np.zeros(0, OBS_DTYPE)
        out_obs, out_fix = [], []
        for f in fixes:
            rows = obs[obs["time_s"] == f["time_s"]]
            rx_tow = f["gps_tow"] + f["clock_bias_m"] / C_LIGHT
            b_obs, pr = self._band_obs(rows, rx_tow)
            fix = self._fix(int(f["gps_week"]), rx_tow, rows, pr)
            used = set(fix.prns) if fix is not None else set()
            for r in b_obs:
                r["used_in_fix"] = 1 if r["prn"] in used else 0
            out_obs.extend(b_obs)
            if fix is not None:
                lat, lon, h = ecef2lla(fix.ecef)
                out_fix.append((fix.gps_week, fix.gps_tow, f["time_s"], fix.ecef, fix.velocity_ecef,
                                fix.clock_bias_m, fix.clock_drift_mps, fix.n_sats, fix.pdop, fix.hdop, fix.vdop,
                                fix.gdop, 0, float(lat), float(lon), float(h), IONO_NONE))
        return np.array(out_obs, OBS_DTYPE), np.array(out_fix, FIX_DTYPE)

    def _band_obs(self, rows, rx_tow):
        out, pr = [], {}
        for r in rows:
            m = self.band.code_phase_at(int(r["prn"]), float(r["time_s"]))
            if m is None:
                continue
            p5 = band_pseudorange(float(r["pseudorange_m"]), rx_tow, m[0], self.band.signal.chip_rate)
            p5 = self._smooth(int(r["prn"]), float(r["time_s"]), p5, -self.lam * m[2])
            pr[int(r["prn"])] = p5
            o = r.copy()
            o["pseudorange_m"], o["cn0_dbhz"], o["residual_m"] = p5, m[1], np.nan
            o["doppler_hz"] = r["doppler_hz"] * self.band.signal.carrier_hz / L1_HZ
            o["pseudorange_rate_mps"] = -o["doppler_hz"] * self.lam
            o["carrier_phase_cycles"] = np.nan
            out.append(o)
        return out, pr

    def _smooth(self, prn, t, p5, carrier_m):
        """Hatch filter of the L5 code with the L5 carrier over navigation.smoothing_s (restarted after a gap
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
        for r in rows:
            p = int(r["prn"])
            if p not in pr5:
                continue
            p_if = float(ionofree(r["pseudorange_m"], pr5[p], self.g))
            obs.append(Observation(prn=p, tx_tow=rx_tow - p_if / C_LIGHT, doppler_hz=float(r["doppler_hz"]),
                                   cn0_dbhz=float(r["cn0_dbhz"])))
        if len(obs) < 4:
            return None
        fix = self.solver.fix(week, rx_tow, obs, self.store.ephemerides(rx_tow), None, x0=self.x0)
        if fix is not None:
            self.x0 = fix.ecef
        return fix
