"""Coarse-time (snapshot) navigation: a fix from the sub-millisecond code phases of a few milliseconds of
signal, a broadcast ephemeris and a time known only roughly.

Measurements (one per satellite, all at the recording's first sample): the code phase phi_i (chips; the
satellite's transmit time modulo 1 ms is phi_i / chip rate) and the carrier Doppler (Hz, > 0 approaching).

Pseudoranges are known modulo c x 1 ms (299.79 km).  With an a-priori position and time the whole
milliseconds are fixed relative to a reference satellite (the highest): rho_i = M_i c 1 ms - phi_i c /
chip_rate, M_i the integer that brings rho_i - rho_ref nearest to the predicted range difference
(van Diggelen, *A-GPS*, ch. 4: correct when the prior's range-difference error stays below 150 km,
e.g. a position within ~100 km horizontally and a time within a minute).  Then weighted least squares
for five unknowns: position, a range bias b (clock bias plus the unknown common whole milliseconds) and
the error dt of the coarse time of the first sample; d rho_i / d dt is the satellite's range rate.

Without a prior position a Doppler-only solution (position, clock drift and dt from the Dopplers of a
static receiver; several start points on the Earth's surface, the lowest residual kept) gives it.

Integrity: >= 5 satellites (4 with a height constraint), a residual test (the worst satellite is
dropped while the residual RMS exceeds ``residual_threshold_m`` and enough remain), and the whole
milliseconds are tried again from other reference satellites and start points when the test fails.
Pure numpy over receiver.gnss (ephemeris, geodesy, atmosphere).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..gnss.atmosphere import klobuchar_delay_s, saastamoinen_m
from ..gnss.ephemeris import earth_rotation, sat_state, select
from ..gnss.geodesy import azel, ecef2lla, enu_matrix, lla2ecef
from ..gnss.signals import CA_CHIP_RATE, C_LIGHT, L1_HZ
from ..gnss.time import normalize_week_tow

MS_M = C_LIGHT * 1e-3                  # one code period in metres
CHIP_M = C_LIGHT / CA_CHIP_RATE        # one chip in metres
LAMBDA = C_LIGHT / L1_HZ


@dataclass
class SnapObs:
    """One satellite's snapshot measurement at the first sample."""
    prn: int
    code_phase_chips: float           # code phase of the received signal at the first sample
    doppler_hz: float                 # carrier Doppler (> 0 approaching), including the oscillator's error
    cn0_dbhz: float = 45.0
    length_ms: float = 10.0           # snapshot length (the noise model of the weights)


@dataclass
class SnapshotFix:
    """A coarse-time snapshot fix (coarse_time_fix): ok and a message, the position (ECEF m and WGS-84
    lat/lon/height), the estimated GPS time of the first sample, velocity and clock drift, the satellites
    used with their residuals, DOPs and how the prior and the time were found."""
    ok: bool
    message: str = ""
    ecef: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    lat_deg: float = float("nan")
    lon_deg: float = float("nan")
    height_m: float = float("nan")
    gps_week: int = 0
    gps_tow_s: float = float("nan")    # true GPS time of the first sample (estimated)
    time_sigma_s: float = float("nan")
    time_correction_s: float = float("nan")     # estimated minus the coarse time given
    clock_bias_m: float = float("nan")          # range bias b (mod 1 ms meaningless in absolute terms)
    velocity_ecef: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    clock_drift_mps: float = float("nan")
    sigma_enu_m: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    dops: dict = field(default_factory=dict)
    prns: list = field(default_factory=list)
    residuals_m: list = field(default_factory=list)
    doppler_residuals_mps: list = field(default_factory=list)
    rejected: list = field(default_factory=list)
    residual_rms_m: float = float("nan")
    prior: str = ""                   # 'position', 'doppler'
    prior_ecef: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    height_aided: bool = False
    iterations: int = 0
    time_source: str = "code phases"  # or "bit transitions of N satellites" (receiver.navigation.snapshot.refine_time)

    @property
    def n_sats(self) -> int:
        """Number of satellites used in the fix."""
        return len(self.prns)


