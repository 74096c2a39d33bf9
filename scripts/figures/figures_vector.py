#!/usr/bin/env python3
"""Reproduce the two vector-tracking papers with the gnssrx simulator and receiver, over seeds.

    python scripts/figures/figures_vector.py --out figures/vector            # full: 5 seeds x 225 s / 65 s
    python scripts/figures/figures_vector.py --out figures/vector --quick    # shortened scenarios (90 s / 45 s)
    python scripts/figures/figures_vector.py --only fig8 --seeds 3 --duration 120 --variants fixed_r,adaptive_r

The experiments are batch files (configs/batch/figures_vector_fig8.yaml, figures_vector_accel.yaml: receiver
variants x simulator seeds) run through receiver/batch: recordings are simulated per seed and every run is
cached by content hash (code + config) under --data, -j runs at a time; a run's result depends only on its
config and seed, not on -j.  This script scores each run against its seed's truth, and the tables give the
mean ± 95 % interval over the seeds, a 'diverged' count (a visible satellite's replica code more than 1 chip
off), and the per-seed values; the figures show the first seed.

Experiments (recordings, truth and run files go to --data, default out/vector):

* Adaptive VLL paper - configs/scenarios/vll_fig8_blockage.yaml (225 s; --quick: 90 s): a car on a
  horizontal figure-eight at 50 m/s; ten satellites for 50 s, then intermittent blockage with fewer than
  four satellites from 58 s on.  Receiver configs/vector_fig8.yaml: scalar tracking (T = 1 ms, PLL 25 Hz,
  DLL 2 Hz) for 45 s, then the vector loop.  Runs: scalar only, fixed_r VLL, adaptive_r VLL (the paper's
  settings: every channel updates, R 1500 m^2 / 900 (m/s)^2, N = 500), adaptive_r with a 32 dB-Hz
  C/N0 mask and a 3-sigma innovation gate, and fixed_r / adaptive_r with an acceleration state
  (vector.motion_model: ca) plus mask and gate (the last three beyond the paper).
    fig8_carrier_error.png    carrier-frequency tracking error (NCO - true Doppler) vs time and histograms,
                              for an always-visible and an intermittently blocked satellite
    fig8_position_error.png   3D position error vs time (grey: fewer than 4 satellites) and histogram
    fig8_velocity_error.png   3D velocity error vs time and histogram
* Polynomial VDFLL paper - configs/scenarios/vdfll_accel_steps.yaml (8 satellites, 45 dB-Hz, 2.5 MS/s,
  40 s of 3-axis piecewise-linear velocity from 25 s; --quick: 20 s).  Receiver configs/vector_accel.yaml,
  vector loop from 23 s.  Runs: cv with sigma_v^2 = 10, 0.1, 1e-3, 1e-5; polynomial with chi-square
  thresholds 20, 25, 30.
    accel_true_velocity.png   true velocity (E, N, U)
    accel_cv_velocity.png     CV-model velocity error for the four sigma_v^2
    accel_poly_vs_cv.png      polynomial (threshold 25) vs CV (0.1 and 1e-3)
    accel_chi2_x_error.png    X (ECEF) position error for thresholds 20, 25, 30

* Third-party recording (../shared/data/gpssim_static_tokyo.bin, skipped when absent): every variant in
  vector mode from 36 s (configs/vector_tokyo.yaml, assisted mode: broadcast ephemeris from the RINEX
  file): 3D RMS against the published antenna position, channels kept.

Also written: vector_results.md (tables), vector_results.json (mean, CI and per-seed values of every row),
vector_results.h5 (per-seed metrics and the plotted seed's time series),
claims.json (paper claim vs measured, for figures/index.md).
"""
from __future__ import annotations

import argparse
import json
import os
import time

import receiver

# BLAS on one thread before numpy loads: the runs of -j 1 execute in this process, and a threaded BLAS sums
# in a thread-count-dependent order (results must not depend on -j)
receiver.limit_blas_threads()

import numpy as np  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))

from receiver.gnss.signals import C_LIGHT  # noqa: E402

FIG8 = {
    "name": "fig8", "scenario": "configs/scenarios/vll_fig8_blockage.yaml",
    "batch": "configs/batch/figures_vector_fig8.yaml",
    "config": "configs/vector_fig8.yaml", "duration": 225.0, "quick_duration": 90.0,
    "t_vector": 45.0, "window": 45.0,
}
ACCEL = {
    "name": "accel", "scenario": "configs/scenarios/vdfll_accel_steps.yaml",
    "batch": "configs/batch/figures_vector_accel.yaml",
    "config": "configs/vector_accel.yaml", "duration": 65.0, "quick_duration": 45.0,
    "t_vector": 23.0, "window": 25.0,
}
LABEL = {"scalar": "scalar (PLL 25 Hz / DLL 2 Hz)", "fixed_r": "VLL fixed R", "adaptive_r": "adaptive VLL",
         "adaptive_r_robust": "adaptive VLL + C/N0 mask + 3-sigma gate",
         "adaptive_r_ca_only": "adaptive VLL, acceleration state",
         "fixed_r_ca": "VLL fixed R, acceleration state + mask + gate",
         "adaptive_r_ca": "adaptive VLL, acceleration state + mask + gate", "poly_20": "polynomial, chi2 20",
         "poly_25": "polynomial, chi2 25", "poly_30": "polynomial, chi2 30"}
COLOR = {"scalar": "tab:gray", "fixed_r": "tab:blue", "adaptive_r": "tab:red", "adaptive_r_robust": "tab:orange",
         "fixed_r_ca": "tab:cyan", "adaptive_r_ca": "tab:green", "adaptive_r_ca_only": "tab:olive",
         "cv_10": "tab:blue", "cv_0.1": "tab:orange", "cv_0.001": "tab:green", "cv_1e-05": "tab:purple",
         "poly_20": "tab:cyan", "poly_25": "tab:red", "poly_30": "tab:green"}
