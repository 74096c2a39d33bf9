"""Score a receiver run against the GPS-SDR-SIM truth of a validation case.

The truth is the motion file the simulator was given (ECEF rows at 10 Hz from the start, linearly
interpolated: GPS-SDR-SIM interpolates its ranges linearly between rows).  A fix's time on the case's
axis is its GPS time (``/navigation`` gps_week / gps_tow) minus the start's: the receiver solves GPS time,
so the oscillator error of the file does not shift it.  Coast fixes (mode 2, vector loop without
measurements) are told apart as in :mod:`receiver.evaluate.outages`, whose per-outage report is reused.

Metrics (``score_run``):
  n_fixes, ttff_s            fixes with a finite position; time of the first one after the start
  availability               after the first fix: share of the 1/rate epochs (total outages excluded)
                             holding a measured (non-coast) fix
  rms_3d_m, p95_3d_m         3D error of the measured fixes
  max_err_m                  largest 3D error of all fixes (coast included)
  max_err_meas_m             largest 3D error of the measured fixes
  recovery_s                 per outage window: time from the signal's return to the first measured fix
                             within 10 m (NaN: none before the next outage / the end)
  max_recovery_s             the largest of them (inf when one never recovered)
  along_track_m              mean error along the direction of motion over the measured fixes at > 1 m/s
                             (a time-tag offset dt between the fixes and the motion file shows as v dt)
  cn0_dbhz                   median over the channels of their locked mean C/N0 (the receiver's estimate)
  n_channels                 channels that reached lock
"""
from __future__ import annotations

import math

import numpy as np

from ..evaluate.outages import GOOD_M, MODE_COAST, Fixes, outage_report
from ..gnss.time import week_seconds_since
from ..runfile.reader import RunFile


def _fixes(run_h5):
    with RunFile(str(run_h5)) as rf:
        nav = rf.fix_columns(("gps_week", "gps_tow", "ecef", "mode"))
        cn0 = []
        for name in rf.channel_names():
            a = rf.group_attrs(f"channels/{name}") or {}
            v = a.get("cn0_locked_mean_dbhz")
            if v is None:                           # older run files: the records' mean over tracking
                g = rf.channel(name, ("cn0_dbhz", "state"))
                c = g.get("cn0_dbhz")
                if c is not None and "state" in g:
                    c = c[g["state"] >= 1]
                v = float(np.mean(c)) if c is not None and c.size else None
                if v is not None:
                    cn0.append(v)
            elif np.isfinite(v) and int(a.get("epochs_locked", 0)) > 0:
                cn0.append(float(v))
        rate = float((rf.config().get("navigation") or {}).get("rate_hz") or 10.0)
    return nav, cn0, rate


def score_run(run_h5, case) -> dict:
    """Metrics of the run file against the case's truth (a :class:`receiver.validate.Case`)."""
    nav, cn0, rate = _fixes(run_h5)
    t_tr, ecef_tr = case.truth()
    dur = case.duration_s
    windows = [(float(o["start_s"]), float(o["end_s"])) for o in case.outages]
    total = [(float(o["start_s"]), float(o["end_s"])) for o in case.outages
             if math.isinf(float(o.get("atten_db", math.inf)))]
    out = {"n_fixes": 0, "ttff_s": math.nan, "along_track_m": math.nan, "availability": 0.0, "rms_3d_m": math.nan,
           "p95_3d_m": math.nan, "max_err_m": math.nan, "max_err_meas_m": math.nan,
           "recovery_s": [math.nan] * len(windows), "max_recovery_s": math.inf if windows else math.nan,
           "cn0_dbhz": float(np.median(cn0)) if cn0 else math.nan, "n_channels": len(cn0)}
    if nav is None or nav["gps_tow"].size == 0:
        return out
    t = week_seconds_since(nav["gps_week"].astype(float), nav["gps_tow"].astype(float), case.week) - case.tow0
    pos = np.asarray(nav["ecef"], float).reshape(-1, 3)
    ok = np.all(np.isfinite(pos), axis=1) & np.isfinite(t) & (t >= t_tr[0]) & (t <= t_tr[-1])
    if not ok.any():
        return out
    t, pos, mode = t[ok], pos[ok], np.asarray(nav["mode"])[ok]
    true = np.stack([np.interp(t, t_tr, ecef_tr[:, i]) for i in range(3)], axis=1)
    err = np.linalg.norm(pos - true, axis=1)
    vel = np.stack([np.interp(t, t_tr[1:] - 0.05, np.diff(ecef_tr[:, i]) * 10.0) for i in range(3)], axis=1)
    speed = np.linalg.norm(vel, axis=1)
    moving = (speed > 1.0) & (mode != MODE_COAST)
    if moving.any():
        along = np.sum((pos - true)[moving] * vel[moving], axis=1) / speed[moving]
        out["along_track_m"] = float(np.mean(along))
    fx = Fixes(t=t, err=err, coast=mode == MODE_COAST)
    meas = ~fx.coast
    out["n_fixes"] = int(fx.t.size)
    out["ttff_s"] = float(fx.t[0])
    out["max_err_m"] = float(fx.err.max())
    if meas.any():
        em = fx.err[meas]
        out["rms_3d_m"] = float(np.sqrt(np.mean(em ** 2)))
        out["p95_3d_m"] = float(np.percentile(em, 95))
        out["max_err_meas_m"] = float(em.max())
        t0 = float(fx.t[meas][0])
        grid = np.arange(math.ceil(t0 * rate - 1e-6), math.floor(dur * rate - 1e-6) + 1) / rate
        for a, b in total:
            grid = grid[(grid < a) | (grid >= b)]
        got = np.unique(np.rint(fx.t[meas] * rate).astype(np.int64))
        hit = np.isin(np.rint(grid * rate).astype(np.int64), got)
        out["availability"] = float(hit.mean()) if grid.size else math.nan
    if windows:
        rep = outage_report(fx, sorted(windows), dur, good_m=GOOD_M)
        rec = [r["ttgf_s"] for r in rep["outages"]]
        out["recovery_s"] = [float(v) for v in rec]
        out["max_recovery_s"] = max((math.inf if not np.isfinite(v) else float(v)) for v in rec)
    return out