@dataclass
class SnapshotSettings:
    """Options of the snapshot solver (coarse_time_fix): corrections, elevation mask, residual and PDOP
    limits, altitude and time aiding, and the rejection limits of a fix."""
    troposphere: bool = True
    ionosphere: bool = True
    elevation_mask_deg: float = 5.0
    residual_threshold_m: float = 30.0
    max_pdop: float = 20.0
    height_m: float | None = None     # altitude aiding: height constraint (m above the ellipsoid)
    height_sigma_m: float = 10.0
    time_sigma_s: float | None = None     # time aiding: the coarse time's 1-sigma as a constraint on dt
    max_move_m: float = 250e3             # a fix farther than this from its prior is rejected
    max_doppler_rms_mps: float = 15.0     # the Doppler-only prior needs its residual RMS below this (static)
    max_time_shift_s: float = 120.0       # a fix whose time moved farther from the coarse time is rejected
    max_iter: int = 12


class Ephemerides:
    """The ephemerides of a RINEX file (dict prn -> list) with selection at a time."""

    def __init__(self, by_prn: dict, iono=None, max_age_s: float = 4 * 3600.0):
        self.by_prn, self.iono, self.max_age_s = by_prn, iono, max_age_s

    def get(self, prn: int, week: int, tow: float):
        """The ephemeris of ``prn`` valid at GPS week ``week``, seconds of week ``tow`` (the healthy one with
        the nearest toe within max_age_s), or None."""
        return select(self.by_prn.get(prn, ()), tow, week, self.max_age_s)

    def covered(self, week: int, tow: float) -> list:
        """PRNs with a healthy ephemeris valid at that time."""
        return [p for p in sorted(self.by_prn) if self.get(p, week, tow) is not None]


def _corrections(x, sat_pos, tow, iono, settings):
    """Ionospheric + tropospheric delays (m) and elevations (rad) seen from x."""
    az, el = azel(x, sat_pos)
    lat, lon, h = ecef2lla(x)
    d = np.zeros(len(el))
    plausible = -1000.0 < float(h) < 20000.0           # far from the surface: no atmosphere model
    if plausible and settings.ionosphere and iono is not None:
        d += C_LIGHT * klobuchar_delay_s(iono, np.radians(lat), np.radians(lon), az, np.maximum(el, 0.0), tow)
    if plausible and settings.troposphere:
        d += saastamoinen_m(np.radians(lat), max(float(h), -500.0), np.maximum(el, np.radians(1.0)))
    return d, el


def sat_geometry(ephs: Ephemerides, prns, week: int, t_rx: float, x, t_travel=None):
    """Satellite positions (rotated into the ECEF frame at reception), velocities, clock bias (m) and
    drift (m/s) for a reception at true GPS time t_rx (s of ``week``) at position x.  Transmission at
    t_rx - range / c (iterated twice from 75 ms)."""
    n = len(prns)
    pos, vel = np.empty((n, 3)), np.empty((n, 3))
    clk, drift = np.empty(n), np.empty(n)
    tau = np.full(n, 0.075) if t_travel is None else np.array(t_travel, float)
    for i, prn in enumerate(prns):
        eph = ephs.get(prn, week, t_rx)
        for _ in range(2):
            p, v, cb, cd = sat_state(eph, t_rx - tau[i])
            pr = earth_rotation(p, tau[i])
            tau[i] = np.linalg.norm(pr - x) / C_LIGHT
        pos[i], vel[i] = pr, earth_rotation(v, tau[i])
        clk[i], drift[i] = C_LIGHT * cb, C_LIGHT * cd
    return pos, vel, clk, drift, tau


def _dops(h_geo, x, ncols_clock=1):
    """DOPs from the rows [-u, 1, (rate)] (no weights): GDOP, PDOP, HDOP, VDOP, TDOP in the local frame."""
    q = None
    if h_geo.shape[0] >= h_geo.shape[1]:
        try:
            q = np.linalg.inv(h_geo.T @ h_geo)
        except np.linalg.LinAlgError:
            q = None
    if q is None or not np.all(np.isfinite(q)) or np.any(np.diag(q) < 0):
        return {k: float("inf") for k in ("gdop", "pdop", "hdop", "vdop", "tdop")}
    lat, lon, _ = ecef2lla(x)
    r = enu_matrix(lat, lon)
    qe = r @ q[:3, :3] @ r.T
    return {"gdop": float(np.sqrt(np.trace(q[:4, :4]))), "pdop": float(np.sqrt(np.trace(q[:3, :3]))),
            "hdop": float(np.sqrt(qe[0, 0] + qe[1, 1])), "vdop": float(np.sqrt(qe[2, 2])),
            "tdop": float(np.sqrt(q[3, 3]) / C_LIGHT * 1e9) if ncols_clock else float("nan")}