SEEDS_NOTE = ("Every cell: mean ± 95 % Student-t interval over the simulator seeds (noise, oscillator and "
              "data realisations; trajectory and blockage fixed); 'diverged' = runs in which a visible "
              "satellite's replica code drifted more than 1 chip from the truth (lost code lock), shown "
              "as a rate and kept in the means; the next column repeats RMS / max over the other seeds.")
DIVERGED_CODE_CHIPS = 1.0   # a run diverged when a visible satellite's replica code is more than this off
FREQ_LOCK_HZ = 100.0        # "in lock": |NCO - true Doppler| below this ...
CODE_LOCK_CHIPS = 0.5       # ... and |code error| below this, at every epoch


def label(run):
    if run.startswith("cv_"):
        return f"CV, sigma_v^2 = {run[3:]}"
    return LABEL.get(run, run)


# ----------------------------------------------------------------------------------------- running
def experiment_batch(exp, args):
    """The experiment's batch file as a mapping, with the script's options applied (duration, seeds,
    variants, output directory)."""
    from receiver.config import read_yaml
    raw = read_yaml(os.path.join(ROOT, exp["batch"]))
    dur = args.duration or (exp["quick_duration"] if args.quick else exp["duration"])
    for inp in raw["inputs"]:
        inp["set"] = {**(inp.get("set") or {}), "time.duration_s": float(dur)}
    seeds = list(raw["seeds"])
    if args.seeds:
        seeds = (seeds + [200 + k for k in range(args.seeds)])[:args.seeds]
    raw["seeds"] = seeds
    if args.variants:
        want = args.variants.split(",")
        raw["variants"] = [v for v in raw["variants"] if v["name"] in want]
    raw["output_dir"] = os.path.join(args.data, os.path.basename(raw["output_dir"]))
    if args.sets:                       # extra receiver overrides (figures-check perturbation demo)
        base = raw.get("set") or {}
        base = [f"{k}={v}" for k, v in base.items()] if isinstance(base, dict) else list(base)
        raw["set"] = base + list(args.sets)
    return raw, float(dur)


def run_experiment(exp, args, log):
    """Run (or take from the batch cache) every variant x seed of one experiment through receiver/batch.
    Returns {seed: (truth_h5, {variant: (run_h5, wall_s)})} and the signal duration."""
    from receiver.batch.config import load_batch
    from receiver.batch.plan import code_fingerprint, make_plan
    from receiver.batch.runner import run_batch
    from receiver.runfile.reader import RunFile
    raw, dur = experiment_batch(exp, args)
    # one code identity for the run and the plan read back below (a source edit in between must not
    # change the run keys)
    raw["code_version"] = code_fingerprint(raw.get("code_version", "auto"))
    b = load_batch(raw)
    res = run_batch(b, jobs=args.jobs, quiet=True)
    log(f"  batch {b.name}: {res.n_runs} runs ({res.executed} executed, {res.cached} cached, "
        f"{res.failed} failed, {res.simulated} recordings simulated) in {res.wall_s:.0f} s")
    status = {r["run_id"]: r for r in res.rows}
    out = {}
    for r in make_plan(b).runs:
        row = status[r.key]
        if row["status"] != "ok":
            log(f"  {r.variant} seed {r.seed}: {row['status']} {row['error']}")
            continue
        with RunFile(r.h5) as rf:
            wall = rf.attrs.get("wall_time_s")        # the run's own timing (receiver pipeline only)
        out.setdefault(int(r.seed), (r.truth, {}))[1][r.variant_name] = \
            (r.h5, float(wall) if wall is not None else None)
    return out, dur


# ----------------------------------------------------------------------------------------- analysis
def load_truth(path):
    from receiver.runfile.truth import TruthFile
    with TruthFile(path) as tf:
        tr = tf.receiver(("time_s", "gps_tow", "ecef", "velocity_ecef"))
        tr["tow0"] = float(tf.attrs["start_gps_tow_s"])
        sats = {int(k[1:]): s for k, s in tf.satellites(("time_s", "doppler_hz", "pseudorange_m",
                                                          "visible")).items()}
    t = tr["time_s"]
    some = next(iter(sats.values()))
    nvis = np.sum([np.interp(some["time_s"], s["time_s"], s["visible"].astype(float)) > 0.5
                   for s in sats.values()], axis=0)
    tr["nvis_t"], tr["nvis"] = some["time_s"], nvis
    tr["sats"] = sats
    tr["t"] = t
    return tr


def nav_errors(run_h5, tr, t_from):
    """Fixes after t_from (s since the first sample): time, 3D position / velocity errors, ECEF error."""
    from receiver.runfile.reader import RunFile
    with RunFile(run_h5) as rf:
        g = rf.fix_columns(("gps_tow", "ecef", "velocity_ecef", "mode", "n_sats"))
    if g is None:
        return None
    tow, e, v, mode, nsat = g["gps_tow"], g["ecef"], g["velocity_ecef"], g["mode"], g["n_sats"]
    rel = tow - tr["gps_tow"][0] + tr["t"][0]
    k = rel >= t_from
    rel, tow, e, v, mode, nsat = rel[k], tow[k], e[k], v[k], mode[k], nsat[k]
    P = np.stack([np.interp(tow, tr["gps_tow"], tr["ecef"][:, i]) for i in range(3)], 1)
    V = np.stack([np.interp(tow, tr["gps_tow"], tr["velocity_ecef"][:, i]) for i in range(3)], 1)
    de = e - P
    return {"t": rel, "pos_err": np.linalg.norm(de, axis=1), "vel_err": np.linalg.norm(v - V, axis=1),
            "ecef_err": de, "mode": mode, "n_sats": nsat}


