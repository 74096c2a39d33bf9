"""Continuity through signal outages, scored against simulator truth (``gnssrx eval --outages``, batch metrics).

Everything runs on the truth's time axis (``time_s``: receiver seconds since the first sample): a fix's GPS
time (``/navigation`` ``gps_week``/``gps_tow``) is mapped onto it through the truth's ``gps_tow`` column, its
3D error is the distance to the true position interpolated there, and it is a *coast* fix when its ``mode``
is 2 (vector loop bridging an epoch with fewer than four measured satellites); scalar (0), vector (1) and aided
(3: scalar least squares with clock/height constraints, from 3 or more measured satellites) fixes are
*measured* fixes.  A *good* fix is a measured fix within ``good_m`` (10 m) of the truth.

Total outages
    The truth's ``/blockage`` windows of kind *total* (``blockage.total`` and ``prn: all`` outages; random
    blockages that happen to coincide are not total outages), overlapping ones merged; for truth files
    without a ``/blockage`` table, the intervals during which no satellite is visible
    (``/satellites/Gnn/visible`` all false, at the truth rate, at least 50 ms).  For outage k = [a_k, b_k), whose
    *window* runs to the next outage's start a_{k+1} (or the end of the truth):

    ``first_fix_s``  time from the signal's return b_k to the first measured fix in the window;
    ``ttgf_s``       time from b_k to the first good fix in the window (NaN: none);
    ``max_err_m``    largest 3D error of the measured fixes in [a_k, a_{k+1});
    ``max_err_all_m`` the same over every fix, coast fixes included;
    ``n_coast``      coast fixes in [a_k, a_{k+1});
    ``n_inside``     measured fixes more than ``grace_s`` (0.3 s: the time a receiver may take to notice
                     the loss) into the outage, [a_k + grace_s, b_k): a receiver that measures nothing
                     should claim no measured fix there (vector: such epochs must be flagged coast).

    Over the whole run: ``max_err_m`` / ``max_err_all_m`` (measured / all fixes), ``n_coast`` (coast
    fixes), ``n_inside`` (summed over the outages).

Loss of signal (:func:`loss_report`)
    For each blockage of a satellite (>= 0.5 s) whose channel was in lock just before: the time until its
    records lose the lock flag (``lock_lag``) and until its track ends (``lost_lag``, channel declared lost).

Fixes to the end (any blockage)
    ``fixes_to_end``: true when the last measured fix is at most ``end_tol_s`` (2 s) before the end of the
    truth (``end_gap_s``).

Random blockage (urban canyon)
    Over the truth's ``/blockage`` attributes ``random_start_s`` .. ``random_end_s``: the window is cut into
    epochs of one fix period (``navigation.rate_hz`` from the run file's config, else the median fix
    spacing); an epoch *counts* when at least ``min_visible`` (4) satellites are visible in the truth at its
    centre, and is *available* when it holds a measured fix.  ``availability`` = available / counted epochs;
    ``rms_3d_m`` / ``max_err_m``: 3D RMS / maximum of the measured fixes in the window; ``aided_fraction``: the
    share of aided fixes among them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..estimation.interpolation import interp_columns
from ..gnss.time import week_seconds_since
from ..runfile.reader import RunFile
from ..runfile.truth import TruthFile
from ..sim.blockage import KIND_TOTAL

MODE_COAST = 2
MODE_AIDED = 3
GOOD_M = 10.0
END_TOL_S = 2.0
LOSS_GRACE_S = 0.3
MIN_OUTAGE_S = 0.05
LOSS_MIN_BLOCK_S = 0.5
N_OUTAGE_KEYS = 4            # outages reported one by one in the batch metrics

#: batch metric keys of this module (see :func:`batch_metrics`)
OUTAGE_METRIC_KEYS = (
    ("outage_n",)
    + tuple(f"outage{k}_{m}" for k in range(1, N_OUTAGE_KEYS + 1) for m in ("dur_s", "ttgf_s", "max_err_m"))
    + ("outage_max_err_m", "outage_max_err_all_m", "outage_coast_fixes", "outage_fixes_inside", "fixes_to_end",
       "canyon_epochs", "canyon_availability", "canyon_rms_3d_m", "canyon_max_err_m",
       "loss_lock_lag_mean_s", "loss_lock_lag_max_s", "loss_lost_lag_mean_s", "loss_lost_lag_max_s")
)


@dataclass
class Fixes:
    """The fixes of a run on the truth's time axis: t (s), err (3D error, m), coast (bool), aided (bool: mode
    3, a scalar fix with clock/height constraints; None: none); sorted by t."""
    t: np.ndarray
    err: np.ndarray
    coast: np.ndarray
    aided: np.ndarray | None = None

    def __post_init__(self):
        order = np.argsort(self.t, kind="stable")
        self.t = np.asarray(self.t, float)[order]
        self.err = np.asarray(self.err, float)[order]
        self.coast = np.asarray(self.coast, bool)[order]
        self.aided = (np.zeros(self.t.size, bool) if self.aided is None
                      else np.asarray(self.aided, bool)[order])


@dataclass
class Visibility:
    """Truth visibility: t (truth time_s), n_visible per row; random-blockage window (or None); the total
    windows [(start, end)] of the truth's /blockage table (None: the truth has no table)."""
    t: np.ndarray
    n_visible: np.ndarray
    random_window: tuple | None = None
    total_windows: list | None = None