def _sigma_m(cn0_dbhz, length_ms=10.0):
    """Pseudorange noise model (m) for the weights: ~6 m at 45 dB-Hz over 10 ms (measured on simulated
    snapshots at 4 MS/s), 1 / sqrt(C/N0 x length)."""
    return 6.0 * 10 ** ((45.0 - np.asarray(cn0_dbhz, float)) / 20.0) * np.sqrt(10.0 / np.asarray(length_ms, float))


def doppler_solution(obs: list[SnapObs], ephs: Ephemerides, week: int, tow0: float,
                     starts=None, solve_time: bool = True, max_iter: int = 20):
    """Position of a static receiver from Dopplers alone: unknowns position, clock drift (m/s) and
    (``solve_time``) the error of the coarse time tow0.  Several start points (default: 26 points on
    the Earth's surface); the solution with the smallest residual RMS is returned as (x, drift_mps,
    dt_s, rms_mps) or None."""
    prns = [o.prn for o in obs]
    meas = -LAMBDA * np.array([o.doppler_hz for o in obs])          # range rate + clock drift (m/s)
    n_unk = 5 if solve_time else 4
    if len(obs) < n_unk + 1:
        return None
    if starts is None:
        starts = [lla2ecef(la, lo, 0.0) for la in (-60, -30, 0, 30, 60) for lo in range(-180, 180, 72)] + \
            [lla2ecef(90, 0, 0.0), lla2ecef(-90, 0, 0.0)]
    best = None
    for x0 in starts:
        x, d, dt = np.array(x0, float), 0.0, 0.0
        ok = False
        for _ in range(max_iter):
            pred, h = _doppler_model(ephs, prns, week, tow0 + dt, x, d, solve_time)
            dz = meas - pred
            try:
                step = np.linalg.lstsq(h, dz, rcond=None)[0]
            except np.linalg.LinAlgError:
                break
            step[:3] = np.clip(step[:3], -2e6, 2e6)
            x, d = x + step[:3], d + step[3]
            if solve_time:
                dt += float(np.clip(step[4], -120.0, 120.0))
            r = np.linalg.norm(x)
            if r > 1e7 or r < 5e6 or abs(dt) > 600:      # diverging or off the Earth
                break
            if np.linalg.norm(step[:3]) < 1.0:
                ok = True
                break
        if not ok:
            continue
        pred, _ = _doppler_model(ephs, prns, week, tow0 + dt, x, d, solve_time)
        rms = float(np.sqrt(np.mean((meas - pred) ** 2)))
        h_ell = float(ecef2lla(x)[2])
        if abs(h_ell) > 50e3:
            continue
        if best is None or rms < best[3]:
            best = (x, d, dt, rms)
    return best


def _doppler_model(ephs, prns, week, tow, x, drift, solve_time):
    pos, vel, _, cdrift, _ = sat_geometry(ephs, prns, week, tow, x)
    los = pos - x
    rng = np.linalg.norm(los, axis=1)
    u = los / rng[:, None]
    rr = np.sum(u * vel, axis=1)
    pred = rr + drift - cdrift
    # d(u . v)/dx = -(v - (u . v) u) / range
    hx = -(vel - rr[:, None] * u) / rng[:, None]
    cols = [hx, np.ones((len(prns), 1))]
    if solve_time:
        pos2, vel2, _, cd2, _ = sat_geometry(ephs, prns, week, tow + 1.0, x)
        l2 = pos2 - x
        u2 = l2 / np.linalg.norm(l2, axis=1)[:, None]
        rr2 = np.sum(u2 * vel2, axis=1) - cd2
        cols.append(((rr2 - (rr - cdrift)) / 1.0)[:, None])
    return pred, np.hstack(cols)