def channel_errors(run_h5, tr, prns=None, step=1):
    """Per PRN: record time, NCO-minus-true Doppler (Hz), replica code error (chips), signal visible."""
    from receiver.runfile.reader import RunFile
    out = {}
    with RunFile(run_h5) as rf:
        for name in rf.channel_names():
            prn = int(name[1:])
            if prns is not None and prn not in prns or prn not in tr["sats"]:
                continue
            c = rf.channel(name, ("time_s", "doppler_hz", "code_phase_chips"), step)
            t = c["time_s"]
            dop = c["doppler_hz"]
            cp = c["code_phase_chips"]
            s = tr["sats"][prn]
            d_true = np.interp(t, s["time_s"], s["doppler_hz"])
            rho = np.interp(t, s["time_s"], s["pseudorange_m"])
            # signal code phase at the record's first sample: (transmit time mod 1 ms) * f_code
            frac = (tr["tow0"] * 1000.0) % 1.0 + t * 1000.0 - rho / C_LIGHT * 1000.0
            code_true = (frac % 1.0) * 1023.0
            cerr = (cp - code_true + 511.5) % 1023.0 - 511.5
            vis = np.interp(t, s["time_s"], s["visible"].astype(float)) > 0.5
            out[prn] = {"t": t, "freq_err": dop - d_true, "code_err": cerr, "visible": vis}
    return out


def stats(x):
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if not x.size:
        return float("nan"), float("nan")
    return float(np.sqrt(np.mean(x * x))), float(np.max(np.abs(x)))


# ----------------------------------------------------------------------------------------- plots
def shade_outages(ax, tr, t0, t1):
    t, n = tr["nvis_t"], tr["nvis"]
    low = (n < 4) & (t >= t0) & (t <= t1)
    if not low.any():
        return
    edges = np.diff(np.concatenate([[0], low.astype(int), [0]]))
    for a, b in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]):
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color="0.85", lw=0, zorder=0)


def plot_fig8(res, tr, out, t_end):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    runs = [r for r in ("scalar", "fixed_r", "adaptive_r", "adaptive_r_ca") if r in res]
    files = []
    for key, unit, fname in (("pos_err", "m", "fig8_position_error.png"),
                             ("vel_err", "m/s", "fig8_velocity_error.png")):
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5), gridspec_kw={"width_ratios": [3, 1]})
        shade_outages(a1, tr, 40, t_end)
        top, dmax = 1.0, 0.0
        for r in runs:
            e = res[r]["nav"]
            if e is not None and len(e["t"]) and r != "scalar":
                top = max(top, float(np.max(e[key][e["t"] >= FIG8["window"]], initial=0.0)))
        for r in runs:
            e = res[r]["nav"]
            if e is None or not len(e["t"]):
                continue
            a1.plot(e["t"], e[key], ".", ms=1.5, color=COLOR[r], label=label(r))
            vec = e[key][e["t"] >= FIG8["window"]]
            if not len(vec):
                continue
            h, edges = np.histogram(vec, bins=60, range=(0, top * 1.05), density=True)
            a2.stairs(h, edges, color=COLOR[r])
            if r != "scalar":
                dmax = max(dmax, float(h.max()))
        a2.set_ylim(0, dmax * 1.15 if dmax > 0 else 1)
        a1.set_ylim(0, top * 1.1)
        a1.set_xlabel("time since the first sample (s)   (grey: fewer than 4 satellites with signal)")
        a1.set_ylabel(f"3D {'position' if key == 'pos_err' else 'velocity'} error ({unit})")
        a1.axvline(FIG8["t_vector"], color="k", ls=":", lw=1)
        a1.legend(loc="upper left", markerscale=6, fontsize=8)
        a2.set_xlabel(f"error ({unit}), t >= {FIG8['window']:g} s")
        a2.set_ylabel("density")
        fig.tight_layout()
        fig.savefig(os.path.join(out, fname), dpi=110)
        plt.close(fig)
        files.append(fname)
    # carrier-frequency tracking error, two satellites
    prns = res["_carrier_prns"]
    fig, axes = plt.subplots(len(prns), 2, figsize=(13, 3.6 * len(prns)),
                             gridspec_kw={"width_ratios": [3, 1]}, squeeze=False)
    for i, prn in enumerate(prns):
        a1, a2 = axes[i]
        s = tr["sats"][prn]
        for r in runs:
            ce = res[r]["chan"].get(prn)
            if ce is None:
                continue
            a1.plot(ce["t"], ce["freq_err"], ".", ms=1, color=COLOR[r], label=label(r))
            k = ce["t"] >= FIG8["window"]
            a2.hist(ce["freq_err"][k], bins=80, range=(-60, 60), histtype="step", color=COLOR[r], density=True)
        blocked = ~s["visible"].astype(bool)
        if blocked.any():
            a1.fill_between(s["time_s"], -60, 60, where=blocked, color="0.85", lw=0, zorder=0)
        a1.set_ylim(-60, 60)
        a1.axvline(FIG8["t_vector"], color="k", ls=":", lw=1)
        a1.set_ylabel(f"G{prn:02d} Doppler error (Hz)")
        a1.set_title(f"G{prn:02d}: carrier-frequency tracking error (grey: this satellite blocked)", fontsize=9)
        a2.set_xlabel("Hz")
        if i == 0:
            a1.legend(loc="upper left", markerscale=8, fontsize=8)
    axes[-1][0].set_xlabel("time since the first sample (s)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig8_carrier_error.png"), dpi=110)
    plt.close(fig)
    files.append("fig8_carrier_error.png")
    return files


def accel_steps():
    """Times (s) at which the acceleration of the accel scenario changes."""
    from receiver.config import read_yaml
    segs = read_yaml(os.path.join(ROOT, ACCEL["scenario"]))["receiver"]["segments"]
    return np.cumsum([seg["duration_s"] for seg in segs])[:-1]


