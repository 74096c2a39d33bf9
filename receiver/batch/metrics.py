"""Per-run metrics from a run HDF5 file and (when known) the truth: ``compute_metrics(run_h5, ...)``.

Every metric is a float (NaN when it cannot be computed, e.g. no fix or no truth).  Exactly:

``ttff_s``
    Time to first fix: receiver time of the first fix with a finite position (``/navigation/time_s``)
    minus the time of the first processed sample (``first_sample / sample_rate_hz``).
``n_fixes``, ``n_scored``
    Fixes with a finite position; fixes inside the truth's time span (scored).
``pos_3d_rms_m``, ``pos_h_rms_m``, ``pos_v_rms_m``, ``pos_3d_max_m``, ``vel_3d_rms_mps``,
``clock_drift_err_rms_mps``, ``n_sats_mean``, ``pdop_mean``
    From :func:`receiver.evaluate.evaluate` (truth interpolated to the GPS time of each fix, errors in
    East/North/Up at the true position).  With a static ``reference_llh`` instead of a truth file the same
    quantities are computed against that fixed point (velocity truth 0, no clock truth).
``pos_h_max_m``, ``pos_v_max_m``
    Maximum horizontal error and maximum absolute vertical error over the scored fixes (same ENU errors).
``loss_of_lock``
    Number of PLL lock losses: transitions of ``pll_lock`` from 1 to 0, summed over all channels (from the
    channels' ``lock_losses`` attributes, counted over every epoch even when output.channel_rate_hz stores
    fewer records; files without them: from the stored records).
``channels_dropped``
    Channels that had locked and were later dropped (``state`` reached 3 = lost).
``n_channels_locked``
    Channels whose PLL locked at least once (false acquisitions that never lock are not counted).
``carrier_phase_err_std_cyc`` (needs a simulator truth file), ``carrier_phase_epochs``
    For each channel whose PRN has a truth group ``/satellites/Gnn``: the replica (NCO) carrier phase at the
    first sample of each epoch, ``carrier_phase_cycles - if_hz * time_s``, minus the true carrier phase of
    the received signal at the same receiver time (truth ``carrier_phase_cycles``, cubic Hermite
    interpolation with the truth ``doppler_hz`` as its derivative): the negative of
    :func:`receiver.runfile.truth.carrier_phase_error` at the epoch start.  The truth phase already
    contains the receiver clock (the simulated oscillator's bias and drift enter it through
    D_carr = b + tau_c - dt_sv), the satellite clock, the atmosphere and any scintillation phase, so no clock
    or propagation term is left to remove: the difference is the tracking error plus a constant.  That
    constant (integer cycles, the half cycle of the data-bit ambiguity, the NCO's initial phase) is removed
    per channel by the circular mean on the half-cycle circle, m = arg(mean(exp(j 4 pi d))) / (4 pi), and
    the result is wrapped to [-0.25, 0.25) cycles.  Scored epochs: PLL locked, state track or bit-sync, at
    least ``carrier_settle_s`` after the channel's first lock, and the satellite visible in the truth.  The
    metric is the standard deviation (cycles) of all channels' scored epochs pooled; ``carrier_phase_epochs``
    counts them.  Half- and whole-cycle slips do not show in this number (they are wrapped away).
``carrier_disc_std_cyc``
    Truth-free proxy: standard deviation of the carrier discriminator output ``carrier_err_cycles`` over
    the same kind of epochs (locked, settled), all channels pooled.
``cn0_mean_dbhz``
    Mean over channels of each channel's mean C/N0 over its locked epochs (as the run summary).
``vector_fix_fraction``
    Fraction of the fixes produced by a vector loop (``/navigation/mode`` == 1).
``outage_*``, ``fixes_to_end``, ``canyon_*`` (need a simulator truth file with outages)
    From :mod:`receiver.evaluate.outages` (see its docstring): ``outage_n`` total outages; for the first
    four, ``outageK_dur_s`` (length), ``outageK_ttgf_s`` (signal return to the first good fix: measured,
    3D error <= 10 m; NaN if none before the next outage) and ``outageK_max_err_m`` (largest error of the
    measured fixes from its start to the next outage); ``outage_max_err_m`` / ``outage_max_err_all_m``
    (measured / all fixes of the whole run), ``outage_coast_fixes``, ``outage_fixes_inside`` (measured
    fixes more than 0.3 s into an outage: unflagged coasting), ``fixes_to_end`` (1: the
    last measured fix is <= 2 s before the end); random blockage: ``canyon_epochs`` (epochs with >= 4
    satellites visible), ``canyon_availability`` (fraction of them with a measured fix), ``canyon_rms_3d_m``
    and ``canyon_max_err_m`` (measured fixes in the blockage window).
``signal_s``, ``run_wall_s``, ``realtime_factor``
    Seconds of signal processed, and the run file's ``wall_time_s`` / ``realtime_factor`` attributes.
``job_wall_s``, ``job_cpu_s`` (set by the batch runner)
    Wall-clock and CPU time of the whole batch task in its worker (receiver run, output, metrics).
"""
from __future__ import annotations