def velocity_solution(obs: list[SnapObs], ephs: Ephemerides, week: int, tow: float, x):
    """Receiver velocity (ECEF m/s), clock drift (m/s) and the Doppler residuals (m/s) at position x."""
    prns = [o.prn for o in obs]
    if len(prns) < 4:
        return np.full(3, np.nan), float("nan"), []
    pos, vel, _, cdrift, _ = sat_geometry(ephs, prns, week, tow, x)
    u = (pos - x) / np.linalg.norm(pos - x, axis=1)[:, None]
    meas = -LAMBDA * np.array([o.doppler_hz for o in obs])
    # meas = u . (v_sat - v_rx) + drift - sat drift
    z = meas - np.sum(u * vel, axis=1) + cdrift
    h = np.hstack([-u, np.ones((len(prns), 1))])
    sol = np.linalg.lstsq(h, z, rcond=None)[0]
    return sol[:3], float(sol[3]), list(z - h @ sol)


def _whole_ms(rho_frac, pred, ref):
    """Integers M_i: rho_i = M_i MS_M + rho_frac_i with rho_i - rho_ref nearest to pred_i - pred_ref (the
    reference's M chosen so that its pseudorange is within half a millisecond of its prediction)."""
    m_ref = np.round((pred[ref] - rho_frac[ref]) / MS_M)
    b0 = m_ref * MS_M + rho_frac[ref] - pred[ref]
    return np.round((pred + b0 - rho_frac) / MS_M)


def _line_of_sight(ephs, prns, week, t, x, iono, settings):
    """The satellites' state at GPS time ``t`` (s of week) seen from ECEF ``x``: position, velocity (m, m/s),
    clock and clock drift (m, m/s), atmospheric corrections (m), elevations, ranges (m), unit vectors."""
    pos, vel, clk, cdrift, _ = sat_geometry(ephs, prns, week, t, x)
    corr, el = _corrections(x, pos, t, iono, settings)
    los = pos - x
    rng = np.linalg.norm(los, axis=1)
    return pos, vel, clk, cdrift, corr, el, rng, los / rng[:, None]


def _solve_fixed(obs, rho_frac, m_int, ephs, week, tow0, x0, dt0, settings, sig, use_time=True):
    """Gauss-Newton for (x, b, dt) with the whole milliseconds fixed.  Returns a dict or None."""
    prns = [o.prn for o in obs]
    rho = m_int * MS_M + rho_frac
    x, b, dt = np.array(x0, float), 0.0, dt0
    iono = ephs.iono
    aid = settings.height_m is not None
    it = 0
    for it in range(1, settings.max_iter + 1):
        t = tow0 + dt
        pos, vel, clk, cdrift, corr, el, rng, u = _line_of_sight(ephs, prns, week, t, x, iono, settings)
        pred = rng - clk + corr
        if it == 1:
            b = float(np.median(rho - pred))
        rate = np.sum(u * vel, axis=1) - cdrift                 # d range / d t
        cols = [-u, np.ones((len(prns), 1))] + ([rate[:, None]] if use_time else [])
        h = np.hstack(cols)
        dz = rho - (pred + b)
        w = 1.0 / sig
        hw, zw = h * w[:, None], dz * w
        if aid:
            lat, lon, hh = ecef2lla(x)
            up = enu_matrix(lat, lon)[2]
            row = np.zeros(h.shape[1])
            row[:3] = up
            hw = np.vstack([hw, row / settings.height_sigma_m])
            zw = np.append(zw, (settings.height_m - float(hh)) / settings.height_sigma_m)
        if use_time and settings.time_sigma_s:
            row = np.zeros(hw.shape[1])
            row[4] = 1.0 / settings.time_sigma_s
            hw = np.vstack([hw, row])
            zw = np.append(zw, -dt / settings.time_sigma_s)
        try:
            step, *_ = np.linalg.lstsq(hw, zw, rcond=None)
        except np.linalg.LinAlgError:
            return None
        x = x + step[:3]
        b += step[3]
        if use_time:
            dt += float(np.clip(step[4], -300.0, 300.0))
        if not np.all(np.isfinite(x)) or abs(dt) > 3600:
            return None
        if np.linalg.norm(step[:3]) < 1e-3 and (not use_time or abs(step[4]) < 1e-6):
            break
    t = tow0 + dt
    pos, vel, clk, cdrift, corr, el, rng, u = _line_of_sight(ephs, prns, week, t, x, iono, settings)
    res = rho - (rng - clk + corr + b)
    rate = np.sum(u * vel, axis=1) - cdrift
    h = np.hstack([-u, np.ones((len(prns), 1))] + ([rate[:, None]] if use_time else []))
    w = 1.0 / sig
    hw = h * w[:, None]
    if aid:
        lat, lon, _ = ecef2lla(x)
        row = np.zeros(h.shape[1])
        row[:3] = enu_matrix(lat, lon)[2]
        hw = np.vstack([hw, row / settings.height_sigma_m])
        h = np.vstack([h, row])                 # the DOPs with the height constraint as one more row
    if use_time and settings.time_sigma_s:
        row = np.zeros(hw.shape[1])
        row[4] = 1.0 / settings.time_sigma_s
        hw = np.vstack([hw, row])
    try:
        cov = np.linalg.inv(hw.T @ hw)
    except np.linalg.LinAlgError:
        return None
    return {"x": x, "b": b, "dt": dt, "res": res, "el": el, "h": h, "cov": cov, "iter": it}


