"""Doppler positioning of a static receiver: least squares, EKF, CKF and square-root CKF drivers.

State x = [x, y, z, f_u] (ECEF metres, receiver frequency offset in Hz).  Every driver walks the epochs
of a :class:`~receiver.leo.doppler.DopplerData` window in order and returns the estimate after each
epoch, so all methods can be compared epoch by epoch:

* ``lsm``: Gauss-Newton least squares with the analytic Jacobian on all observations received so far
  (growing window, or a sliding one; warm-started from the previous estimate; the previous estimate is
  kept while the batch is too small or formally worse than the initial value, see :func:`solve_lsm`).
* ``ekf``: F = I, Q = diag(Sp Ts, Sp Ts, Sp Ts, Sf Ts) with Sp = sigma_D^2 / 3, R = sigma^2 I.
* ``ckf``: the same model with the cubature Kalman filter (Cholesky factors).
* ``sqrt_ckf``: square-root CKF, every factor by QR (the paper's "ICKF").

The initial state comes from the GeoSOT grid search (:func:`initial_state`) or is given.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..gnss.geodesy import lla2ecef
from . import geosot
from .doppler import DopplerData, doppler_jacobian, doppler_model
from ..estimation.filters import (CubatureKalmanFilter, ExtendedKalmanFilter, FilterDivergence,
                      SquareRootCubatureKalmanFilter)

METHODS = ("lsm", "ekf", "ckf", "sqrt_ckf")

DEFAULT_SETTINGS = dict(sigma_hz=0.5, sigma_d2_m2=10.0, sf_hz2_per_s=0.01, init_sigma_m=500.0,
                        init_sigma_fu_hz=50.0, lsm_max_iter=10, lsm_tol_m=1e-3,
                        lsm_window_epochs=None, lsm_min_observations=4,
                        lsm_hold_until_better=True)


@dataclass
class SolveResult:
    """Output of one solver: the state [x, y, z (ECEF m), f_u (Hz)] after every epoch (T, 4), the filter
    covariances (T, 4, 4; None for lsm), the run time (s) and, on failure, the reason."""
    method: str
    estimates: np.ndarray            # (T, 4) state after each epoch (NaN after a failure)
    covariances: np.ndarray | None   # (T, 4, 4) filter covariance (None for lsm)
    runtime_s: float
    failed: bool = False
    message: str = ""

    @property
    def final(self) -> np.ndarray:
        """The state [x, y, z, f_u] after the last epoch (ECEF m, Hz)."""
        return self.estimates[-1]


def _settings(s):
    out = dict(DEFAULT_SETTINGS)
    out.update({k: v for k, v in (s or {}).items() if v is not None})
    return out


# --------------------------------------------------------------------------------------------------
# Initial value
# --------------------------------------------------------------------------------------------------
def initial_state(data: DopplerData, start_level=9, end_level=18, keep=32, height_m=0.0,
                  clock="fit", elevation_mask_deg=10.0, mask_margin_deg=5.0, region=None):
    """GeoSOT grid-search initial state [x, y, z, f_u] and the grid result."""
    _, sp, sv, z = data.stacked()
    res = geosot.grid_search(sp, sv, z, data.carrier_hz, start_level, end_level, keep, height_m,
                             clock, elevation_mask_deg, mask_margin_deg, region=region)
    return np.r_[res.ecef, res.freq_offset_hz], res


def earth_center_state() -> np.ndarray:
    """The Earth's centre with no frequency offset, [0, 0, 0, 0]: the uninformed initial value."""
    return np.zeros(4)


def given_state(lat_deg, lon_deg, h_m, f_u=0.0) -> np.ndarray:
    """The state [x, y, z (ECEF m), f_u (Hz)] at a given latitude/longitude (deg) and ellipsoidal height (m)."""
    return np.r_[lla2ecef(lat_deg, lon_deg, h_m), f_u]


# --------------------------------------------------------------------------------------------------
# Drivers
# --------------------------------------------------------------------------------------------------
def _check(data: DopplerData):
    if not np.any(data.observed):
        raise UserError("the measurement window holds no Doppler observations")