import math
import os

import numpy as np

from ..errors import UserError
from ..evaluate.outages import OUTAGE_METRIC_KEYS
from ..runfile.reader import RunFile
from ..runfile.record import STATE_BIT_SYNC, STATE_LOST, STATE_TRACK
from ..runfile.truth import TruthFile, carrier_phase_error

METRICS_VERSION = 2

#: metric columns in summary order
METRIC_KEYS = (
    "ttff_s", "n_fixes", "n_scored",
    "pos_3d_rms_m", "pos_3d_max_m", "pos_h_rms_m", "pos_h_max_m", "pos_v_rms_m", "pos_v_max_m",
    "vel_3d_rms_mps", "clock_drift_err_rms_mps",
    "loss_of_lock", "channels_dropped", "n_channels_locked",
    "carrier_phase_err_std_cyc", "carrier_phase_epochs", "carrier_disc_std_cyc",
    "cn0_mean_dbhz", "vector_fix_fraction", "n_sats_mean", "pdop_mean",
) + OUTAGE_METRIC_KEYS + (
    "signal_s", "run_wall_s", "realtime_factor", "job_wall_s", "job_cpu_s",
)
#: metrics that depend on the machine / load, not on the receiver's result
TIMING_KEYS = ("run_wall_s", "realtime_factor", "job_wall_s", "job_cpu_s")


def _nan_dict():
    return {k: math.nan for k in METRIC_KEYS}


def _rms(x):
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else math.nan


def _max(x):
    x = np.asarray(x, dtype=float)
    return float(np.max(x)) if x.size else math.nan


def _read_nav(rf: RunFile):
    return rf.fix_columns()


# ------------------------------------------------------------------------------------------ positions
def fix_enu_errors(nav: dict, truth: dict):
    """ENU position errors (N,3) and 3D velocity errors (N,) of the fixes inside the truth span.

    truth: {"week", "gps_tow" (M,), "ecef" (M,3), "velocity_ecef" (M,3)}; a static reference has M = 2
    rows spanning everything.  Returns (enu, vel_err, scored_mask_over_all_fixes)."""
    from ..estimation.interpolation import interp_columns
    from ..gnss.geodesy import ecef2lla, enu_matrix
    from ..gnss.time import week_seconds_since
    tow = np.asarray(nav["gps_tow"], dtype=float)
    week = np.asarray(nav.get("gps_week", np.full(tow.shape, truth["week"])), dtype=float)
    t = week_seconds_since(week, tow, truth["week"])
    ecef = np.asarray(nav["ecef"], dtype=float).reshape(-1, 3)
    t_tr = truth["gps_tow"]
    ok = np.all(np.isfinite(ecef), axis=1) & np.isfinite(t) & (t >= t_tr[0]) & (t <= t_tr[-1])
    if not ok.any():
        return np.zeros((0, 3)), np.zeros(0), ok
    ts = t[ok]

    def interp(a):
        return interp_columns(t_tr, a, ts)

    true_pos = interp(truth["ecef"])
    lat, lon, _ = ecef2lla(true_pos.mean(axis=0))
    enu = (ecef[ok] - true_pos) @ enu_matrix(lat, lon).T
    vel_err = np.full(ts.size, math.nan)
    if "velocity_ecef" in nav:
        v = np.asarray(nav["velocity_ecef"], dtype=float).reshape(-1, 3)[ok]
        vel_err = np.linalg.norm(v - interp(truth["velocity_ecef"]), axis=1)
    return enu, vel_err, ok


def _read_truth_receiver(truth_h5):
    with TruthFile(truth_h5) as tf:
        return tf.receiver(("gps_tow", "ecef", "velocity_ecef"))


