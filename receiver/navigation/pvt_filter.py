"""Kalman-filter navigation solution (``navigation.filter: ekf | ckf``) on top of the single-epoch WLS fix.

State (metres, seconds):  x = [r (ECEF, 3), v (3), b, d (, delta)]
    r, v      receiver position and velocity
    b         receiver clock bias as seen by the code (c times the clock error)
    d         receiver clock drift as seen by the carrier (m/s)
    delta     optional code-minus-carrier clock drift (m/s), ``navigation.filter_code_carrier_drift``:
              db/dt = d + delta.  Zero for a front end whose oscillator drives both the sample clock and
              the local oscillator; a recording whose oscillator error reached the carrier only (the
              third-party reference recording: ~150 m/s of carrier drift, a constant code clock) has
              delta = -d, which an 8-state filter cannot represent.

Process model over dt (receiver time between navigation epochs): constant velocity driven by white
acceleration of PSD q_a per axis (``filter_accel_psd``, m^2/s^3) and a two-state clock driven by the
oscillator noise of ``filter_clock`` (h0, h_-2 of the fractional frequency):
    S_b = h0 / 2 c^2 (m^2/s),  S_d = 2 pi^2 h_-2 c^2 (m^2/s^3)
    Q_rr = q_a dt^3/3,  Q_rv = q_a dt^2/2,  Q_vv = q_a dt
    Q_bb = S_b dt + S_d dt^3/3,  Q_bd = S_d dt^2/2,  Q_dd = S_d dt     (+ a small delta random walk)

Measurements: the WLS fix's corrected pseudoranges and pseudorange rates of the satellites that fix used
(so the WLS elevation mask and residual check are also the filter's outlier gate), with the satellite
states of the fix (``Fix.sat_pos_ecef``/``sat_vel_ecef``, transmit time, rotated into the reception frame):
    rho_i  = |p_i - r| + b                                   sigma = filter_code_sigma_m / sin(el_i)
    rate_i = u_i . (v_i - v) + d,  u_i = (p_i - r)/|p_i - r|  sigma = filter_rate_sigma_mps / sin(el_i)
(the 1/sin(el) scaling is the WLS's sin^2(el) weighting; ``navigation.weighting: none`` drops it).
The rates come from the carrier, which the ionosphere advances while it delays the code: they are
corrected by the change of the fix's modelled iono - tropo since the previous epoch (per satellite, over
the step; about 1 cm/s for the troposphere of a satellite at 7 deg), else the carrier-propagated position
drifts against the code (mostly hidden by the elevation weighting; tests: equal weights).

Unsmoothed code (``filter_smoothed_code: false``, the default): the receiver's WLS uses carrier-smoothed
pseudoranges (``navigation.smoothing_s``), whose errors are correlated over the smoothing window and large
while the smoothers start.  A Kalman filter that also integrates the carrier-derived rates already smooths
the code with the carrier, and it takes the code errors as white: fed with smoothed code it averages the
correlated early errors of every epoch since its start (on the reference recording and a simulated
figure eight it came out 10-30 % worse than the smoothed WLS).  The engine therefore hands
:meth:`PvtFilter.step` the per-satellite difference unsmoothed - smoothed pseudorange, which the filter adds
back (the satellite set, corrections and geometry stay those of the WLS fix).

Interval-averaged rates (``rate_interval_s``, in the receiver 1 / navigation.rate_hz): the engine's
pseudorange rates are carrier-phase differences over the last navigation interval T, i.e. the mean range
rate over [t - T, t], which lags the instantaneous one by a T / 2 under an acceleration a (0.2 m/s at
4 m/s^2 and 10 Hz).  A constant-velocity filter that takes them as instantaneous integrates that lag into
a metre-level along-track position error.  When consecutive steps are T apart the filter therefore
clones the position and clock bias of the previous epoch (stochastic cloning: the augmented state
[x, r(t-T), b(t-T)] with the correlations of the prediction) and models the rate as the delta range
    rate_i = (|p_i - r| - |p_i' - r(t-T)|) / T + (b - b(t-T)) / T - delta
(p_i' the satellite position of the previous fix), exact for any receiver motion.  Otherwise (first
epoch, gaps, ``rate_interval_s=None``) the instantaneous model above is used.

Initialisation: from the first WLS fix handed to :meth:`PvtFilter.step` (in the receiver: the first fix
after the receiver clock has been re-based), as a weak prior (100 m, 100 m/s, 1000 m/s on delta) around
the WLS state followed by the measurement update of that epoch.  Consistency: when the WLS position or
clock bias leaves the predicted one by more than ``filter_reset_m`` plus five predicted standard
deviations the epoch is not used (the prediction is returned); after three such epochs in a row the filter
restarts from the WLS fix (clock jumps, a lost track).

``kind``: ``ekf`` (:class:`ExtendedKalmanFilter`, analytic Jacobians) or ``ckf``, the square-root cubature
filter :class:`SquareRootCubatureKalmanFilter`.  The square-root form is used because this problem is
badly scaled for a Cholesky-per-step filter: the prior holds 100 m / 1000 m/s while the carrier-derived
rates pin velocity and drift to centimetres per second (variances shrink by 1e-7 and more in the first
updates, and the position/clock clone is perfectly correlated with the state it copies, a singular
covariance that :class:`CubatureKalmanFilter` cannot even factor); the QR-propagated factor handles both.
Its cost (QR decompositions of 13 x ~40 arrays per epoch) is irrelevant at navigation rates.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..gnss.clock import OSCILLATORS, h0_h2
from ..gnss.signals import C_LIGHT
from ..gnss.time import HALF_WEEK, WEEK_S, normalize_week_tow, week_seconds_since
from ..estimation.filters import ExtendedKalmanFilter, SquareRootCubatureKalmanFilter, tria
from .config import FILTERS, default
from .pvt import Fix

#: (h0, h_-2) of the fractional-frequency PSD of the oscillator classes (receiver.gnss.clock)
CLOCK_CLASSES = {k: h0_h2(k) for k in OSCILLATORS}

#: PSD of the code-minus-carrier drift random walk ((m/s)^2/s)
Q_CODE_CARRIER_DRIFT = 1e-4
#: prior standard deviations of the initialisation (around the WLS state, before its update)
INIT_SIGMA = {"pos": 100.0, "vel": 100.0, "b": 100.0, "d": 100.0, "delta": 1000.0}
#: WLS fixes inconsistent with the prediction in a row before the filter restarts from the WLS
RESET_AFTER = 3
KINDS = tuple(k for k in FILTERS if k != "wls")
IB, ID = 6, 7


class PvtFilter:
    """EKF / CKF position-velocity-time filter fed with WLS fixes (see the module docstring).

    ``step(t, fix)`` predicts to receiver time t (s, any monotonic origin), updates with the fix's
    measurements and returns a copy of ``fix`` whose position, velocity, clock bias/drift and GPS time
    are the filter's (satellite lists, DOPs and residuals stay those of the WLS).
    """

    def __init__(self, kind: str = KINDS[0], accel_psd: float = default("filter_accel_psd"),
                 code_sigma_m: float = default("filter_code_sigma_m"),
                 rate_sigma_mps: float = default("filter_rate_sigma_mps"), clock: str = default("filter_clock"),
                 code_carrier_drift: bool = default("filter_code_carrier_drift"),
                 reset_m: float = default("filter_reset_m"), weighting: str = default("weighting"),
                 rate_interval_s: float | None = None, smoothed_code: bool = default("filter_smoothed_code")):
        if kind not in KINDS:
            raise ValueError(f"unknown navigation filter {kind!r} (ekf or ckf)")
        if clock not in CLOCK_CLASSES:
            raise ValueError(f"unknown clock class {clock!r}")
        self.kind = kind
        self.accel_psd = float(accel_psd)
        self.code_sigma_m = float(code_sigma_m)
        self.rate_sigma_mps = float(rate_sigma_mps)
        self.clock = clock
        h0, h2 = CLOCK_CLASSES[clock]
        self.s_b = 0.5 * h0 * C_LIGHT ** 2
        self.s_d = 2.0 * math.pi ** 2 * h2 * C_LIGHT ** 2
        self.has_delta = bool(code_carrier_drift)
        self.n = 9 if self.has_delta else 8
        self.reset_m = float(reset_m)
        self.elevation_weighting = weighting != "none"
        self.rate_interval_s = float(rate_interval_s) if rate_interval_s else None
        self.smoothed_code = bool(smoothed_code)
        self.kf = None                  # the filter object (None until the first fix)
        self.t = None                   # receiver time of the state
        self.prev_sats = {}             # prn -> satellite position of the previous epoch
        self.prev_atmo = {}             # prn -> iono - tropo (m) of the previous epoch
        self.n_inconsistent = 0
        self.n_resets = 0               # restarts after the first initialisation
        self.n_updates = 0
        self.n_cloned = 0               # updates with the delta-range rate model
        self.last_used = False          # whether the last step's measurements were used

    @classmethod
    def from_config(cls, nav_cfg) -> "PvtFilter":
        """The filter configured by the navigation section (``navigation.filter*``, ``weighting``; the delta-range
        rate model at the interval 1 / ``rate_hz`` when the section has one)."""
        g = lambda name: getattr(nav_cfg, name, default(name))  # noqa: E731
        rate = getattr(nav_cfg, "rate_hz", None)        # absent: no delta-range rate model
        return cls(kind=g("filter"), accel_psd=g("filter_accel_psd"),
                   code_sigma_m=g("filter_code_sigma_m"), rate_sigma_mps=g("filter_rate_sigma_mps"),
                   clock=g("filter_clock"), code_carrier_drift=g("filter_code_carrier_drift"),
                   reset_m=g("filter_reset_m"), weighting=g("weighting"),
                   rate_interval_s=1.0 / rate if rate else None,
                   smoothed_code=g("filter_smoothed_code"))

    # ------------------------------------------------------------------------------------- models
    def transition(self, dt: float) -> np.ndarray:
        """State transition F over dt seconds (position from velocity, clock bias from drift and, with the
        code-minus-carrier drift state, from it)."""
        F = np.eye(self.n)
        F[0:3, 3:6] = dt * np.eye(3)
        F[IB, ID] = dt
        if self.has_delta:
            F[IB, 8] = dt
        return F

    def process_noise(self, dt: float) -> np.ndarray:
        """Process noise Q over dt seconds: white acceleration (accel_psd) on position/velocity, the two-state
        clock (S_b, S_d) on bias/drift (m, m/s), Q_CODE_CARRIER_DRIFT on the code-minus-carrier drift state."""
        n, qa, sb, sd = self.n, self.accel_psd, self.s_b, self.s_d
        Q = np.zeros((n, n))
        for a in range(3):
            Q[a, a] = qa * dt ** 3 / 3.0
            Q[a, 3 + a] = Q[3 + a, a] = qa * dt ** 2 / 2.0
            Q[3 + a, 3 + a] = qa * dt
        Q[IB, IB] = sb * dt + sd * dt ** 3 / 3.0
        Q[IB, ID] = Q[ID, IB] = sd * dt ** 2 / 2.0
        Q[ID, ID] = sd * dt
        if self.has_delta:
            qd = Q_CODE_CARRIER_DRIFT
            Q[IB, IB] += qd * dt ** 3 / 3.0
            Q[IB, 8] = Q[8, IB] = qd * dt ** 2 / 2.0
            Q[8, 8] = qd * dt
        return Q

    def _atmosphere(self, fix: Fix) -> np.ndarray:
        """iono - tropo (m) per satellite of the fix (the code-minus-carrier of the atmosphere models)."""
        k = len(fix.prns)
        iono = np.asarray(fix.iono_m, float) if len(fix.iono_m) == k else np.zeros(k)
        tropo = np.asarray(fix.tropo_m, float) if len(fix.tropo_m) == k else np.zeros(k)
        return iono - tropo

    def _measurements(self, fix: Fix, clone: bool, code_offsets=None, dt=None):
        """Measurement vector, noise sigmas and the geometry the models need."""
        p = np.asarray(fix.sat_pos_ecef, float).reshape(-1, 3)
        v = np.asarray(fix.sat_vel_ecef, float).reshape(-1, 3)
        rho = np.asarray(fix.pseudoranges_m, float)
        if code_offsets and not self.smoothed_code:
            rho = rho + np.array([code_offsets.get(prn, 0.0) for prn in fix.prns], float)
        rate = np.asarray(fix.pseudorange_rates_mps, float)
        if dt is not None and dt > 0 and self.prev_atmo:
            # the carrier sees the ionosphere advance and the troposphere delay: range rate = measured
            # rate + d(iono - tropo)/dt (modelled values of this and the previous fix)
            a = self._atmosphere(fix)
            rate = rate + np.array([(a[i] - self.prev_atmo[prn]) / dt if prn in self.prev_atmo else 0.0
                                    for i, prn in enumerate(fix.prns)])
        if len(p) != len(rho):
            raise ValueError("the fix carries no satellite states (Fix.sat_pos_ecef); "
                             "it was not made by NavSolver.fix")
        ok = np.isfinite(rate) & np.all(np.isfinite(v), axis=1)
        el = np.radians(np.asarray(fix.elevations_deg, float))
        w = np.sin(np.maximum(el, np.radians(1.0))) if self.elevation_weighting else np.ones(len(rho))
        sig = np.concatenate([self.code_sigma_m / w, self.rate_sigma_mps / w[ok]])
        geo = {"p": p, "v": v, "ok": ok, "clone": clone}
        if clone:
            T = self.rate_interval_s
            geo["T"] = T
            geo["pc"] = np.array([self.prev_sats.get(prn, p[i] - v[i] * T)
                                  for i, prn in enumerate(fix.prns)]).reshape(-1, 3)[ok]
        return np.concatenate([rho, rate[ok]]), sig, geo

    def h_points(self, X: np.ndarray, geo: dict) -> np.ndarray:
        """Predicted measurements for state rows X (m, n or n + 4 with the clone) -> (m, p)."""
        X = np.atleast_2d(X)
        p, ok = geo["p"], geo["ok"]
        d = p[None, :, :] - X[:, None, 0:3]                 # (m, k, 3)
        rng = np.sqrt(np.einsum("mki,mki->mk", d, d))
        rho = rng + X[:, IB:IB + 1]
        if geo["clone"]:
            n, T = self.n, geo["T"]
            dc = geo["pc"][None, :, :] - X[:, None, n:n + 3]
            rc = np.sqrt(np.einsum("mki,mki->mk", dc, dc))
            rate = (rng[:, ok] - rc + X[:, IB:IB + 1] - X[:, n + 3:n + 4]) / T
            if self.has_delta:
                rate = rate - X[:, 8:9]
        else:
            u = d[:, ok] / rng[:, ok, None]
            rate = np.einsum("mki,mki->mk", u, geo["v"][None, ok] - X[:, None, 3:6]) + X[:, ID:ID + 1]
        return np.hstack([rho, rate])

    def jacobian(self, x: np.ndarray, geo: dict) -> np.ndarray:
        """Jacobian H of the measurements (pseudoranges, then the rates of the satellites in ``geo["ok"]``) at
        state x (the clone's delta-range rows with ``geo["clone"]``)."""
        p, v, ok = geo["p"], geo["v"], geo["ok"]
        d = p - x[0:3]
        rng = np.linalg.norm(d, axis=1)
        u = d / rng[:, None]
        k, kr = len(p), int(np.count_nonzero(ok))
        H = np.zeros((k + kr, x.size))
        H[:k, 0:3] = -u
        H[:k, IB] = 1.0
        uo = u[ok]
        if geo["clone"]:
            n, T = self.n, geo["T"]
            dc = geo["pc"] - x[n:n + 3]
            uc = dc / np.linalg.norm(dc, axis=1)[:, None]
            H[k:, 0:3] = -uo / T
            H[k:, n:n + 3] = uc / T
            H[k:, IB] = 1.0 / T
            H[k:, n + 3] = -1.0 / T
            if self.has_delta:
                H[k:, 8] = -1.0
        else:
            dv, ro = v[ok] - x[3:6], rng[ok]
            # d(u . dv)/dr = -(I - u u^T) dv / |p - r|
            H[k:, 0:3] = -(dv - uo * np.sum(uo * dv, axis=1)[:, None]) / ro[:, None]
            H[k:, 3:6] = -uo
            H[k:, ID] = 1.0
        return H

    # ------------------------------------------------------------------------------------- filter
    @property
    def x(self):
        """The filter's state vector (ECEF position m, velocity m/s, clock bias m, drift m/s, ...), or None
        before the first fix."""
        return None if self.kf is None else self.kf.x

    @property
    def P(self):
        """The filter's state covariance, or None before the first fix."""
        return None if self.kf is None else self.kf.P

    def _make(self, x, P=None, S=None):
        """A filter object of the selected kind for state x with covariance P or (CKF) factor S, whose
        rows may be linearly dependent (the clone)."""
        if self.kind == "ekf":
            return ExtendedKalmanFilter(x, S @ S.T if P is None else P)
        if S is None:
            w, V = np.linalg.eigh(0.5 * (P + P.T))
            S = V * np.sqrt(np.clip(w, 0.0, None))[None, :]
        return SquareRootCubatureKalmanFilter(x, S0=S, vectorized=True)

    def _initialise(self, t: float, fix: Fix):
        x = np.zeros(self.n)
        x[0:3] = fix.ecef
        vel = np.asarray(fix.velocity_ecef, float)
        x[3:6] = vel if np.all(np.isfinite(vel)) else 0.0
        x[IB] = fix.clock_bias_m
        x[ID] = fix.clock_drift_mps if np.isfinite(fix.clock_drift_mps) else 0.0
        s = INIT_SIGMA
        sig = [s["pos"]] * 3 + [s["vel"]] * 3 + [s["b"], s["d"]] + ([s["delta"]] if self.has_delta else [])
        self.kf = self._make(x, S=np.diag(sig))
        self.t = float(t)
        self.n_inconsistent = 0

    def _consistent(self, x, P, fix: Fix) -> bool:
        dr = float(np.linalg.norm(np.asarray(fix.ecef) - x[0:3]))
        db = abs(float(fix.clock_bias_m) - x[IB])
        sr = math.sqrt(max(np.trace(P[0:3, 0:3]), 0.0))
        sb = math.sqrt(max(P[IB, IB], 0.0))
        return dr <= self.reset_m + 5.0 * sr and db <= self.reset_m + 5.0 * sb

    def _update(self, kf, fix: Fix, clone: bool, code_offsets=None, dt=None):
        z, sig, geo = self._measurements(fix, clone, code_offsets, dt)
        if self.kind == "ekf":
            kf.update(z, lambda x: self.h_points(x, geo)[0], lambda x: self.jacobian(x, geo),
                      np.diag(sig ** 2))
        else:
            kf.update(z, lambda X: self.h_points(X, geo), SR=np.diag(sig))
        self.n_updates += 1
        self.n_cloned += int(clone)

    def step(self, t: float, fix: Fix, code_offsets: dict | None = None) -> Fix:
        """Predict to receiver time t, update with the WLS fix, return the filtered fix.

        code_offsets: prn -> unsmoothed minus smoothed pseudorange (m), added to the fix's pseudoranges
        unless ``smoothed_code`` (missing PRNs: 0; None: the fix's pseudoranges as they are)."""
        if self.kf is None:
            self._initialise(t, fix)
            self._update(self.kf, fix, False, code_offsets)
            self.last_used = True
            return self._finish(fix)
        dt = float(t) - self.t
        T = self.rate_interval_s
        clone = T is not None and abs(dt - T) <= 0.01 * T
        n = self.n
        if clone:
            # augmented state [x, r, b] at the previous epoch, predicted with the clone held fixed
            A = np.vstack([np.eye(n), np.eye(n)[[0, 1, 2, IB]]])
            kf = (self._make(A @ self.kf.x, P=A @ self.kf.P @ A.T) if self.kind == "ekf"
                  else self._make(A @ self.kf.x, S=A @ self.kf.S))
            Fa = np.eye(n + 4)
            Fa[:n, :n] = self.transition(dt)
            Qa = np.zeros((n + 4, n + 4))
            Qa[:n, :n] = self.process_noise(dt)
        else:
            kf = self.kf
            Fa, Qa = self.transition(dt), self.process_noise(dt)
        if dt > 0.0:
            if self.kind == "ekf":
                kf.predict(F=Fa, Q=Qa)
            else:
                kf.predict(f=lambda X: X @ Fa.T, Q=Qa)
            self.t = float(t)
        if self._consistent(kf.x, kf.P, fix):
            self.n_inconsistent = 0
            self._update(kf, fix, clone, code_offsets, dt)
            self.last_used = True
        else:
            self.n_inconsistent += 1
            self.last_used = False
        if clone:                                    # drop the clone
            self.kf = (self._make(kf.x[:n], P=kf.P[:n, :n]) if self.kind == "ekf"
                       else self._make(kf.x[:n], S=tria(kf.S[:n, :])))
        if self.n_inconsistent >= RESET_AFTER:
            self._initialise(t, fix)
            self._update(self.kf, fix, False, code_offsets)
            self.n_resets += 1
            self.last_used = True
        return self._finish(fix)

    def _finish(self, fix: Fix) -> Fix:
        self.prev_sats = {prn: np.asarray(p, float) for prn, p in zip(fix.prns, fix.sat_pos_ecef)}
        self.prev_atmo = dict(zip(fix.prns, self._atmosphere(fix)))
        return self.output(fix)

    def output(self, fix: Fix) -> Fix:
        """``fix`` with the filter's position, velocity, clock and GPS time (t = rx_tow - b / c)."""
        x = self.kf.x
        b = float(x[IB])
        week, tow = int(fix.gps_week), float(fix.gps_tow)
        if np.isfinite(fix.rx_tow):
            tow = fix.rx_tow - b / C_LIGHT
            # the WLS fix may sit on the other side of a week boundary than rx_tow - b / c
            if tow - fix.gps_tow > HALF_WEEK:
                tow -= WEEK_S
            elif tow - fix.gps_tow < -HALF_WEEK:
                tow += WEEK_S
            week, tow = normalize_week_tow(week, tow)
        return replace(fix, gps_week=week, gps_tow=float(tow), ecef=x[0:3].copy(),
                       velocity_ecef=x[3:6].copy(), clock_bias_m=b, clock_drift_mps=float(x[ID]))


def make_pvt_filter(nav_cfg):
    """The filter selected by ``navigation.filter`` (None for ``wls``)."""
    kind = getattr(nav_cfg, "filter", default("filter"))
    if kind in (None, "wls"):
        return None
    return PvtFilter.from_config(nav_cfg)


def replay_run(run_h5, ephemerides, iono_utc=None, nav_cfg=None, kinds=("ekf", "ckf")) -> dict:
    """Recompute the WLS fixes of a receiver run from its ``/observables`` and run the filters on them.

    Lets filters and their settings be compared on a recorded run without tracking the signal again.
    run_h5: a gnssrx run file (any navigation.filter); ephemerides: dict prn -> Ephemeris or list of
    Ephemeris (e.g. ``read_rinex_nav`` of the file the run was assisted with); nav_cfg: the
    ``navigation`` config section or any object with the NavSolver / filter attributes (the run's
    navigation.rate_hz sets the filters' rate interval).  The receiver time of each epoch follows from the
    run's rows (rx_tow = gps_tow + clock_bias_m / c, affine in the sample time).  The run file stores the
    pseudoranges the WLS used, i.e. carrier-smoothed ones unless the run had navigation.smoothing_s: 0, so
    the replayed filters see those (the receiver's filters see unsmoothed code, see the module docstring).
    Returns dict: ``time_s`` (epochs of the run), ``wls`` (list of Fix or None), and one list of Fix (or
    None where the WLS failed) per kind.
    """
    from ..runfile.reader import RunFile
    from .pvt import NavSolver, Observation
    with RunFile(run_h5) as rf:
        nav = rf.fix_columns(("gps_week", "gps_tow", "time_s", "clock_bias_m"))
        obs = rf.observable_columns(("time_s", "prn", "pseudorange_m", "doppler_hz", "cn0_dbhz",
                                     "carrier_phase_cycles"))
    # receiver clock: rx_tow = tow0 + (s - s0) / fs is affine in time_s; the median removes rounding
    week0 = int(nav["gps_week"][0])
    rx = week_seconds_since(nav["gps_week"], nav["gps_tow"], week0) + nav["clock_bias_m"] / C_LIGHT
    offset = float(np.median(rx - nav["time_s"]))
    solver = NavSolver(nav_cfg)
    kw = {} if nav_cfg is None else {"nav_cfg": nav_cfg}
    filters = {k: (PvtFilter.from_config(_KindCfg(nav_cfg, k)) if kw else PvtFilter(kind=k)) for k in kinds}
    out = {"time_s": [], "wls": []}
    out.update({k: [] for k in kinds})
    order = np.argsort(obs["time_s"], kind="stable")
    t_all = obs["time_s"][order]
    starts = np.flatnonzero(np.r_[True, np.diff(t_all) != 0.0])
    x0 = None
    for a, b in zip(starts, np.r_[starts[1:], len(t_all)]):
        rows = order[a:b]
        t = float(t_all[a])
        week, rx_tow = normalize_week_tow(week0, offset + t)
        observations = [Observation(prn=int(obs["prn"][i]),
                                    tx_tow=rx_tow - float(obs["pseudorange_m"][i]) / C_LIGHT,
                                    doppler_hz=float(obs["doppler_hz"][i]),
                                    cn0_dbhz=float(obs["cn0_dbhz"][i]),
                                    carrier_phase_cycles=float(obs["carrier_phase_cycles"][i]))
                        for i in rows]
        fix = solver.fix(week, rx_tow, observations, ephemerides, iono_utc, x0=x0)
        out["time_s"].append(t)
        out["wls"].append(fix)
        for k, flt in filters.items():
            out[k].append(flt.step(t, fix) if fix is not None else None)
        if fix is not None:
            x0 = fix.ecef
    return out


class _KindCfg:
    """A navigation config with ``filter`` replaced (for replay_run)."""

    def __init__(self, cfg, kind):
        self._cfg, self.filter = cfg, kind

    def __getattr__(self, name):
        return getattr(self._cfg, name)
