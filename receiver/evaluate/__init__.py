"""Score a receiver run against simulator truth: ``evaluate(run_h5, truth_h5) -> dict``.

The run file's ``/navigation`` table (one row per fix: gps_week, gps_tow, ecef, velocity_ecef,
clock_bias_m, clock_drift_mps, n_sats, pdop, mode) is compared with the truth file's ``/receiver`` group,
linearly interpolated to each fix's GPS time (``gps_week``/``gps_tow``, aligned to the truth's week).
Fixes outside the truth's time span, or with non-finite positions, are not scored.

Position errors are resolved in the local East/North/Up frame at the true position.  The receiver's clock
bias is compared with the truth's ``clock_bias_m`` (c * (receiver clock reading - GPS time), the receiver
clock being the sample counter started at the truth's ``start_gps_tow_s``); since a receiver may count its
clock from another origin, both the mean and the standard deviation of the difference are reported.
"""
from __future__ import annotations

import math
import os

import numpy as np

from ..errors import UserError
from ..estimation.interpolation import interp_columns
from ..gnss.geodesy import ecef2lla, enu_matrix
from ..gnss.time import week_seconds_since
from ..runfile.reader import RunFile
from ..runfile.truth import TruthFile


def _rms(x):
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else math.nan


def _stat(fn, x):
    x = np.asarray(x, dtype=float)
    return float(fn(x)) if x.size else math.nan


def _read_truth(path):
    with TruthFile(path) as tf:
        return tf.receiver(("gps_tow", "ecef", "velocity_ecef", "clock_bias_m", "clock_drift_mps"))


def _read_run(path):
    with RunFile(path) as rf:
        return rf.fix_columns(("gps_week", "gps_tow", "ecef", "velocity_ecef", "clock_bias_m",
                               "clock_drift_mps", "n_sats", "pdop", "mode"))


def evaluate(run_h5, truth_h5, require_overlap: bool = True) -> dict:
    """Statistics of the run's fixes against the truth (see the module docstring).

    A run whose fixes all lie outside the truth's time span is a one-line UserError (the two files are
    not from the same recording) unless ``require_overlap`` is False."""
    truth = _read_truth(os.fspath(truth_h5))
    nav = _read_run(os.fspath(run_h5))
    t_tr = truth["gps_tow"]
    out = {"n_fixes": 0, "n_scored": 0, "ttff_s": math.nan}
    if nav is None or nav["gps_tow"].size == 0:
        return _fill_nan(out)
    tow = nav["gps_tow"].astype(float)
    week = nav.get("gps_week", np.full(tow.shape, truth["week"])).astype(float)
    t = week_seconds_since(week, tow, truth["week"])     # seconds of the truth's week
    ecef = np.asarray(nav["ecef"], dtype=float).reshape(-1, 3)
    ok = np.all(np.isfinite(ecef), axis=1) & np.isfinite(t)
    out["n_fixes"] = int(np.count_nonzero(ok))
    if out["n_fixes"]:
        out["ttff_s"] = float(np.min(t[ok]) - t_tr[0])
    ok &= (t >= t_tr[0]) & (t <= t_tr[-1])
    out["n_scored"] = int(np.count_nonzero(ok))
    if not out["n_scored"] and out["n_fixes"] and require_overlap:
        tf = t[np.all(np.isfinite(ecef), axis=1) & np.isfinite(t)]
        raise UserError(f"the run's fixes (GPS seconds {tf.min():.1f} .. {tf.max():.1f} of week "
                        f"{truth['week']}) do not overlap the truth file's span ({t_tr[0]:.1f} .. "
                        f"{t_tr[-1]:.1f}): not the same recording?")
    if not out["n_scored"]:
        return _fill_nan(out)
    t = t[ok]

    def interp(a):
        return interp_columns(t_tr, a, t)

    true_pos = interp(truth["ecef"])
    lat, lon, _ = ecef2lla(true_pos.mean(axis=0))
    rot = enu_matrix(lat, lon)
    err = ecef[ok] - true_pos
    enu = err @ rot.T
    d3 = np.linalg.norm(err, axis=1)
    dh = np.hypot(enu[:, 0], enu[:, 1])
    out.update({
        "span_s": float(t[-1] - t[0]),
        "pos_3d_rms_m": _rms(d3), "pos_h_rms_m": _rms(dh), "pos_v_rms_m": _rms(enu[:, 2]),
        "pos_3d_max_m": float(np.max(d3)), "pos_3d_p50_m": float(np.percentile(d3, 50)),
        "pos_3d_p95_m": float(np.percentile(d3, 95)),
        "pos_mean_e_m": float(np.mean(enu[:, 0])), "pos_mean_n_m": float(np.mean(enu[:, 1])),
        "pos_mean_u_m": float(np.mean(enu[:, 2])),
    })
    if "velocity_ecef" in nav:
        verr = np.asarray(nav["velocity_ecef"], dtype=float).reshape(-1, 3)[ok] - interp(truth["velocity_ecef"])
        v3 = np.linalg.norm(verr, axis=1)
        v3 = v3[np.isfinite(v3)]
        out.update({"vel_3d_rms_mps": _rms(v3), "vel_3d_max_mps": _stat(np.max, v3)})
    if "clock_bias_m" in nav:
        cb = np.asarray(nav["clock_bias_m"], dtype=float)[ok] - interp(truth["clock_bias_m"])
        cb = cb[np.isfinite(cb)]
        out.update({"clock_bias_err_mean_m": _stat(np.mean, cb), "clock_bias_err_std_m": _stat(np.std, cb),
                    "clock_bias_err_rms_m": _rms(cb)})
    if "clock_drift_mps" in nav:
        cd = np.asarray(nav["clock_drift_mps"], dtype=float)[ok] - interp(truth["clock_drift_mps"])
        cd = cd[np.isfinite(cd)]
        out.update({"clock_drift_err_mean_mps": _stat(np.mean, cd), "clock_drift_err_rms_mps": _rms(cd)})
    if "n_sats" in nav:
        out["n_sats_mean"] = float(np.mean(nav["n_sats"][ok]))
    if "pdop" in nav:
        out["pdop_mean"] = _stat(np.nanmean, np.asarray(nav["pdop"], dtype=float)[ok])
    return _fill_nan(out)