def _static_truth(reference_llh, nav):
    from ..gnss.geodesy import lla2ecef
    from ..gnss.time import WEEK_S
    ref = np.asarray(lla2ecef(*reference_llh), dtype=float).reshape(3)
    week = int(np.asarray(nav.get("gps_week", [0]))[0]) if len(nav["gps_tow"]) else 0
    return {"week": week, "gps_tow": np.array([-2 * WEEK_S, 3 * WEEK_S]), "ecef": np.tile(ref, (2, 1)),
            "velocity_ecef": np.zeros((2, 3))}


def _position_metrics(out, run_h5, nav, truth_h5, reference_llh):
    if nav is None or not len(nav["gps_tow"]):
        out["n_scored"] = 0.0
        return
    if truth_h5:
        from ..evaluate import evaluate
        s = evaluate(run_h5, truth_h5, require_overlap=False)   # a failed run scores n/a
        for k in ("n_scored", "pos_3d_rms_m", "pos_3d_max_m", "pos_h_rms_m", "pos_v_rms_m", "vel_3d_rms_mps",
                  "clock_drift_err_rms_mps", "n_sats_mean", "pdop_mean"):
            out[k] = float(s.get(k, math.nan))
        truth = _read_truth_receiver(truth_h5)
    elif reference_llh is not None:
        truth = _static_truth(reference_llh, nav)
    else:
        return
    enu, vel_err, ok = fix_enu_errors(nav, truth)
    dh = np.hypot(enu[:, 0], enu[:, 1])
    out["pos_h_max_m"] = _max(dh)
    out["pos_v_max_m"] = _max(np.abs(enu[:, 2]))
    if not truth_h5:                 # static reference: the evaluate() quantities computed here
        d3 = np.linalg.norm(enu, axis=1)
        out.update({"n_scored": float(ok.sum()), "pos_3d_rms_m": _rms(d3), "pos_3d_max_m": _max(d3),
                    "pos_h_rms_m": _rms(dh), "pos_v_rms_m": _rms(enu[:, 2]),
                    "vel_3d_rms_mps": _rms(vel_err[np.isfinite(vel_err)])})
        if "n_sats" in nav:
            out["n_sats_mean"] = float(np.mean(np.asarray(nav["n_sats"], float)[ok])) if ok.any() else math.nan
        if "pdop" in nav and ok.any():
            out["pdop_mean"] = float(np.nanmean(np.asarray(nav["pdop"], float)[ok]))


# ------------------------------------------------------------------------------------------ channels
def _truth_sats(truth_h5):
    if not truth_h5:
        return {}
    with TruthFile(truth_h5) as tf:
        sats = tf.satellites(("time_s", "carrier_phase_cycles", "doppler_hz", "visible"))
    return {k: s for k, s in sats.items() if "carrier_phase_cycles" in s and "time_s" in s}


def carrier_phase_errors(ch: dict, tr: dict, if_hz: float, settle_s: float) -> np.ndarray:
    """Wrapped carrier phase errors (cycles) of one channel against its truth (see the module docstring)."""
    t = ch["time_s"]
    lock = ch["pll_lock"] > 0
    if not lock.any():
        return np.zeros(0)
    t_lock = t[np.argmax(lock)]
    tt = tr["time_s"]
    sel = (lock & np.isin(ch["state"], (STATE_TRACK, STATE_BIT_SYNC)) & (t >= t_lock + settle_s)
           & (t >= tt[0]) & (t <= tt[-1]))
    if "visible" in tr and tr["visible"].size:
        k = np.clip(np.searchsorted(tt, t, side="right") - 1, 0, tt.size - 1)
        sel &= tr["visible"][k].astype(bool)
    if sel.sum() < 2 or tt.size < 2:
        return np.zeros(0)
    _, err = carrier_phase_error({k: ch[k][sel] for k in ("time_s", "carrier_phase_cycles")}, tr, if_hz)
    d = -err                          # NCO minus truth
    m = np.angle(np.mean(np.exp(4j * np.pi * d))) / (4.0 * np.pi)
    return np.mod(d - m + 0.25, 0.5) - 0.25