def plot_accel(res, tr, out, t_end):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from receiver.gnss.geodesy import ecef2lla, enu_matrix
    files = []
    steps = [t for t in accel_steps() if t <= t_end]

    def mark(ax):
        for t in steps:
            ax.axvline(t, color="0.6", lw=0.6, ls="--", zorder=0)
    lat, lon, _ = ecef2lla(tr["ecef"][0])
    R = enu_matrix(lat, lon)
    venu = tr["velocity_ecef"] @ R.T
    fig, ax = plt.subplots(figsize=(10, 4))
    for i, n in enumerate("ENU"):
        ax.plot(tr["t"], venu[:, i], label=f"v_{n}")
    ax.axvline(ACCEL["t_vector"], color="k", ls=":", lw=1)
    mark(ax)
    ax.set_xlabel("time since the first sample (s)   (dashed: acceleration changes)")
    ax.set_ylabel("true velocity (m/s)")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "accel_true_velocity.png"), dpi=110)
    plt.close(fig)
    files.append("accel_true_velocity.png")

    def vel_plot(runs, fname, title):
        fig, ax = plt.subplots(figsize=(10, 4))
        for r in runs:
            e = res.get(r, {}).get("nav")
            if e is None:
                continue
            ax.plot(e["t"], e["vel_err"], lw=0.8, color=COLOR[r],
                    label=f"{label(r)} (RMS {stats(e['vel_err'][e['t'] >= ACCEL['window']])[0]:.2f} m/s)")
        ax.set_xlabel("time since the first sample (s)")
        ax.set_ylabel("3D velocity error (m/s)")
        ax.set_title(title, fontsize=10)
        ax.axvline(ACCEL["window"], color="k", ls=":", lw=1)
        mark(ax)
        ax.set_yscale("log")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(os.path.join(out, fname), dpi=110)
        plt.close(fig)
        files.append(fname)

    vel_plot([r for r in res if r.startswith("cv_")], "accel_cv_velocity.png",
             "CV-model VDFLL: velocity error for four velocity process noises")
    vel_plot(["poly_25", "cv_0.1", "cv_0.001"], "accel_poly_vs_cv.png",
             "polynomial-predictive VDFLL (chi2 threshold 25) vs CV-model VDFLL")
    fig, ax = plt.subplots(figsize=(10, 4))
    for r in ("poly_20", "poly_25", "poly_30"):
        e = res.get(r, {}).get("nav")
        if e is None:
            continue
        ax.plot(e["t"], e["ecef_err"][:, 0], lw=0.8, color=COLOR[r], label=label(r))
    ax.set_xlabel("time since the first sample (s)")
    ax.set_ylabel("X (ECEF) position error (m)")
    ax.axvline(ACCEL["window"], color="k", ls=":", lw=1)
    mark(ax)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "accel_chi2_x_error.png"), dpi=110)
    plt.close(fig)
    files.append("accel_chi2_x_error.png")
    return files


# ----------------------------------------------------------------------------------------- third party
TOKYO_BIN = os.path.join(os.path.dirname(ROOT), "shared", "data", "gpssim_static_tokyo.bin")
TOKYO_ECEF = np.array([-3959617.482, 3350136.615, 3699531.459])


def tokyo(data, quick, reuse, log):
    """Every variant on the third-party recording from 36 s; rows for the table."""
    if not os.path.exists(TOKYO_BIN):
        log(f"  third-party recording absent ({TOKYO_BIN}): skipped")
        return []
    from receiver.schema import load_receiver_config
    from receiver.pipeline import run as run_pipeline
    rows = []
    for variant in ("fixed_r", "adaptive_r", "polynomial", "cv"):
        out = os.path.join(data, f"tokyo_{variant}.h5")
        wall = None
        if not (reuse and os.path.exists(out)):
            cfg = load_receiver_config(os.path.join(ROOT, "configs", "vector_tokyo.yaml"),
                                       [("vector.variant", variant), ("output.path", out)])
            t0 = time.perf_counter()
            run_pipeline(cfg, quiet=True, log=lambda *a: None)
            wall = time.perf_counter() - t0
            log(f"  tokyo {variant:<12} in {wall:5.1f} s")
        from receiver.runfile.reader import RunFile
        with RunFile(out) as rf:
            g = rf.fix_columns(("mode", "ecef", "velocity_ecef", "time_s", "n_sats", "clock_drift_mps",
                                "clock_bias_m"))
            vec = g["mode"] == 1
            d = np.linalg.norm(g["ecef"][vec] - TOKYO_ECEF, axis=1)
            v = np.linalg.norm(g["velocity_ecef"][vec], axis=1)
            t_end = float(g["time_s"][-1])
            kept, total = 0, 0
            for name in rf.channel_names():
                c = rf.channel(name, ("time_s", "pll_lock"))
                tt = c["time_s"]
                if tt[0] < 35.0:
                    total += 1
                    kept += int(tt[-1] > t_end - 0.5 and c["pll_lock"][-500:].mean() > 0.9)
            rows.append({"run": variant, "n_fixes": int(vec.sum()), "pos_rms": stats(d)[0], "pos_max": stats(d)[1],
                         "vel_rms": stats(v)[0], "vel_max": stats(v)[1], "kept": kept, "total": total,
                         "n_sats_min": int(g["n_sats"][vec].min()) if vec.any() else 0,
                         "drift": float(np.median(g["clock_drift_mps"][vec])),
                         "bias_span": float(np.ptp(g["clock_bias_m"][vec])), "wall_s": wall})
    return rows


# ----------------------------------------------------------------------------------------- main
def analyse(exp, runs_h5, tr, carrier_prns, t_end, chan_step):
    res = {"_carrier_prns": carrier_prns}
    for run, (h5, wall) in runs_h5.items():
        nav = nav_errors(h5, tr, exp["t_vector"] - 5.0)
        chan = channel_errors(h5, tr, None, chan_step)
        res[run] = {"nav": nav, "chan": chan, "wall": wall, "h5": h5}
    return res


