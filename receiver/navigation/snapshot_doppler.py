"""Coarse-time (snapshot) navigation from the Dopplers: the a-priori position when none is given (a static
receiver, or a moving one with its velocity as three more unknowns) and the receiver velocity at the fix.

Measurement: -lambda x Doppler = u . (v_sat - v_rx) + clock drift - satellite clock drift (m/s), u the unit
vector to the satellite.  The position enters through u (a km moves u by ~5e-5 rad, the prediction by
~0.2 m/s): a position to a few km (static) or tens of km (moving) -- enough for the whole-millisecond
resolution (receiver/navigation/snapshot.py), which tolerates ~100 km.
Weights from the Doppler noise model :func:`doppler_sigma_mps`; the velocity solution rejects outliers.
"""
from __future__ import annotations

import numpy as np

from ..gnss.geodesy import ecef2lla, enu_matrix, lla2ecef
from .snapshot_model import LAMBDA, Ephemerides, SnapObs, sat_geometry

#: soft constraint on the vertical velocity of the moving Doppler solution (m/s, 1-sigma): aircraft and cars
VERTICAL_SIGMA_MPS = 20.0


def doppler_sigma_mps(cn0_dbhz, length_ms) -> np.ndarray:
    """Range-rate noise (m/s) of a Doppler from a snapshot of ``length_ms`` at ``cn0_dbhz``: the frequency
    estimate's Cramer-Rao bound sqrt(6 / ((2 pi)^2 C/N0 T^3)) (coherent over the whole length; the bit
    transitions cost a little), times lambda, with a floor of 0.02 m/s."""
    cn0 = 10 ** (np.asarray(cn0_dbhz, float) / 10.0)
    t = np.asarray(length_ms, float) * 1e-3
    return np.maximum(LAMBDA * np.sqrt(6.0 / ((2 * np.pi) ** 2 * cn0 * t ** 3)), 0.02)


def _starts():
    return [lla2ecef(la, lo, 0.0) for la in (-60, -30, 0, 30, 60) for lo in range(-180, 180, 72)] + \
        [lla2ecef(90, 0, 0.0), lla2ecef(-90, 0, 0.0)]


def doppler_solution(obs: list[SnapObs], ephs: Ephemerides, week: int, tow0: float, starts=None,
                     solve_time: bool = True, max_iter: int = 20, moving: bool = False):
    """Position from Dopplers alone: unknowns position, clock drift (m/s), (``solve_time``) the error of the
    coarse time tow0 and (``moving``) the receiver velocity (its vertical part softly constrained to 0 +/-
    VERTICAL_SIGMA_MPS).  Several start points (default: 27 on the Earth's surface); the solution with the
    smallest residual RMS: (x, drift_mps, dt_s, rms_mps, v_ecef) or None."""
    prns = [o.prn for o in obs]
    meas = -LAMBDA * np.array([o.doppler_hz for o in obs])          # range rate + clock drift (m/s)
    sig = doppler_sigma_mps([o.cn0_dbhz for o in obs], [o.length_ms for o in obs])
    w = np.median(sig) / sig                                        # relative weights
    n_unk = (5 if solve_time else 4) + (3 if moving else 0)
    if len(obs) < n_unk + (0 if moving else 1):
        return None
    best = None
    for x0 in (_starts() if starts is None else starts):
        x, d, dt, v = np.array(x0, float), 0.0, 0.0, np.zeros(3)
        ok = False
        for _ in range(max_iter):
            pred, h = doppler_model(ephs, prns, week, tow0 + dt, x, d, solve_time, v if moving else None)
            hw, zw = h * w[:, None], (meas - pred) * w
            if moving:
                up = enu_matrix(*ecef2lla(x)[:2])[2]
                row = np.zeros(h.shape[1])
                row[-3:] = up * np.median(sig) / VERTICAL_SIGMA_MPS       # the velocity: the last 3 columns
                hw, zw = np.vstack([hw, row]), np.append(zw, -float(up @ v) * np.median(sig) / VERTICAL_SIGMA_MPS)
            try:
                step = np.linalg.lstsq(hw, zw, rcond=None)[0]
            except np.linalg.LinAlgError:
                break
            step[:3] = np.clip(step[:3], -2e6, 2e6)
            x, d = x + step[:3], d + step[3]
            if solve_time:
                dt += float(np.clip(step[4], -120.0, 120.0))
            if moving:
                v = v + np.clip(step[-3:], -1000.0, 1000.0)
            r = np.linalg.norm(x)
            if r > 1e7 or r < 5e6 or abs(dt) > 600 or np.linalg.norm(v) > 2000.0:   # diverging or off the Earth
                break
            if np.linalg.norm(step[:3]) < (10.0 if moving else 1.0):
                ok = True
                break
        if not ok or abs(float(ecef2lla(x)[2])) > 50e3:
            continue
        pred, _ = doppler_model(ephs, prns, week, tow0 + dt, x, d, solve_time, v if moving else None)
        rms = float(np.sqrt(np.mean((meas - pred) ** 2)))
        if best is None or rms < best[3]:
            best = (x, d, dt, rms, v)
    return best