def coarse_time_fix(obs: list[SnapObs], ephs: Ephemerides, week: int, tow0: float, prior_ecef=None,
                    settings: SnapshotSettings | None = None, chip_rate: float = CA_CHIP_RATE) -> SnapshotFix:
    """Snapshot fix from ``obs`` (code phases at the first sample), the coarse GPS time of that sample
    (week, tow0) and an a-priori position (ECEF; None: a Doppler-only solution gives it)."""
    s = settings or SnapshotSettings()
    week, tow0 = int(week), float(tow0)
    obs = [o for o in obs if ephs.get(o.prn, week, tow0) is not None]
    min_sats = 4 if s.height_m is not None else 5
    if len(obs) < min_sats:
        return SnapshotFix(False, f"{len(obs)} satellites with an ephemeris found, {min_sats} needed"
                           + ("" if s.height_m is not None else " (4 with a height constraint)"))
    prior, dt_prior, dop_rms = "position", 0.0, None
    if prior_ecef is None:
        sol = doppler_solution(obs, ephs, week, tow0)
        if sol is None:
            return SnapshotFix(False, "no Doppler solution for the a-priori position (too few satellites "
                                      "or inconsistent Dopplers); give --position")
        prior_ecef, dt_prior, dop_rms = sol[0], sol[2], sol[3]
        if dop_rms > s.max_doppler_rms_mps:
            return SnapshotFix(False, f"the Doppler-only solution does not fit a static receiver (RMS {dop_rms:.0f} "
                                      "m/s): a moving receiver? give --position")
        prior = "doppler"
        lat, lon, _ = ecef2lla(prior_ecef)        # the Doppler fix's height is poor: put it on the surface
        prior_ecef = lla2ecef(lat, lon, 0.0 if s.height_m is None else s.height_m)
    prior_ecef = np.asarray(prior_ecef, float)
    rho_frac = -(C_LIGHT / chip_rate) * np.array([o.code_phase_chips for o in obs])
    check = None
    if dop_rms is not None:
        # a static receiver's Dopplers must fit the fix about as well as the Doppler-only solution: a fix
        # hundreds of km off (wrong whole milliseconds from a poor Doppler prior) does not
        def check(sol):
            # (the Doppler-only fit has few degrees of freedom: its RMS can be far below the noise; 20 m/s is
            # ~100 Hz, the misfit of a position ~150-300 km off)
            return _static_doppler_rms(obs, ephs, week, tow0 + sol["dt"], sol["x"]) <= max(2.0 * dop_rms + 3.0,
                                                                                        20.0)
    best = _search(obs, rho_frac, ephs, week, tow0, prior_ecef, dt_prior, s, check)
    if best is None and prior == "doppler":
        # the Doppler fix may be off by more than the ambiguity resolution tolerates: a ring of start
        # points around it
        lat, lon, _ = ecef2lla(prior_ecef)
        enu = enu_matrix(lat, lon)
        for r in (100e3, 200e3):
            for az in np.radians(np.arange(0, 360, 45)):
                x0 = prior_ecef + r * (np.sin(az) * enu[0] + np.cos(az) * enu[1])
                lat2, lon2, _ = ecef2lla(x0)
                x0 = lla2ecef(lat2, lon2, 0.0 if s.height_m is None else s.height_m)
                best = _search(obs, rho_frac, ephs, week, tow0, x0, dt_prior, s, check)
                if best is not None:
                    break
            if best is not None:
                break
    if best is None:
        return SnapshotFix(False, "no consistent solution: the whole milliseconds could not be resolved "
                                  "(a-priori position or time too far off, or false detections)",
                           prior=prior, prior_ecef=prior_ecef)
    sol, used, rejected = best
    uobs = [obs[i] for i in used]
    x = sol["x"]
    lat, lon, h = ecef2lla(x)
    tow = tow0 + sol["dt"]
    wk, tow_n = normalize_week_tow(week, tow)
    cov = sol["cov"]
    enu = enu_matrix(lat, lon)
    cen = enu @ cov[:3, :3] @ enu.T
    v, drift, dres = velocity_solution(uobs, ephs, week, tow, x)
    fix = SnapshotFix(True, "", ecef=x, lat_deg=float(lat), lon_deg=float(lon), height_m=float(h),
                      gps_week=int(wk), gps_tow_s=float(tow_n),
                      time_sigma_s=float(np.sqrt(cov[4, 4])) if cov.shape[0] > 4 else float("nan"),
                      time_correction_s=float(sol["dt"]), clock_bias_m=float(sol["b"]), velocity_ecef=v,
                      clock_drift_mps=drift, sigma_enu_m=np.sqrt(np.maximum(np.diag(cen), 0.0)),
                      dops=_dops(sol["h"], x), prns=[o.prn for o in uobs],
                      residuals_m=[float(r) for r in sol["res"]], doppler_residuals_mps=[float(r) for r in dres],
                      rejected=[obs[i].prn for i in rejected],
                      residual_rms_m=float(np.sqrt(np.mean(sol["res"] ** 2))), prior=prior,
                      prior_ecef=prior_ecef, height_aided=s.height_m is not None, iterations=sol["iter"])
    return fix