def summarise(exp, res, tr, t_end, rate):
    rows = []
    w0 = exp["window"]
    for run, r in res.items():
        if run.startswith("_"):
            continue
        e = r["nav"]
        row = {"run": run}
        if e is not None:
            k = e["t"] >= w0
            if run != "scalar":
                k &= e["mode"] == 1
            row["pos_rms"], row["pos_max"] = stats(e["pos_err"][k])
            row["vel_rms"], row["vel_max"] = stats(e["vel_err"][k])
            row["n_fixes"] = int(k.sum())
            row["availability"] = float(k.sum() / ((t_end - w0) * rate))
            # fixes while fewer than 4 satellites carry a signal
            nv = np.interp(e["t"][k], tr["nvis_t"], tr["nvis"])
            row["fixes_lt4"] = int(np.sum(nv < 4))
            row["pos_max_lt4"] = stats(e["pos_err"][k][nv < 4])[1]
            # velocity away from the two-satellite periods: at least 3 satellites over the last 2 s
            nmin = np.array([tr["nvis"][(tr["nvis_t"] >= t - 2.0) & (tr["nvis_t"] <= t)].min(initial=99)
                             for t in e["t"][k]])
            row["vel_max_ge3"] = stats(e["vel_err"][k][nmin >= 3])[1]
            row["vel_max_2"] = stats(e["vel_err"][k][nmin <= 2])[1]
        else:
            row.update(pos_rms=np.nan, pos_max=np.nan, vel_rms=np.nan, vel_max=np.nan, n_fixes=0,
                       availability=0.0, fixes_lt4=0, pos_max_lt4=np.nan, vel_max_ge3=np.nan,
                       vel_max_2=np.nan)
        fmax, cmax = 0.0, 0.0
        for prn, c in r["chan"].items():
            k = (c["t"] >= w0) & c["visible"]
            if k.any():
                fmax = max(fmax, float(np.max(np.abs(c["freq_err"][k]))))
                cmax = max(cmax, float(np.max(np.abs(c["code_err"][k]))))
        row["freq_err_max_hz"], row["code_err_max_chips"] = fmax, cmax
        row["channels"] = len(r["chan"])
        row["wall_s"] = r["wall"] if r["wall"] is not None else np.nan
        rows.append(row)
    return rows


LABEL_ORDER = {"fig8": ["scalar", "fixed_r", "adaptive_r", "adaptive_r_robust", "adaptive_r_ca_only", "fixed_r_ca",
                         "adaptive_r_ca"],
               "accel": ["cv_10", "cv_0.1", "cv_0.001", "cv_1e-05", "poly_20", "poly_25", "poly_30"]}
NUMERIC = ("pos_rms", "pos_max", "vel_rms", "vel_max", "n_fixes", "availability", "fixes_lt4", "pos_max_lt4",
           "vel_max_ge3", "vel_max_2", "freq_err_max_hz", "code_err_max_chips", "channels", "wall_s")


def interval(values):
    """(mean, half width of the 95 % Student-t interval) of the finite values (NaN half width for n < 2)."""
    from receiver.batch.compare import interval as t_interval
    n, mean, lo, hi = t_interval(values, 0.95)
    return mean, (hi - lo) / 2.0 if n >= 2 else float("nan")


def aggregate(seed_rows, order):
    """One row per variant: the mean of every metric over the seeds (same keys as a per-seed row), the 95 %
    half widths under 'ci', the per-seed values under 'per_seed', diverged / lock_kept counts."""
    out = []
    for run in order:
        rs = sorted((r for r in seed_rows if r["run"] == run), key=lambda r: r["seed"])
        agg = {"run": run, "n_seeds": len(rs), "seeds": [r["seed"] for r in rs], "ci": {}, "per_seed": {}}
        for k in NUMERIC:
            vals = [float(r[k]) for r in rs]
            agg[k], agg["ci"][k] = interval(vals)
            agg["per_seed"][k] = vals
        # the same statistics without the diverged seeds (a divergence is shown, not averaged away)
        ok = [r for r in rs if not r["diverged"]]
        agg["ok"] = {k: interval([float(r[k]) for r in ok]) for k in ("pos_rms", "pos_max", "vel_rms", "vel_max")}
        agg["n_diverged"] = int(sum(r["diverged"] for r in rs))
        agg["n_lock_kept"] = int(sum(r["lock_kept"] for r in rs))
        agg["per_seed"]["diverged"] = [bool(r["diverged"]) for r in rs]
        out.append(agg)
    return out


def pm(r, k, d=2):
    if k not in r:                           # a row left out (--variants)
        return "n/a"
    m, h = r[k], r["ci"].get(k, float("nan"))
    return f"{m:.{d}f} ± {h:.{d}f}" if np.isfinite(h) else f"{m:.{d}f}"


def table(rows, extra=()):
    head = "| run | seeds | diverged | fixes | 3D pos RMS (m) | 3D pos max (m) | 3D vel RMS (m/s) | " \
           "3D vel max (m/s) | pos RMS / max, non-diverged seeds (m) " + "".join(f"| {h} " for h, _ in extra) + "|"
    lines = [head, "|" + "---|" * (9 + len(extra))]
    for r in rows:
        okr = r["ok"]
        ok_txt = "-" if not np.isfinite(okr["pos_rms"][0]) else \
            f"{okr['pos_rms'][0]:.2f} / {okr['pos_max'][0]:.2f}"
        cells = [label(r["run"]), str(r["n_seeds"]),
                 f"{r['n_diverged']}/{r['n_seeds']} ({100.0 * r['n_diverged'] / max(r['n_seeds'], 1):.0f} %)",
                 f"{r['n_fixes']:.0f} ({100 * r['availability']:.0f} %)",
                 pm(r, "pos_rms"), pm(r, "pos_max"), pm(r, "vel_rms"), pm(r, "vel_max"), ok_txt]
        cells += [fmt(r) for _, fmt in extra]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def per_seed_table(rows, keys=(("pos_rms", "3D pos RMS (m)", 1), ("pos_max", "3D pos max (m)", 1),
                               ("vel_max", "3D vel max (m/s)", 1))):
    """Per-seed values of the main metrics (D: the seed diverged)."""
    if not rows:
        return []
    seeds = rows[0]["seeds"]
    lines = ["| run | metric | " + " | ".join(f"seed {s}" for s in seeds) + " |",
             "|---|---|" + "---|" * len(seeds)]
    for r in rows:
        for k, name, d in keys:
            vals = [f"{v:.{d}f}" + (" D" if dv else "") for v, dv in zip(r["per_seed"][k], r["per_seed"]["diverged"])]
            lines.append(f"| {label(r['run'])} | {name} | " + " | ".join(vals) + " |")
    return lines