def doppler_model(ephs, prns, week, tow, x, drift, solve_time, v=None):
    """Predicted -lambda x Doppler (m/s) at position x (ECEF), clock drift, receiver velocity v (None: static)
    and the Jacobian: columns position, drift, (solve_time) time, (v given) velocity."""
    pos, vel, _, cdrift, _ = sat_geometry(ephs, prns, week, tow, x)
    vr = vel if v is None else vel - v
    los = pos - x
    rng = np.linalg.norm(los, axis=1)
    u = los / rng[:, None]
    rr = np.sum(u * vr, axis=1)
    pred = rr + drift - cdrift
    # d(u . v)/dx = -(v - (u . v) u) / range
    hx = -(vr - rr[:, None] * u) / rng[:, None]
    cols = [hx, np.ones((len(prns), 1))]
    if solve_time:
        pos2, vel2, _, cd2, _ = sat_geometry(ephs, prns, week, tow + 1.0, x)
        l2 = pos2 - x
        u2 = l2 / np.linalg.norm(l2, axis=1)[:, None]
        rr2 = np.sum(u2 * (vel2 if v is None else vel2 - v), axis=1) - cd2
        cols.append(((rr2 - (rr - cdrift)) / 1.0)[:, None])
    if v is not None:
        cols.append(-u)
    return pred, np.hstack(cols)


def velocity_solution(obs: list[SnapObs], ephs: Ephemerides, week: int, tow: float, x, k_sigma: float = 5.0):
    """Receiver velocity (ECEF m/s), clock drift (m/s) and the Doppler residuals (m/s, one per observation)
    at position x: weighted least squares (:func:`doppler_sigma_mps`); while more than 5 satellites remain,
    the one whose residual exceeds ``k_sigma`` times its sigma (the sigmas scaled up when the fit says the
    noise is larger) by the most is left out.  Returns (v, drift, residuals, indices left out)."""
    prns = [o.prn for o in obs]
    if len(prns) < 4:
        return np.full(3, np.nan), float("nan"), [], []
    pos, vel, _, cdrift, _ = sat_geometry(ephs, prns, week, tow, x)
    u = (pos - x) / np.linalg.norm(pos - x, axis=1)[:, None]
    meas = -LAMBDA * np.array([o.doppler_hz for o in obs])
    # meas = u . (v_sat - v_rx) + drift - sat drift
    z = meas - np.sum(u * vel, axis=1) + cdrift
    h = np.hstack([-u, np.ones((len(prns), 1))])
    sig = doppler_sigma_mps([o.cn0_dbhz for o in obs], [o.length_ms for o in obs])
    active = list(range(len(prns)))
    out = []
    while True:
        a = np.array(active)
        sol = np.linalg.lstsq(h[a] / sig[a, None], z[a] / sig[a], rcond=None)[0]
        res = z - h @ sol
        nr = res[a] / sig[a]
        dof = len(a) - 4
        scale = max(1.0, float(np.sqrt(np.sum(nr ** 2) / dof))) if dof > 0 else 1.0
        j = int(np.argmax(np.abs(nr)))
        if len(a) <= 5 or abs(nr[j]) <= k_sigma * min(scale, 3.0):
            break
        out.append(active.pop(j))
    return sol[:3], float(sol[3]), list(res), out


def static_doppler_rms(obs, ephs, week, tow, x) -> float:
    """RMS (m/s) of the Doppler residuals at position x for a static receiver (the clock drift fitted)."""
    prns = [o.prn for o in obs]
    pred, _ = doppler_model(ephs, prns, week, tow, np.asarray(x, float), 0.0, False)
    r = -LAMBDA * np.array([o.doppler_hz for o in obs]) - pred
    return float(np.std(r))


def moving_doppler_rms(obs, ephs, week, tow, x) -> float:
    """RMS (m/s) of the Doppler residuals at position x with the velocity and clock drift fitted (4 unknowns)."""
    _, _, res, out = velocity_solution(obs, ephs, week, tow, np.asarray(x, float), k_sigma=1e9)
    return float(np.sqrt(np.mean(np.square(res)))) if res else float("inf")
