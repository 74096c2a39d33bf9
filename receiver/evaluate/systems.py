"""Per-system fixes of a multi-system run, solved again from its observables (issue 33: a combined fix must be
no worse than the better system alone).

:func:`resolve_fixes` gives the fixes of a run's epochs from the satellites of some systems only, with the
run's own pseudoranges, ephemerides, Klobuchar set and navigation settings (receiver.navigation.pvt.NavSolver,
unaided WLS, each fix started from the previous one): GPS alone, BeiDou alone and both on identical
measurements, so that the comparison is the solver's and not the tracking's.  :func:`score_enu` scores fixes
against a known position.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..gnss.ephemeris import select
from ..gnss.geodesy import ecef2lla, enu_matrix
from ..gnss.satid import split_key
from ..gnss.signals import C_LIGHT, LAMBDA_L1
from ..gnss.signals_bds import B1I_HZ
from ..navigation.config import default
from ..navigation.pvt import NavSolver, Observation

#: navigation settings the re-solved fixes take from the run's configuration
NAV_KEYS = ("elevation_mask_deg", "weighting", "troposphere", "ionosphere", "residual_threshold_m", "max_pdop",
            "weighting_per_system", "vce_window_s")
FIX_ROWS = np.dtype([("gps_tow", "f8"), ("ecef", "f8", (3,)), ("n_sats", "i4"), ("pdop", "f8")])


def nav_settings(run, **changes):
    """The run's navigation settings (NAV_KEYS) as an object for NavSolver, with ``changes`` applied."""
    nav = {k: run.cfg(f"navigation.{k}", default(k)) for k in NAV_KEYS}
    nav.update(changes)
    return SimpleNamespace(**nav)


def resolve_fixes(run, systems: str, iono="run", nav=None, every: int = 1) -> np.ndarray:
    """FIX_ROWS of the run's fix epochs solved from the satellites of ``systems`` (RINEX letters, e.g. "G",
    "C", "GC").  run: receiver.runfile.reader.RunData; iono: "run" (the set the run used) or an IonoUtc / None;
    nav: NavSolver settings (default :func:`nav_settings`); every: use every n-th epoch."""
    obs = run.obs
    if not len(obs):
        return np.zeros(0, FIX_ROWS)
    iono = run.iono() if isinstance(iono, str) and iono == "run" else iono
    rx = run.rx_tow()
    ephs = {}
    for e in run.used_ephemerides():
        ephs.setdefault(run.eph_key(e), []).append(e)
    solver = NavSolver(nav if nav is not None else nav_settings(run))
    rows, x0 = [], None
    for k, ep in enumerate(np.unique(obs["epoch"])):
        sel = np.flatnonzero(obs["epoch"] == ep)
        week = obs["gps_week"][sel[0]]
        if k % every:
            continue
        t_rx = float(rx[sel[0]])
        observations = []
        for i in sel:
            letter, _ = split_key(int(obs["prn"][i]))
            if letter not in systems or not np.isfinite(obs["pseudorange_m"][i]):
                continue
            observations.append(Observation(
                prn=int(obs["prn"][i]), tx_tow=float(rx[i] - obs["pseudorange_m"][i] / C_LIGHT),
                doppler_hz=float(obs["doppler_hz"][i]), cn0_dbhz=float(obs["cn0_dbhz"][i]),
                wavelength_m=C_LIGHT / B1I_HZ if letter == "C" else LAMBDA_L1, system=letter))
        # (one record per satellite, the nearest toe: BeiDou records carry BDT weeks, so no week here)
        now = {p: select(lst, t_rx) for p, lst in ephs.items()}
        fix = solver.fix(int(week), t_rx, observations, now, iono, x0=x0)
        if fix is not None:
            x0 = fix.ecef
            rows.append((round(float(obs["gps_tow"][sel[0]]), 3), fix.ecef, fix.n_sats, fix.pdop))
    return np.array(rows, FIX_ROWS)


def score_enu(fixes, x_true, keep=None) -> dict:
    """n, 3D RMS (m), mean east/north/up error (m), mean satellites and PDOP of fixes (rows with 'gps_tow',
    'ecef', 'n_sats', 'pdop'; only those whose gps_tow, rounded to 1 ms, is in ``keep`` when given)."""
    fx = fixes
    if keep is not None:
        fx = fx[np.isin(np.round(fx["gps_tow"], 3), np.asarray(keep, float))]
    if not len(fx):
        return dict(n=0, rms=np.nan, enu=np.full(3, np.nan), sats=np.nan, pdop=np.nan)
    x_true = np.asarray(x_true, float)
    lat, lon, _ = ecef2lla(x_true)
    enu = (fx["ecef"] - x_true) @ enu_matrix(lat, lon).T
    return dict(n=len(fx), rms=float(np.sqrt(np.mean(np.sum(enu ** 2, axis=1)))), enu=np.mean(enu, axis=0),
                sats=float(np.mean(fx["n_sats"])), pdop=float(np.mean(fx["pdop"])))


def common_epochs(*fixes) -> np.ndarray:
    """The gps_tow values (rounded to 1 ms) present in every one of the fix arrays."""
    common = None
    for fx in fixes:
        t = set(np.round(fx["gps_tow"], 3).tolist())
        common = t if common is None else common & t
    return np.array(sorted(common or ()))