def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, (np.floating, float)):
        return None if not np.isfinite(o) else float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o


def save_h5(path, everything):
    """Per-seed metrics of every run (datasets over the seeds) and the time series of the plotted seed."""
    import h5py
    with h5py.File(path, "w") as f:
        for exp, (res, rows, seed_rows, plot_seed) in everything.items():
            g = f.create_group(exp)
            g.attrs["plotted_seed"] = plot_seed
            for row in rows:
                rg = g.create_group(row["run"])
                rg["seeds"] = np.array(row["seeds"])
                for k, v in row["per_seed"].items():
                    rg[f"per_seed/{k}"] = np.array(v, dtype=float)
                for k in NUMERIC:
                    rg.attrs[f"{k}_mean"] = row[k]
                    rg.attrs[f"{k}_ci95"] = row["ci"][k]
                rg.attrs["n_diverged"] = row["n_diverged"]
                e = res.get(row["run"], {}).get("nav")
                if e is not None:
                    for k in ("t", "pos_err", "vel_err", "ecef_err", "mode", "n_sats"):
                        rg.create_dataset(f"plotted_seed/{k}", data=e[k], compression="gzip")
                for prn, c in res.get(row["run"], {}).get("chan", {}).items():
                    for k in ("t", "freq_err", "code_err", "visible"):
                        rg.create_dataset(f"plotted_seed/channels/G{prn:02d}/{k}", data=c[k], compression="gzip")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(ROOT, "figures", "vector"))
    ap.add_argument("--data", default=os.path.join(ROOT, "out", "vector"))
    ap.add_argument("--quick", action="store_true", help="shortened scenarios (fig8 90 s, accel 45 s)")
    ap.add_argument("--only", choices=("fig8", "accel", "tokyo"), help="run one experiment")
    ap.add_argument("--seeds", type=int, default=None,
                    help="number of simulator seeds per experiment (default: the batch file's five)")
    ap.add_argument("--duration", type=float, default=None, help="seconds of signal (overrides --quick)")
    ap.add_argument("--variants", default=None, help="comma-separated subset of the batch variants")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                    help="receiver override for every run of the batch experiments")
    ap.add_argument("--reuse-runs", action="store_true", help="tokyo: reuse its run files (the batch "
                                                              "experiments are always cached by content hash)")
    ap.add_argument("--jobs", "-j", type=int, default=min(2, os.cpu_count() or 1),
                    help="receiver runs in parallel (default: 2; wall times per run grow when they share cores)")
    args = ap.parse_args(argv)
    os.chdir(ROOT)
    os.makedirs(args.out, exist_ok=True)
    os.makedirs(args.data, exist_ok=True)
    log = lambda msg: print(msg, flush=True)          # noqa: E731
    everything, md, claims = {}, [], []
    rate = 10.0
    md += ["# Vector tracking: paper reproductions", "",
           f"Generated by `scripts/figures/figures_vector.py{' --quick' if args.quick else ''}` "
           f"({time.strftime('%Y-%m-%d %H:%M')}).  Errors are against the simulator truth, over the "
           "vector phase (and the same span for the scalar receiver); RMS / max over the 10 Hz fixes.", ""]
    for exp in (FIG8, ACCEL):
        if args.only and exp["name"] != args.only:
            continue
        log(f"{exp['name']}:")
        per_seed, t_end = run_experiment(exp, args, log)
        if not per_seed:
            log(f"  {exp['name']}: no successful run")
            continue
        carrier_prns = [24, 26] if exp is FIG8 else [12, 30]
        seed_rows, first = [], None
        for seed, (truth, runs_h5) in sorted(per_seed.items()):
            tr_s = load_truth(truth)
            res_s = analyse(exp, runs_h5, tr_s, carrier_prns, t_end, 1)
            for r in summarise(exp, res_s, tr_s, t_end, rate):
                r["seed"] = seed
                r["diverged"] = bool(not r["code_err_max_chips"] < DIVERGED_CODE_CHIPS)
                r["lock_kept"] = bool(r["freq_err_max_hz"] < FREQ_LOCK_HZ and
                                      r["code_err_max_chips"] < CODE_LOCK_CHIPS)
                seed_rows.append(r)
            if first is None:
                first = (res_s, tr_s, seed)          # the figures show the first seed
        res, tr, plot_seed = first
        order = [v for v in LABEL_ORDER[exp["name"]] if any(r["run"] == v for r in seed_rows)]
        rows = aggregate(seed_rows, order)
        everything[exp["name"]] = (res, rows, seed_rows, plot_seed)
        by = {r["run"]: r for r in rows}
        if exp is FIG8:
            plot_fig8(res, tr, args.out, t_end)
            md += [f"## Adaptive VLL: figure-eight at 50 m/s with blockage ({t_end:g} s, vector from "
                   f"{FIG8['t_vector']:g} s)", "",
                   f"{SEEDS_NOTE} Seeds {', '.join(str(x) for x in rows[0]['seeds'])} "
                   f"(configs/batch/figures_vector_fig8.yaml).", "",
                   "Fixes counted over t >= 45 s (availability = fixes / expected 10 Hz epochs); 'fixes < 4 sats' "
                   "= fixes while fewer than four satellites carried a signal.  Lock columns: largest "
                   "|NCO - true Doppler| and |code error| over the channels while their satellite was visible.", ""]
            md += table(rows, [("fixes < 4 sats", lambda r: f"{r['fixes_lt4']:.0f}"),
                               ("max pos err < 4 sats (m)", lambda r: pm(r, "pos_max_lt4", 1)),
                               ("max vel err, >= 3 sats for 2 s / within 2 s of a 2-sat period (m/s)",
                                lambda r: f"{r['vel_max_ge3']:.1f} / {r['vel_max_2']:.1f}"),
                               ("max freq err (Hz)", lambda r: pm(r, "freq_err_max_hz", 0)),
                               ("max code err (chips)", lambda r: pm(r, "code_err_max_chips", 2))])
            md += ["", f"Per seed (figures: seed {plot_seed}; D = diverged):", ""] + per_seed_table(rows)
            md += ["", "Notes.  The paper's settings (every channel updates, R = 1500 m^2 / 900 (m/s)^2, N = 500, "
                   "paper form of the adaptive R, constant-velocity state) are used for fixed_r and adaptive_r.  "
                   "'+ C/N0 mask + 3-sigma gate' additionally keeps channels under 32 dB-Hz (M2M4, 200 ms) out "
                   "of the update and skips innovations beyond 3 sigma (vector.cn0_mask_dbhz, "
                   "vector.innovation_gate_sigma; not in the paper).  'acceleration state' runs the same loops "
                   "with vector.motion_model: ca (an acceleration per axis, white-jerk PSD vector.q_jerk = 1 "
                   "m^2/s^5; not in the paper).", "",
                   "Why the paper's loop misses the 5 m/s bound: (1) while only two satellites carry a signal "
                   "(73-75, 140-142, 195-197 s; their lines of sight are nearly opposite in azimuth, e.g. G14 at "
                   "48 deg and G29 at 254 deg) the horizontal velocity across them is unobserved, and a "
                   "constant-velocity state lets its error grow with the car's centripetal acceleration (up to "
                   "4.2 m/s^2); the acceleration state predicts the turn instead.  (2) When a satellite is "
                   "blocked, its R estimate over N = 500 epochs needs ~0.5 s to rise from ~250 to ~12000 "
                   "(m/s)^2 (the variance of a frequency discriminator on noise), and the noise enters the "
                   "velocity meanwhile (the peaks at 142 s and 184 s, where G17 / G01 are blocked as the others "
                   "return); the C/N0 mask and the gate keep it out.  Each measure alone leaves a peak above "
                   "5 m/s: mask + gate without the acceleration state "
                   f"{by.get('adaptive_r_robust', {}).get('vel_max', np.nan):.1f} m/s, the acceleration state "
                   f"without mask and gate {by.get('adaptive_r_ca_only', {}).get('vel_max', np.nan):.1f} m/s; "
                   f"both: {by.get('adaptive_r_ca', {}).get('vel_max', np.nan):.1f} m/s.", ""]
            a = by.get("adaptive_r", {})
            f_ = by.get("fixed_r", {})
            s_ = by.get("scalar", {})
            am = by.get("adaptive_r_robust", {})
            ac = by.get("adaptive_r_ca", {})
            fc = by.get("fixed_r_ca", {})
            claims += [
                {"figure": "fig8_position_error.png", "claim": "scalar positioning fails after 58 s",
                 "measured": f"scalar availability {100 * s_.get('availability', 0):.0f} % of the 10 Hz epochs "
                             f"after 45 s, {s_.get('fixes_lt4', 0):.1f} fixes with < 4 satellites (mean over seeds)",
                 "status": "reproduced" if s_.get("fixes_lt4", 1) == 0 else "partly"},
                {"figure": "fig8_position_error.png",
                 "claim": "adaptive VLL within 220 m 3D (acceptance: <= 50 m), beats fixed R",
                 "measured": f"means over {a.get('n_seeds', 0)} seeds: adaptive {a.get('pos_max', np.nan):.1f} m "
                             f"max / {a.get('pos_rms', np.nan):.1f} m RMS ({a.get('n_diverged', 0)} diverged); "
                             f"fixed R {f_.get('pos_max', np.nan):.1f} m max / "
                             f"{f_.get('pos_rms', np.nan):.1f} m RMS ({f_.get('n_diverged', 0)}/"
                             f"{f_.get('n_seeds', 0)} seeds diverged); with the acceleration state + mask + gate "
                             f"adaptive {ac.get('pos_max', np.nan):.1f} m max, fixed R "
                             f"{fc.get('pos_max', np.nan):.1f} m max",
                 "status": "reproduced" if a.get("pos_max", 1e9) <= 50 and
                 a.get("pos_rms", 1e9) < f_.get("pos_rms", 0) else "partly"},
                {"figure": "fig8_velocity_error.png",
                 "claim": "adaptive VLL within 30 m/s (acceptance: <= 5 m/s), beats fixed R",
                 "measured": f"paper's loop: adaptive {a.get('vel_max', np.nan):.1f} m/s max / "
                             f"{a.get('vel_rms', np.nan):.2f} RMS, fixed R {f_.get('vel_max', np.nan):.1f} m/s max, "
                             f"adaptive + mask + gate {am.get('vel_max', np.nan):.1f} m/s max; with the "
                             f"acceleration state + mask + gate: adaptive {ac.get('vel_max', np.nan):.1f} m/s max / "
                             f"{ac.get('vel_rms', np.nan):.2f} RMS, fixed R {fc.get('vel_max', np.nan):.1f} m/s max",
                 "status": "reproduced" if a.get("vel_max", 1e9) <= 5 else
                 ("reproduced with the acceleration state + mask + gate; the paper's 8-state loop meets the "
                  "paper's 30 m/s only" if ac.get("vel_max", 1e9) <= 5 and a.get("vel_max", 1e9) <= 30 else
                  ("paper's bound reproduced, acceptance not met" if a.get("vel_max", 1e9) <= 30 else
                   "not reproduced"))},
            ]
        else:
            plot_accel(res, tr, args.out, t_end)
            md += [f"## Polynomial VDFLL: 3-axis acceleration steps ({t_end:g} s, vector from "
                   f"{ACCEL['t_vector']:g} s, scored from {ACCEL['window']:g} s)", "",
                   f"{SEEDS_NOTE} Seeds {', '.join(str(x) for x in rows[0]['seeds'])} "
                   f"(configs/batch/figures_vector_accel.yaml).", "",
                   f"'lock kept' = every channel within {FREQ_LOCK_HZ:g} Hz and {CODE_LOCK_CHIPS:g} chip of the "
                   "truth at every epoch.", ""]

            def lock(r):
                return (f"{r['n_lock_kept']}/{r['n_seeds']} ({pm(r, 'freq_err_max_hz', 0)} Hz, "
                        f"{pm(r, 'code_err_max_chips', 2)} ch)")

            md += table(rows, [("lock kept in seeds (max freq / code err)", lock)])
            md += ["", f"Per seed (figures: seed {plot_seed}; D = diverged):", ""]
            md += per_seed_table(rows, (("vel_rms", "3D vel RMS (m/s)", 2), ("pos_rms", "3D pos RMS (m)", 1)))
            md += ["", "Settings: the paper's are the CV model at sigma_v^2 = 10, 0.1, 1e-3, 1e-5 and the "
                   "18-state polynomial predictor with chi-square thresholds 20 / 25 / 30; ours are the "
                   "scenario (8 satellites, 45 dB-Hz, 2.5 MS/s, our acceleration profile), the handover time "
                   "and the loop's R (the receiver defaults).", ""]
            cv_best = min((r for r in rows if r["run"].startswith("cv_")), key=lambda r: r["vel_rms"])
            p25 = by.get("poly_25", {})
            ok_lock = bool(p25) and p25["n_lock_kept"] == p25["n_seeds"]
            claims += [
                {"figure": "accel_poly_vs_cv.png",
                 "claim": "polynomial VDFLL velocity error <= the best CV setting",
                 "measured": f"polynomial (25) {pm(p25, 'vel_rms')} m/s RMS vs best CV "
                             f"({label(cv_best['run'])}) {pm(cv_best, 'vel_rms')} m/s (mean ± 95 % over "
                             f"{p25.get('n_seeds', 0)} seeds)",
                 "status": "reproduced" if p25.get("vel_rms", 1e9) <= cv_best["vel_rms"] else "not reproduced"},
                {"figure": "accel_chi2_x_error.png", "claim": "no loss of lock at any step (threshold 25)",
                 "measured": f"lock kept in {p25.get('n_lock_kept', 0)}/{p25.get('n_seeds', 0)} seeds; max "
                             f"|freq err| {p25.get('freq_err_max_hz', np.nan):.0f} Hz, max |code err| "
                             f"{p25.get('code_err_max_chips', np.nan):.2f} chip (means over the seeds)",
                 "status": "reproduced" if ok_lock else "not reproduced"},
            ]
        walls = [(r["run"], r["wall_s"]) for r in rows if np.isfinite(r["wall_s"])]
        if walls:
            md += ["Wall-clock time per run (whole run, scalar part included; "
                   f"{args.jobs} run{'s' if args.jobs > 1 else ''} at a time): " +
                   ", ".join(f"{label(n)} {w:.0f} s" for n, w in walls) + f" for {t_end:g} s of signal.", ""]
    if not args.only or args.only == "tokyo":
        log("tokyo:")
        rows = tokyo(args.data, args.quick, args.reuse_runs, log)
        if rows:
            md += ["## Third-party recording (GPS-SDR-SIM, static, Tokyo): vector loop from 36 s", "",
                   "configs/vector_tokyo.yaml: assisted mode (broadcast ephemeris from brdc0010.22n), scalar "
                   "tracking until 36 s, then the vector loop to the end of the file (43.9 s).  The file's "
                   "oscillator error is on the carrier only: the carrier drift stays at ~150 m/s while the code "
                   "clock does not drift, which the code-minus-carrier drift state absorbs.", "",
                   "| variant | vector fixes | 3D RMS (m) | 3D max (m) | vel RMS (m/s) | vel max (m/s) | "
                   "channels kept | min n_sats | carrier drift (m/s) | clock bias span (m) |",
                   "|---|---|---|---|---|---|---|---|---|---|"]
            for r in rows:
                md.append(f"| {r['run']} | {r['n_fixes']} | {r['pos_rms']:.2f} | {r['pos_max']:.2f} | "
                          f"{r['vel_rms']:.2f} | {r['vel_max']:.2f} | {r['kept']} / {r['total']} | "
                          f"{r['n_sats_min']} | {r['drift']:.1f} | {r['bias_span']:.1f} |")
            md.append("")
            ok = all(r["pos_rms"] <= 5.0 and r["kept"] == r["total"] for r in rows)
            claims.append({"figure": "vector_results.md (third-party recording)",
                           "claim": "each variant from 36 s keeps all channels, 3D RMS <= 5 m (acceptance)",
                           "measured": ", ".join(f"{r['run']} {r['pos_rms']:.2f} m ({r['kept']}/{r['total']} ch)"
                                                 for r in rows),
                           "status": "reproduced" if ok else "not met"})
    save_h5(os.path.join(args.out, "vector_results.h5"), everything)
    with open(os.path.join(args.out, "vector_results.md"), "w") as fh:
        fh.write("\n".join(md) + "\n")
    with open(os.path.join(args.out, "vector_results.json"), "w") as fh:
        json.dump(_jsonable({k: {"rows": v[1], "per_seed_rows": v[2], "plotted_seed": v[3]}
                             for k, v in everything.items()}), fh, indent=1)
    with open(os.path.join(args.out, "claims.json"), "w") as fh:
        json.dump({"title": "vector tracking (adaptive VLL, polynomial VDFLL)", "claims": claims}, fh, indent=1)
    log("\n".join(md))


if __name__ == "__main__":
    main()