# ------------------------------------------------------------------------------------------ pure math
def total_outages(vis: Visibility, min_s: float = MIN_OUTAGE_S) -> list:
    """[(start, end)]: the /blockage total windows (merged, clipped to the truth span) when the truth has
    the table with such windows or a random blockage (whose coincidences are not total outages), else the
    runs of truth rows with no satellite visible (end: first row with one; e.g. per-satellite outages listed
    for every satellite at once)."""
    step = float(np.median(np.diff(vis.t))) if vis.t.size > 1 else 0.0
    if vis.total_windows is not None and (vis.total_windows or vis.random_window is not None):
        t0, t1 = float(vis.t[0]), float(vis.t[-1]) + step
        out = []
        for a, b in sorted(vis.total_windows):
            a, b = max(a, t0), min(b, t1)
            if b <= a:
                continue
            if out and a <= out[-1][1]:
                out[-1] = (out[-1][0], max(out[-1][1], b))
            else:
                out.append((a, b))
        return out
    dark = np.concatenate(([0], (vis.n_visible == 0).astype(np.int8), [0]))
    starts = np.nonzero(np.diff(dark) == 1)[0]
    ends = np.nonzero(np.diff(dark) == -1)[0]
    t = vis.t
    out = []
    for a, e in zip(starts, ends):
        ta = float(t[a])
        te = float(t[e]) if e < t.size else float(t[-1]) + step
        if te - ta >= min_s - 1e-9:
            out.append((ta, te))
    return out


def outage_report(fx: Fixes, outages: list, t_end: float, good_m: float = GOOD_M,
                  end_tol_s: float = END_TOL_S, grace_s: float = LOSS_GRACE_S) -> dict:
    """Per-outage recovery and error statistics (see the module docstring)."""
    meas = ~fx.coast
    good = meas & (fx.err <= good_m)
    rows = []
    for k, (a, b) in enumerate(outages):
        w_end = outages[k + 1][0] if k + 1 < len(outages) else math.inf
        win = (fx.t >= a) & (fx.t < w_end)
        after = (fx.t >= b) & (fx.t < w_end)

        def first(sel):
            i = np.nonzero(sel)[0]
            return float(fx.t[i[0]] - b) if i.size else math.nan

        def vmax(sel):
            e = fx.err[sel]
            e = e[np.isfinite(e)]
            return float(e.max()) if e.size else math.nan

        rows.append({"start_s": a, "end_s": b, "dur_s": b - a,
                     "first_fix_s": first(after & meas), "ttgf_s": first(after & good),
                     "max_err_m": vmax(win & meas), "max_err_all_m": vmax(win),
                     "n_coast": int(np.count_nonzero(win & fx.coast)),
                     "n_inside": int(np.count_nonzero(meas & (fx.t >= a + grace_s) & (fx.t < b)))})
    out = {"outages": rows}
    out.update(end_report(fx, t_end, end_tol_s))
    e_m, e_a = fx.err[meas], fx.err
    e_m, e_a = e_m[np.isfinite(e_m)], e_a[np.isfinite(e_a)]
    out["max_err_m"] = float(e_m.max()) if e_m.size else math.nan
    out["max_err_all_m"] = float(e_a.max()) if e_a.size else math.nan
    out["n_coast"] = int(np.count_nonzero(fx.coast))
    out["n_inside"] = int(sum(r["n_inside"] for r in rows))
    return out


