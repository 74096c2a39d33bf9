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
static receiver; several start points on the Earth's surface, the lowest residual kept) gives it; when
the Dopplers do not fit a static receiver, the same with the receiver velocity as three more unknowns
(a moving receiver: at least 8 satellites, with 8 the coarse time held; receiver/navigation/snapshot_doppler.py).

Integrity: >= 5 satellites (4 with a height constraint), a residual test (the worst satellite is
dropped while the residual RMS exceeds ``residual_threshold_m`` and enough remain), and the whole
milliseconds are tried again from other reference satellites and start points when the test fails.
The model (measurements, result, settings, geometry) is snapshot_model.py (its names re-exported here),
the time from data-bit transitions snapshot_time.py (which builds on this module).  Pure numpy over receiver.gnss.
"""
from __future__ import annotations

import numpy as np

from ..gnss.geodesy import ecef2lla, enu_matrix, lla2ecef
from ..gnss.signals import CA_CHIP_RATE, C_LIGHT
from ..gnss.time import normalize_week_tow
from .snapshot_doppler import (doppler_solution, moving_doppler_rms, static_doppler_rms,  # noqa: F401
                               velocity_solution)
from .snapshot_model import (CHIP_M, LAMBDA, MS_M, Ephemerides, SnapObs, SnapshotFix,  # noqa: F401
                             SnapshotSettings, corrections, dops, in_sky, line_of_sight, sat_geometry, sigma_m)


#: satellites for the Doppler solution of a moving receiver with the time error (8 unknowns); with one fewer the
#: coarse time is held (7 unknowns)
MIN_MOVING_SATS = 9

def _whole_ms(rho_frac, pred, ref):
    """Integers M_i: rho_i = M_i MS_M + rho_frac_i with rho_i - rho_ref nearest to pred_i - pred_ref (the
    reference's M chosen so that its pseudorange is within half a millisecond of its prediction)."""
    m_ref = np.round((pred[ref] - rho_frac[ref]) / MS_M)
    b0 = m_ref * MS_M + rho_frac[ref] - pred[ref]
    return np.round((pred + b0 - rho_frac) / MS_M)


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
        pos, vel, clk, cdrift, corr, el, rng, u = line_of_sight(ephs, prns, week, t, x, iono, settings)
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
    pos, vel, clk, cdrift, corr, el, rng, u = line_of_sight(ephs, prns, week, t, x, iono, settings)
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
        r = _doppler_prior(obs, ephs, week, tow0, s)
        if isinstance(r, SnapshotFix):
            return r
        prior_ecef, dt_prior, dop_rms, prior = r
    prior_ecef = np.asarray(prior_ecef, float)
    rho_frac = -(C_LIGHT / chip_rate) * np.array([o.code_phase_chips for o in obs])
    check = None
    if dop_rms is not None:
        # the Dopplers must fit the fix about as well as the Doppler-only solution: a fix hundreds of km off
        # (wrong whole milliseconds from a poor Doppler prior) does not.  (The Doppler-only fit has few
        # degrees of freedom: its RMS can be far below the noise; 20 m/s is ~100 Hz, the misfit of a
        # position ~150-300 km off.)
        rms_at = moving_doppler_rms if prior == "doppler (moving)" else static_doppler_rms

        def check(sol):
            return rms_at(obs, ephs, week, tow0 + sol["dt"], sol["x"]) <= max(2.0 * dop_rms + 3.0, 20.0)
    best = _search(obs, rho_frac, ephs, week, tow0, prior_ecef, dt_prior, s, check)
    if best is None and prior.startswith("doppler"):
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
    v, drift, dres, _ = velocity_solution(uobs, ephs, week, tow, x)
    fix = SnapshotFix(True, "", ecef=x, lat_deg=float(lat), lon_deg=float(lon), height_m=float(h),
                      gps_week=int(wk), gps_tow_s=float(tow_n),
                      time_sigma_s=float(np.sqrt(cov[4, 4])) if cov.shape[0] > 4 else float("nan"),
                      time_correction_s=float(sol["dt"]), clock_bias_m=float(sol["b"]), velocity_ecef=v,
                      clock_drift_mps=drift, sigma_enu_m=np.sqrt(np.maximum(np.diag(cen), 0.0)),
                      dops=dops(sol["h"], x), prns=[o.prn for o in uobs],
                      residuals_m=[float(r) for r in sol["res"]], doppler_residuals_mps=[float(r) for r in dres],
                      rejected=[obs[i].prn for i in rejected],
                      residual_rms_m=float(np.sqrt(np.mean(sol["res"] ** 2))), prior=prior,
                      prior_ecef=prior_ecef, height_aided=s.height_m is not None, iterations=sol["iter"])
    return fix


def _doppler_prior(obs, ephs, week, tow0, s):
    """The a-priori position from the Dopplers alone: a static receiver, else a moving one (at least
    MIN_MOVING_SATS - 1 satellites).  (x on the surface, dt, residual RMS m/s, 'doppler' or 'doppler (moving)') or
    a failed SnapshotFix."""
    sol = doppler_solution(obs, ephs, week, tow0)
    kind = "doppler"
    if (sol is None or sol[3] > s.max_doppler_rms_mps) and len(obs) >= MIN_MOVING_SATS - 1:
        # a moving receiver: the velocity as three more unknowns; with one satellite too few for the time
        # error as well, the coarse time is held (a minute's error moves the prior by tens of km, within what
        # the whole-millisecond resolution tolerates)
        mov = doppler_solution(obs, ephs, week, tow0, moving=True, solve_time=len(obs) >= MIN_MOVING_SATS)
        if mov is not None and mov[3] <= s.max_doppler_rms_mps:
            sol, kind = mov, "doppler (moving)"
    if sol is None:
        return SnapshotFix(False, "no Doppler solution for the a-priori position (too few satellites, "
                                  "inconsistent Dopplers, or a moving receiver with fewer than 8 satellites); "
                                  "give --position")
    if sol[3] > s.max_doppler_rms_mps:
        return SnapshotFix(False, f"the Doppler-only solution does not fit a static receiver (RMS {sol[3]:.0f} "
                                  "m/s) nor a moving one (that needs 8 satellites): give --position")
    lat, lon, _ = ecef2lla(sol[0])        # the Doppler fix's height is poor: put it on the surface
    return lla2ecef(lat, lon, 0.0 if s.height_m is None else s.height_m), sol[2], sol[3], kind


def _w_test(res, h, cov, sig):
    """|residual| / (sigma sqrt(1 - leverage)) per observation (rows h of the design, the solution's
    covariance; the leverage w_i^2 h_i cov h_i^T, w_i = 1 / sigma_i)."""
    hc = h[:, :cov.shape[0]]
    lev = np.einsum("ij,jk,ik->i", hc, cov, hc) / sig ** 2
    return np.abs(res) / (sig * np.sqrt(np.clip(1.0 - lev, 1e-4, 1.0)))


def _search(obs, rho_frac, ephs, week, tow0, x0, dt0, s, check=None):
    """Whole milliseconds from the prior (x0, dt0), solve, residual test (the RMS against
    ``residual_threshold_m``, each residual against ``max_norm_residual`` times its noise) with exclusion
    of the worst satellite; the reference satellite tried in order of elevation.  With ``check`` (a Doppler
    prior: its whole milliseconds are a hypothesis) one satellite more than the unknowns is kept, so that
    the residual test can see them wrong (with none to spare any pseudoranges fit exactly: a 5-satellite
    fix 725 km off passed).  (sol, used indices, rejected) or None."""
    prns = [o.prn for o in obs]
    pos, vel, clk, cdrift, tau = sat_geometry(ephs, prns, week, tow0 + dt0, x0)
    corr, el = corrections(x0, pos, tow0 + dt0, ephs.iono, s)
    pred = np.linalg.norm(pos - x0, axis=1) - clk + corr
    min_sats = (4 if s.height_m is not None else 5) + (1 if check is not None else 0)
    visible = el > np.radians(-5.0)
    order = [i for i in np.argsort(-el) if visible[i]][:3]
    sig_all = sigma_m([o.cn0_dbhz for o in obs], [o.length_ms for o in obs])
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
            # a residual far beyond its satellite's noise (sigma_m) is an outlier while others can replace it:
            # Baarda's w-test, the residual over its own sigma, sigma_i sqrt(1 - leverage_i) (a satellite that
            # alone fixes a direction, e.g. the only low one for the height, leaves a small residual)
            nres = _w_test(res, sol["h"][:len(idx)], sol["cov"], sig_all[idx])
            outlier = len(active) > min_sats and float(nres.max()) > s.max_norm_residual
            if plausible and rms <= s.residual_threshold_m and el_ok.all() and not outlier and \
                    dops(sol["h"], sol["x"])["pdop"] <= s.max_pdop:
                if check is None or check(sol):
                    return sol, active, rejected
                break                       # consistent pseudoranges, inconsistent Dopplers: next reference
            if len(active) == min_sats:
                break
            # drop the worst: below the mask first, else the largest residual over its noise
            worst = int(np.argmin(sol["el"])) if not el_ok.all() else int(np.argmax(nres))
            rejected.append(active.pop(worst))
            # the whole milliseconds again from the new solution when it is plausible (closer prior)
    return None