def _static_doppler_rms(obs, ephs, week, tow, x) -> float:
    """RMS (m/s) of the Doppler residuals at position x for a static receiver (the clock drift fitted)."""
    prns = [o.prn for o in obs]
    pred, _ = _doppler_model(ephs, prns, week, tow, np.asarray(x, float), 0.0, False)
    r = -LAMBDA * np.array([o.doppler_hz for o in obs]) - pred
    return float(np.std(r))


def _search(obs, rho_frac, ephs, week, tow0, x0, dt0, s, check=None):
    """Whole milliseconds from the prior (x0, dt0), solve, residual test with exclusion of the worst
    satellite; the reference satellite tried in order of elevation.  (sol, used indices, rejected) or
    None."""
    prns = [o.prn for o in obs]
    pos, vel, clk, cdrift, tau = sat_geometry(ephs, prns, week, tow0 + dt0, x0)
    corr, el = _corrections(x0, pos, tow0 + dt0, ephs.iono, s)
    pred = np.linalg.norm(pos - x0, axis=1) - clk + corr
    min_sats = 4 if s.height_m is not None else 5
    visible = el > np.radians(-5.0)
    order = [i for i in np.argsort(-el) if visible[i]][:3]
    sig_all = _sigma_m([o.cn0_dbhz for o in obs], [o.length_ms for o in obs])
    for ref in order:
        m_int = _whole_ms(rho_frac, pred, ref)
        active = [i for i in range(len(obs)) if visible[i]]
        rejected = [i for i in range(len(obs)) if not visible[i]]
        while len(active) >= min_sats:
            idx = np.array(active)
            sol = _solve_fixed([obs[i] for i in idx], rho_frac[idx], m_int[idx], ephs, week, tow0, x0, dt0, s,
                               sig_all[idx])
            if sol is None:
                break
            el_ok = sol["el"] >= np.radians(s.elevation_mask_deg)
            res = sol["res"]
            rms = float(np.sqrt(np.mean(res ** 2)))
            h_ell = float(ecef2lla(sol["x"])[2])
            # the whole milliseconds assumed the prior within ~100 km: a solution much farther from it
            # resolved them under a false assumption (a consistent-looking wrong fix)
            plausible = -2000.0 < h_ell < 20000.0 and np.linalg.norm(sol["x"] - x0) <= s.max_move_m and \
                abs(sol["dt"]) <= s.max_time_shift_s
            if plausible and rms <= s.residual_threshold_m and el_ok.all() and \
                    _dops(sol["h"], sol["x"])["pdop"] <= s.max_pdop:
                if check is None or check(sol):
                    return sol, active, rejected
                break                       # consistent pseudoranges, inconsistent Dopplers: next reference
            if len(active) == min_sats:
                break
            # drop the worst: below the mask first, else the largest residual
            worst = int(np.argmin(sol["el"])) if not el_ok.all() else int(np.argmax(np.abs(res)))
            rejected.append(active.pop(worst))
            # the whole milliseconds again from the new solution when it is plausible (closer prior)
    return None