def end_report(fx: Fixes, t_end: float, end_tol_s: float = END_TOL_S) -> dict:
    """{"end_gap_s": end of the truth - last measured fix, "fixes_to_end": gap <= end_tol_s}."""
    t_meas = fx.t[~fx.coast]
    gap = float(t_end - t_meas[-1]) if t_meas.size else math.inf
    return {"end_gap_s": gap, "fixes_to_end": bool(gap <= end_tol_s)}


def canyon_report(fx: Fixes, vis: Visibility, rate_hz: float, min_visible: int = 4) -> dict | None:
    """Availability and accuracy over the random-blockage window (None without one)."""
    if vis.random_window is None or not rate_hz > 0:
        return None
    w0 = max(vis.random_window[0], float(vis.t[0]))
    w1 = min(vis.random_window[1], float(vis.t[-1]))
    period = 1.0 / rate_hz
    n_ep = int(math.floor((w1 - w0) / period + 1e-9))
    if n_ep < 1:
        return None
    if fx.t.size:        # epochs centred on the fixes' phase (fixes at round GPS times, off the window grid)
        phase = np.angle(np.mean(np.exp(2j * np.pi * (fx.t - w0) / period))) / (2 * np.pi) * period
        w0 += (phase - 0.5 * period) % period
        n_ep = int(math.floor((w1 - w0) / period + 1e-9))
        if n_ep < 1:
            return None
    centres = w0 + (np.arange(n_ep) + 0.5) * period
    k = np.clip(np.searchsorted(vis.t, centres, side="right") - 1, 0, vis.t.size - 1)
    counted = vis.n_visible[k] >= min_visible
    meas = ~fx.coast & (fx.t >= w0) & (fx.t < w0 + n_ep * period)
    slots = np.floor((fx.t[meas] - w0) / period).astype(np.int64)
    has_fix = np.zeros(n_ep, bool)
    has_fix[slots[(slots >= 0) & (slots < n_ep)]] = True
    e = fx.err[meas]
    n_aided = int(np.count_nonzero(fx.aided[meas]))
    e = e[np.isfinite(e)]
    n_counted = int(counted.sum())
    return {"window_s": (w0, w0 + n_ep * period), "epochs": n_ep, "counted": n_counted,
            "available": int((counted & has_fix).sum()),
            "availability": float((counted & has_fix).sum() / n_counted) if n_counted else math.nan,
            "fix_fraction_all": float(has_fix.mean()),
            "aided_fraction": float(n_aided / max(int(meas.sum()), 1)),
            "visible_fraction": float(counted.mean()),
            "rms_3d_m": float(np.sqrt(np.mean(e * e))) if e.size else math.nan,
            "max_err_m": float(e.max()) if e.size else math.nan}