def _channel_metrics(out, rf: RunFile, truth_h5, settle_s):
    if_hz = float(rf.attrs.get("if_hz", 0.0))
    truth = _truth_sats(truth_h5)
    n_lol = n_drop = n_locked = 0
    cn0_means, perr, disc = [], [], []
    names = ("time_s", "carrier_phase_cycles", "pll_lock", "state", "cn0_dbhz",
             "carrier_err_cycles")
    for name in rf.channel_names():
        ch = rf.channel(name, names)
        if "pll_lock" not in ch or not ch["pll_lock"].size:
            continue
        lock = ch["pll_lock"] > 0
        st = rf.group_attrs(f"channels/{name}") or {}
        if "lock_losses" in st:          # statistics over every epoch (exact with output.channel_rate_hz)
            if not st["epochs_locked"]:
                continue
            n_locked += 1
            n_lol += int(st["lock_losses"])
            n_drop += int(bool(st["dropped"]))
            if np.isfinite(st["cn0_locked_mean_dbhz"]):
                cn0_means.append(float(st["cn0_locked_mean_dbhz"]))
            if not lock.any():
                continue
        else:                            # files written before the statistics attributes
            if not lock.any():
                continue
            n_locked += 1
            n_lol += int(np.count_nonzero(np.diff(lock.astype(np.int8)) == -1))
            if "state" in ch and np.any(ch["state"] == STATE_LOST):
                n_drop += 1
            if "cn0_dbhz" in ch:
                c = ch["cn0_dbhz"][lock].astype(float)
                c = c[np.isfinite(c)]
                if c.size:
                    cn0_means.append(float(np.mean(c)))
        t_lock = ch["time_s"][np.argmax(lock)]
        settled = lock & (ch["time_s"] >= t_lock + settle_s)
        if "state" in ch:
            settled &= np.isin(ch["state"], (STATE_TRACK, STATE_BIT_SYNC))
        if "carrier_err_cycles" in ch:
            e = ch["carrier_err_cycles"][settled].astype(float)
            disc.append(e[np.isfinite(e)])
        if name in truth and {"time_s", "carrier_phase_cycles", "state"} <= set(ch):
            perr.append(carrier_phase_errors(ch, truth[name], if_hz, settle_s))
    out["loss_of_lock"] = float(n_lol)
    out["channels_dropped"] = float(n_drop)
    out["n_channels_locked"] = float(n_locked)
    out["cn0_mean_dbhz"] = float(np.mean(cn0_means)) if cn0_means else math.nan
    d = np.concatenate(disc) if disc else np.zeros(0)
    out["carrier_disc_std_cyc"] = float(np.std(d)) if d.size > 1 else math.nan
    if truth:
        p = np.concatenate(perr) if perr else np.zeros(0)
        out["carrier_phase_epochs"] = float(p.size)
        out["carrier_phase_err_std_cyc"] = float(np.std(p)) if p.size > 1 else math.nan


# ------------------------------------------------------------------------------------------ entry point
def compute_metrics(run_h5, truth_h5=None, reference_llh=None, carrier_settle_s: float = 1.0) -> dict:
    """Metrics of one run (see the module docstring); truth_h5: simulator truth file or None;
    reference_llh: [lat, lon, h] of a static antenna when there is no truth file."""
    run_h5 = os.fspath(run_h5)
    if not os.path.isfile(run_h5):
        raise UserError(f"run file not found: {run_h5}")
    out = _nan_dict()
    with np.errstate(all="ignore"):
        with RunFile(run_h5) as rf:
            a = rf.attrs
            fs = float(a.get("sample_rate_hz", math.nan))
            t0 = float(a.get("first_sample", 0)) / fs
            out["signal_s"] = float(a.get("n_samples", math.nan)) / fs
            out["run_wall_s"] = float(a.get("wall_time_s", math.nan))
            out["realtime_factor"] = float(a.get("realtime_factor", math.nan))
            nav = _read_nav(rf)
            n_fix = 0
            if nav is not None and len(nav["gps_tow"]):
                ecef = np.asarray(nav["ecef"], dtype=float).reshape(-1, 3)
                good = np.all(np.isfinite(ecef), axis=1)
                n_fix = int(good.sum())
                if n_fix:
                    out["ttff_s"] = float(np.asarray(nav["time_s"], float)[good][0] - t0)
                if "mode" in nav and len(nav["mode"]):
                    out["vector_fix_fraction"] = float(np.mean(np.asarray(nav["mode"])[good] == 1)) \
                        if n_fix else math.nan
            out["n_fixes"] = float(n_fix)
            _channel_metrics(out, rf, truth_h5, carrier_settle_s)
        _position_metrics(out, run_h5, nav, truth_h5, reference_llh)
        if truth_h5:
            from ..evaluate.outages import batch_metrics, report
            out.update(batch_metrics(report(run_h5, truth_h5)))
    return out