def solve_lsm(data: DopplerData, x0, settings=None) -> SolveResult:
    """Gauss-Newton least squares after every epoch on the observations received so far.

    ``lsm_window_epochs`` limits the batch to the most recent epochs (None: growing window).
    The previous estimate (initially x0) is reported while the batch holds fewer than
    ``lsm_min_observations`` observations or, with ``lsm_hold_until_better``, while the formal 3-D
    position standard deviation of the solution, sigma sqrt(trace (J^T J)^-1), exceeds the 3-D
    standard deviation of the initial value, sqrt(3) * init_sigma_m (the prior the filters start
    with): a barely determined batch is not allowed to replace a better initial value.
    """
    s = _settings(settings)
    _check(data)
    f0 = data.carrier_hz
    k_idx, sp, sv, z = data.stacked()
    ends = np.searchsorted(k_idx, np.arange(data.n_epochs), side="right")
    win = s.get("lsm_window_epochs")
    starts = (np.searchsorted(k_idx, np.arange(data.n_epochs) - win + 1, side="left")
              if win else np.zeros(data.n_epochs, int))
    min_obs = max(int(s.get("lsm_min_observations") or 0), 1)
    accept = np.sqrt(3.0) * s["init_sigma_m"] if s.get("lsm_hold_until_better") else None
    x = np.array(x0, float)
    est = np.full((data.n_epochs, 4), np.nan)
    t0 = time.perf_counter()
    failed, msg = False, ""
    for k in range(data.n_epochs):
        a, b = starts[k], ends[k]
        if b - a < min_obs:
            est[k] = x
            continue
        P, V, Z = sp[a:b], sv[a:b], z[a:b]
        xk = x.copy()
        for _ in range(s["lsm_max_iter"]):
            r = Z - doppler_model(xk, P, V, f0)[0]
            J = doppler_jacobian(xk, P, V, f0)
            dx = np.linalg.lstsq(J, r, rcond=None)[0]
            xk = xk + dx
            if not np.all(np.isfinite(xk)) or np.linalg.norm(dx[:3]) < s["lsm_tol_m"]:
                break
        if not np.all(np.isfinite(xk)) or np.linalg.norm(xk[:3]) > 1e9:
            failed, msg = True, f"least squares diverged at epoch {k}"
            break
        if accept is not None:
            # formal 3-D position standard deviation of the solution, sigma^2 (J^T J)^-1
            J = doppler_jacobian(xk, P, V, f0)
            cov = np.linalg.pinv(J.T @ J) * s["sigma_hz"] ** 2
            if not np.sqrt(max(np.trace(cov[:3, :3]), 0.0)) <= accept:
                est[k] = x                     # not yet better than the previous estimate
                continue
        x = xk
        est[k] = x
    return SolveResult("lsm", est, None, time.perf_counter() - t0, failed, msg)


def _process_noise(s, dt):
    sp = s["sigma_d2_m2"] / 3.0
    return np.diag([sp * dt, sp * dt, sp * dt, s["sf_hz2_per_s"] * dt])


def _p0(s):
    return np.diag([s["init_sigma_m"] ** 2] * 3 + [s["init_sigma_fu_hz"] ** 2])


def solve_filter(data: DopplerData, x0, method: str, settings=None) -> SolveResult:
    """Run ekf / ckf / sqrt_ckf over the epochs (identity dynamics, process noise Q(Ts))."""
    s = _settings(settings)
    _check(data)
    f0 = data.carrier_hz
    r2 = s["sigma_hz"] ** 2
    if method == "ekf":
        flt = ExtendedKalmanFilter(x0, _p0(s))
    elif method == "ckf":
        flt = CubatureKalmanFilter(x0, _p0(s), vectorized=True)
    elif method == "sqrt_ckf":
        flt = SquareRootCubatureKalmanFilter(x0, _p0(s), vectorized=True)
    else:
        raise UserError(f"unknown filter '{method}'")
    T = data.n_epochs
    est = np.full((T, 4), np.nan)
    cov = np.full((T, 4, 4), np.nan)
    identity = (lambda X: X)
    failed, msg = False, ""
    t0 = time.perf_counter()
    try:
        for k in range(T):
            if k > 0:
                Q = _process_noise(s, data.t_s[k] - data.t_s[k - 1])
                if method == "ekf":
                    flt.predict(None, None, Q)
                else:
                    flt.predict(identity, Q)
            P, V, Z = data.epoch(k)
            if len(Z):
                R = np.full(len(Z), r2)
                if method == "ekf":
                    flt.update(Z, lambda x, P=P, V=V: doppler_model(x, P, V, f0)[0],
                               lambda x, P=P, V=V: doppler_jacobian(x, P, V, f0), R)
                else:
                    flt.update(Z, lambda X, P=P, V=V: doppler_model(X, P, V, f0), R)
            if not np.all(np.isfinite(flt.x)):
                raise FilterDivergence("state is not finite")
            est[k] = flt.x
            cov[k] = flt.P
    except FilterDivergence as exc:
        failed, msg = True, f"{method} stopped at epoch {k}: {exc}"
    return SolveResult(method, est, cov, time.perf_counter() - t0, failed, msg)


def solve(data: DopplerData, method: str, x0, settings=None) -> SolveResult:
    """Run one of :data:`METHODS` (``lsm``, ``ekf``, ``ckf``, ``sqrt_ckf``) from the initial state x0; an
    unknown name is a UserError."""
    if method == "lsm":
        return solve_lsm(data, x0, settings)
    if method in ("ekf", "ckf", "sqrt_ckf"):
        return solve_filter(data, x0, method, settings)
    raise UserError(f"unknown solver '{method}' (choose from {', '.join(METHODS)})")