def loss_report(tracks: dict, sat_vis: dict, t_truth: np.ndarray, min_block_s: float = LOSS_MIN_BLOCK_S) -> dict | None:
    """Loss-of-signal detection latency.  tracks: prn -> (record times, lock flags) of its channel(s);
    sat_vis: prn -> truth visibility per t_truth row.  For every blockage of a satellite (visible -> not
    visible, lasting at least min_block_s) whose channel was in lock during the 0.2 s before it:
    ``lock_lag`` = time to the first record without lock (no measurement of it enters a fix from there),
    ``lost_lag`` = time to the end of the track (the channel declared the signal lost; a channel that never
    does - vector tracking - is left out of this one).  None when no such blockage exists."""
    lock, lost = [], []
    for prn, vis in sat_vis.items():
        if prn not in tracks:
            continue
        t, ok = tracks[prn]
        v = np.asarray(vis, bool)
        starts = np.flatnonzero(v[:-1] & ~v[1:]) + 1
        for i in starts:
            tb = float(t_truth[i])
            j = np.flatnonzero(v[i:])
            te = float(t_truth[i + j[0]]) if j.size else float(t_truth[-1])
            if te - tb < min_block_s:
                continue
            pre = (t >= tb - 0.2) & (t < tb)
            if not pre.any() or not ok[pre].all():
                continue
            k = int(np.searchsorted(t, tb))
            after_t, after_ok = t[k:], ok[k:]
            bad = np.flatnonzero(~after_ok)
            gap = np.flatnonzero(np.diff(t[k - 1:]) > 0.1)       # the track ends: the next record is later
            t_end = float(t[k - 1 + gap[0]]) if gap.size else math.inf
            t_bad = float(after_t[bad[0]]) if bad.size else math.inf
            lock.append(min(t_bad, t_end) - tb)
            if t_end < te:
                lost.append(t_end - tb)
    if not lock:
        return None
    lock, lost = np.array(lock), np.array(lost)
    out = {"n": int(lock.size), "lock_lag_mean_s": float(lock.mean()), "lock_lag_max_s": float(lock.max()),
           "n_lost": int(lost.size), "lost_lag_mean_s": math.nan, "lost_lag_max_s": math.nan}
    if lost.size:
        out.update(lost_lag_mean_s=float(lost.mean()), lost_lag_max_s=float(lost.max()))
    return out


def batch_metrics(rep: dict) -> dict:
    """Flat float metrics (:data:`OUTAGE_METRIC_KEYS`) of :func:`report`'s result; NaN where n/a."""
    m = {k: math.nan for k in OUTAGE_METRIC_KEYS}
    o, c = rep.get("total"), rep.get("canyon")
    if o is not None and o["outages"]:
        m["outage_n"] = float(len(o["outages"]))
        for k, row in enumerate(o["outages"][:N_OUTAGE_KEYS], start=1):
            for name in ("dur_s", "ttgf_s", "max_err_m"):
                m[f"outage{k}_{name}"] = float(row[name])
        m["outage_max_err_m"] = o["max_err_m"]
        m["outage_max_err_all_m"] = o["max_err_all_m"]
        m["outage_coast_fixes"] = float(o["n_coast"])
        m["outage_fixes_inside"] = float(o["n_inside"])
    if "fixes_to_end" in rep and has_outages(rep):
        m["fixes_to_end"] = float(rep["fixes_to_end"])
    lr = rep.get("loss")
    if lr is not None:
        for k in ("lock_lag_mean_s", "lock_lag_max_s", "lost_lag_mean_s", "lost_lag_max_s"):
            m[f"loss_{k}"] = lr[k]
    if c is not None:
        m["canyon_epochs"] = float(c["counted"])
        m["canyon_availability"] = c["availability"]
        m["canyon_rms_3d_m"] = c["rms_3d_m"]
        m["canyon_max_err_m"] = c["max_err_m"]
    return m


# ------------------------------------------------------------------------------------------ files
def read_visibility(truth_h5) -> Visibility:
    """The truth file's :class:`Visibility`: satellites visible per truth row and the blockage windows; a file
    that is not a simulator truth file is a one-line UserError."""
    with TruthFile(truth_h5) as tf:
        if not (tf.has("receiver") and tf.has("satellites")):
            raise UserError(f"truth file {truth_h5} has no /receiver or /satellites group "
                            "(not a gnssrx simulator truth file)")
        t = tf.receiver(("time_s",))["time_s"]
        n = np.zeros(t.size, np.int32)
        for s in tf.satellites(("visible",)).values():
            if "visible" in s and s["visible"].shape[0] == t.size:
                n += s["visible"].astype(np.int32)
        win, total = None, None
        battrs = tf.group_attrs("blockage")
        if battrs is not None:
            if "random_start_s" in battrs:
                win = (float(battrs["random_start_s"]), float(battrs["random_end_s"]))
            b = tf.table("blockage")
            if "kind" in b:
                sel = b["kind"] == KIND_TOTAL
                total = [(float(x), float(y)) for x, y in zip(b["start_s"][sel], b["end_s"][sel])]
    return Visibility(t=t, n_visible=n, random_window=win, total_windows=total)