_ROWS = (
    ("fixes (scored / total)", None, ""),
    ("time to first fix", "ttff_s", "s"),
    ("scored span", "span_s", "s"),
    ("position 3D RMS", "pos_3d_rms_m", "m"),
    ("position horizontal RMS", "pos_h_rms_m", "m"),
    ("position vertical RMS", "pos_v_rms_m", "m"),
    ("position 3D max", "pos_3d_max_m", "m"),
    ("position 3D 50% / 95%", ("pos_3d_p50_m", "pos_3d_p95_m"), "m"),
    ("position mean E / N / U", ("pos_mean_e_m", "pos_mean_n_m", "pos_mean_u_m"), "m"),
    ("velocity 3D RMS", "vel_3d_rms_mps", "m/s"),
    ("velocity 3D max", "vel_3d_max_mps", "m/s"),
    ("clock bias error mean / std", ("clock_bias_err_mean_m", "clock_bias_err_std_m"), "m"),
    ("clock drift error mean / RMS", ("clock_drift_err_mean_mps", "clock_drift_err_rms_mps"), "m/s"),
    ("satellites used (mean)", "n_sats_mean", ""),
    ("PDOP (mean)", "pdop_mean", ""),
)
_KEYS = ("span_s", "pos_3d_rms_m", "pos_h_rms_m", "pos_v_rms_m", "pos_3d_max_m", "pos_3d_p50_m",
         "pos_3d_p95_m", "pos_mean_e_m", "pos_mean_n_m", "pos_mean_u_m", "vel_3d_rms_mps", "vel_3d_max_mps",
         "clock_bias_err_mean_m", "clock_bias_err_std_m", "clock_bias_err_rms_m", "clock_drift_err_mean_mps",
         "clock_drift_err_rms_mps", "n_sats_mean", "pdop_mean")


def _fill_nan(out):
    for k in _KEYS:
        out.setdefault(k, math.nan)
    return out


def format_table(stats: dict) -> str:
    """A printable two-column table of :func:`evaluate`'s statistics."""
    lines = ["gnssrx evaluation against truth", "-" * 52]
    for label, key, unit in _ROWS:
        if key is None:
            val = f"{stats['n_scored']} / {stats['n_fixes']}"
        else:
            keys = key if isinstance(key, tuple) else (key,)
            val = " / ".join("n/a" if not np.isfinite(stats.get(k, math.nan)) else f"{stats[k]:.3f}"
                             for k in keys)
        lines.append(f"{label:<32} {val} {unit}".rstrip())
    return "\n".join(lines)