def in_sky(ephs: Ephemerides, week: int, tow: float, x, mask_deg: float = 5.0) -> list[int]:
    """PRNs above ``mask_deg`` at position x and time (week, tow) according to the ephemerides."""
    prns = ephs.covered(week, tow)
    if not prns:
        return []
    pos, *_ = sat_geometry(ephs, prns, week, tow, np.asarray(x, float))
    _, el = azel(np.asarray(x, float), pos)
    return [p for p, e in zip(prns, el) if np.degrees(e) >= mask_deg]


def refine_time(fix: SnapshotFix, edges: dict, ephs: Ephemerides, settings: SnapshotSettings | None = None,
                max_shift_s: float = 8e-3, tol_s: float = 2e-4):
    """The time of the first sample from data-bit transitions: ``edges`` {prn: time of a transition after the
    first sample (s)}.  A transition leaves the satellite at a multiple of 20 ms of its clock, so from the fix
    (position, its time within a few ms) each gives the first sample's time modulo 20 ms to the accuracy of the
    range (ns).  Returns (tow, n_agreeing) when at least two satellites agree within ``tol_s`` on a time within
    ``max_shift_s`` of the fix's, else None."""
    s = settings or SnapshotSettings()
    prns = [p for p in edges if p in fix.prns]
    if len(prns) < 2 or not fix.ok:
        return None
    week, tow = fix.gps_week, fix.gps_tow_s
    cands = []
    for p in prns:
        t_rx = tow + edges[p]                                   # the transition's arrival (true time)
        pos, _, clk, _, _ = sat_geometry(ephs, [p], week, t_rx, fix.ecef)
        corr, _ = _corrections(fix.ecef, pos, t_rx, ephs.iono, s)
        travel = (np.linalg.norm(pos[0] - fix.ecef) + corr[0]) / C_LIGHT
        t_sv = t_rx - travel + clk[0] / C_LIGHT                 # satellite clock at transmission
        k = np.round(t_sv / 0.02)
        cands.append(tow + (k * 0.02 - t_sv))                   # shift the first sample's time onto the grid
    cands = np.array(cands)
    med = float(np.median(cands))
    agree = np.abs(cands - med) <= tol_s
    if agree.sum() < 2 or abs(med - tow) > max_shift_s:
        return None
    return float(np.mean(cands[agree])), int(agree.sum())


def with_bit_edges(fix: SnapshotFix, obs: list[SnapObs], edges: dict, ephs: Ephemerides,
                   settings: SnapshotSettings | None = None) -> SnapshotFix:
    """The fix again with the time from data-bit transitions (:func:`refine_time`) as a tight constraint, when
    they give one and the new fix passes the same tests; else ``fix`` unchanged.  The result's
    ``time_source`` says which."""
    from dataclasses import replace as _replace
    s = settings or SnapshotSettings()
    r = refine_time(fix, edges, ephs, s)
    if r is None:
        return fix
    tow, n = r
    new = coarse_time_fix(obs, ephs, fix.gps_week, tow, fix.ecef, _replace(s, time_sigma_s=1e-6))
    if not new.ok:
        return fix
    new.prior, new.prior_ecef = fix.prior, fix.prior_ecef
    new.time_source = f"bit transitions of {n} satellites"
    new.time_sigma_s = 1e-6
    return new