def read_tracks(run_h5) -> dict:
    """prn -> (record times, lock flags) of its channel records, sorted by time."""
    out = {}
    with RunFile(run_h5) as rf:
        for name in rf.channel_names():
            c = rf.channel(name, ("time_s", "pll_lock"))
            prn = rf.channel_prn(name)
            t0, l0 = out.get(prn, (np.zeros(0), np.zeros(0, bool)))
            out[prn] = (np.concatenate([t0, c["time_s"]]), np.concatenate([l0, c["pll_lock"] > 0]))
    for prn, (t, ok) in out.items():
        o = np.argsort(t, kind="stable")
        out[prn] = (t[o], ok[o])
    return out


def read_sat_visibility(truth_h5):
    """(truth time_s, prn -> visible per row)."""
    with TruthFile(truth_h5) as tf:
        t = tf.receiver(("time_s",))["time_s"]
        vis = {}
        for name, s in tf.satellites(("visible",)).items():
            if "visible" in s and s["visible"].shape[0] == t.size and name[1:].isdigit():
                vis[int(name[1:])] = s["visible"].astype(bool)
    return t, vis


def read_fixes(run_h5, truth_h5):
    """(Fixes on the truth's time axis, navigation rate (Hz) or NaN, truth end time)."""
    with TruthFile(truth_h5) as tf:
        tr = tf.receiver(("time_s", "gps_tow", "ecef"))
    week0 = tr["week"]
    rate = math.nan
    with RunFile(run_h5) as rf:
        try:
            rate = float(rf.config()["navigation"]["rate_hz"])
        except Exception:          # older or foreign run files: estimated from the fix spacing below
            rate = math.nan
        nav = rf.fix_columns(("gps_tow", "gps_week", "ecef", "mode"))
    if nav is None or nav["gps_tow"].shape[0] == 0:
        empty = np.zeros(0)
        return Fixes(empty, empty, empty.astype(bool)), rate, float(tr["time_s"][-1])
    tow = nav["gps_tow"].astype(float)
    week = nav["gps_week"].astype(float) if "gps_week" in nav else np.full(tow.shape, week0)
    ecef = nav["ecef"].astype(float).reshape(-1, 3)
    mode = nav["mode"] if "mode" in nav else np.zeros(tow.size, np.uint8)
    gps = week_seconds_since(week, tow, week0)
    ok = np.all(np.isfinite(ecef), axis=1) & (gps >= tr["gps_tow"][0]) & (gps <= tr["gps_tow"][-1])
    gps, ecef, mode = gps[ok], ecef[ok], mode[ok]
    t = np.interp(gps, tr["gps_tow"], tr["time_s"])
    true = interp_columns(tr["gps_tow"], tr["ecef"], gps)
    err = np.linalg.norm(ecef - true, axis=1)
    fx = Fixes(t, err, mode == MODE_COAST, mode == MODE_AIDED)
    if not np.isfinite(rate) and fx.t.size > 1:
        d = np.diff(fx.t)
        d = d[d > 0]
        rate = 1.0 / float(np.median(d)) if d.size else math.nan
    return fx, rate, float(tr["time_s"][-1])


def report(run_h5, truth_h5, good_m: float = GOOD_M) -> dict:
    """{"total": outage_report or None, "canyon": canyon_report or None} of a run against its truth."""
    vis = read_visibility(truth_h5)
    fx, rate, t_end = read_fixes(run_h5, truth_h5)
    outs = total_outages(vis)
    t_truth, sat_vis = read_sat_visibility(truth_h5)
    return {"total": outage_report(fx, outs, t_end, good_m) if outs else None,
            "loss": loss_report(read_tracks(run_h5), sat_vis, t_truth),
            "canyon": canyon_report(fx, vis, rate), "rate_hz": rate, "good_m": good_m,
            **end_report(fx, t_end)}


def has_outages(rep: dict) -> bool:
    """True when an outage report (:func:`report`) has total-outage or urban-canyon results."""
    return rep.get("total") is not None or rep.get("canyon") is not None


def _f(v, fmt="{:.2f}"):
    return "-" if v is None or not np.isfinite(v) else fmt.format(v)


def format_report(rep: dict) -> str:
    """Printable tables of :func:`report`'s result."""
    lines = []
    o = rep.get("total")
    if o is not None:
        lines += ["", f"total outages (good fix: measured, 3D error <= {rep['good_m']:g} m)", "-" * 96,
                  f"{'window (s)':<16}{'length':>8}{'1st fix':>10}{'good fix':>10}{'max err':>10}"
                  f"{'max incl.':>11}{'coast':>8}{'fixes':>8}",
                  f"{'':<16}{'(s)':>8}{'after (s)':>10}{'after (s)':>10}{'(m)':>10}{'coast (m)':>11}"
                  f"{'fixes':>8}{'inside*':>8}"]
        for r in o["outages"]:
            lines.append(f"{r['start_s']:7.2f}-{r['end_s']:<8.2f}{r['dur_s']:8.2f}"
                         f"{_f(r['first_fix_s']):>10}{_f(r['ttgf_s']) if np.isfinite(r['ttgf_s']) else 'never':>10}"
                         f"{_f(r['max_err_m'], '{:.1f}'):>10}{_f(r['max_err_all_m'], '{:.1f}'):>11}"
                         f"{r['n_coast']:>8d}{r['n_inside']:>8d}")
        lines.append(f"* measured (non-coast) fixes more than {LOSS_GRACE_S:g} s into the outage")
        lines.append(f"whole run: max error {_f(o['max_err_m'], '{:.1f}')} m (measured fixes), "
                     f"{_f(o['max_err_all_m'], '{:.1f}')} m (all); coast fixes {o['n_coast']}")
    c = rep.get("canyon")
    if c is not None:
        lines += ["", "random blockage (urban canyon)", "-" * 52,
                  f"window {c['window_s'][0]:.1f}-{c['window_s'][1]:.1f} s, {c['epochs']} epochs of "
                  f"{1.0 / rep['rate_hz']:.3g} s; >= 4 satellites visible in {c['counted']} "
                  f"({100 * c['visible_fraction']:.1f} %)",
                  f"availability (measured fix in those epochs)  {_f(100 * c['availability'], '{:.1f}')} %",
                  f"measured fixes in all epochs                 {_f(100 * c['fix_fraction_all'], '{:.1f}')} %",
                  f"aided (mode 3) among the measured fixes      {_f(100 * c.get('aided_fraction', 0.0), '{:.1f}')} %",
                  f"3D RMS / max of the measured fixes           {_f(c['rms_3d_m'])} / {_f(c['max_err_m'])} m"]
    lr = rep.get("loss")
    if lr is not None and has_outages(rep):
        lines += ["", f"loss of signal ({lr['n']} blockages >= {LOSS_MIN_BLOCK_S:g} s of a satellite in lock)",
                  f"lock flag drops after  mean {_f(lr['lock_lag_mean_s'], '{:.3f}')} s, "
                  f"max {_f(lr['lock_lag_max_s'], '{:.3f}')} s",
                  f"channel declares lost  mean {_f(lr['lost_lag_mean_s'], '{:.3f}')} s, "
                  f"max {_f(lr['lost_lag_max_s'], '{:.3f}')} s ({lr['n_lost']} losses)"]
    if has_outages(rep) and "fixes_to_end" in rep:
        lines.append(f"fixes continue to the end: {'yes' if rep['fixes_to_end'] else 'NO'} "
                     f"(last measured fix {_f(rep['end_gap_s'])} s before the end)")
    return "\n".join(lines)
