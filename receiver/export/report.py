"""One-page PNG report of a run (matplotlib, Agg backend).

Panels: C/N0 per channel, sky plot (labels placed clear of each other), Doppler per channel (with a legend),
horizontal scatter, lock status per channel (tracking state, PLL lock, satellite used in the fix), a summary
table, position and velocity over the span of the fixes (not the whole file) in the local East/North/Up frame
(errors against a truth file when one is given, else deviations from the mean position / the velocity
itself), satellites used and DOP, and the receiver clock.  Periods in vector-tracking mode
(``/navigation/mode`` = 1) are shaded in the time panels.

Channel records are reduced to at most ``MAX_POINTS`` time bins per channel (mean C/N0 and Doppler, the
lock state), one channel at a time.

One module for the report: its panels share the run's arrays and the layout.
"""
from __future__ import annotations

import os

import numpy as np

from ..gnss.satid import sat_label

from ..gnss.geodesy import ecef2lla, enu_matrix
from ..runfile.record import STATE_BIT_SYNC, STATE_LOST, STATE_PULL_IN, STATE_TRACK
from ..runfile.reader import RunData, RunFile, load_run
from ..runfile.truth import load_truth, truth_at

MAX_POINTS = 3000
STATE_COLORS = {STATE_PULL_IN: "#f4a340", STATE_TRACK: "#8fb8de", STATE_BIT_SYNC: "#4daf4a",
                STATE_LOST: "#d62728"}
STATE_LABELS = {STATE_PULL_IN: "pull-in (FLL)", STATE_TRACK: "PLL, no bit sync",
                STATE_BIT_SYNC: "PLL, bit sync", STATE_LOST: "lost"}
VECTOR_COLOR = "#c9b3e6"


# -------------------------------------------------------------------------------------------------- data
def read_vector_log(path, max_points: int = MAX_POINTS):
    """The /vector diagnostics (time_s, r_carrier_m2s2, sigma_pos_m, sigma_vel_mps), at most ``max_points``
    rows (every k-th), or None when the run has none."""
    with RunFile(path) as rf:
        n = rf.length("vector")
        if not n:
            return None
        step = max(1, -(-n // max_points))
        return rf.vector_log(("time_s", "r_carrier_m2s2", "sigma_pos_m", "sigma_vel_mps"), step)


def read_channels(path, max_points: int = MAX_POINTS) -> dict:
    """prn -> dict(time_s, t_end, cn0, doppler, state, unlocked, gap) in at most ``max_points`` time bins.

    Per bin (equal time bins over the channel's span; empty bins are dropped): first and last record time,
    mean C/N0 and Doppler, the state of the last record (``lost`` when any record is lost), ``unlocked`` =
    fraction of records without PLL lock; ``gap`` marks bins that follow a gap in the records (the channel
    was dropped and re-acquired).  One channel's columns are read at a time."""
    out = {}
    with RunFile(path) as rf:
        for name in rf.channel_names():
            g = rf.channel(name, ("time_s", "cn0_dbhz", "doppler_hz", "state", "pll_lock"))
            if "time_s" not in g or g["time_s"].shape[0] == 0:
                continue
            t = g["time_s"]
            n = len(t)
            span = float(t[-1] - t[0])
            nbins = max(1, min(max_points, n))
            width = span / nbins if span > 0 else 1.0
            b = np.minimum(((t - t[0]) / width).astype(np.int64), nbins - 1)
            starts = np.nonzero(np.concatenate([[True], b[1:] != b[:-1]]))[0]
            ends = np.append(starts[1:], n) - 1
            counts = (ends - starts + 1).astype(float)

            def mean(col):
                if col not in g:
                    return np.full(len(starts), np.nan)
                x = g[col].astype(float)
                return np.add.reduceat(x, starts) / counts

            ch = {"time_s": t[starts], "t_end": t[ends], "cn0": mean("cn0_dbhz"), "doppler": mean("doppler_hz")}
            if "state" in g:
                st = g["state"]
                lost = np.add.reduceat((st == STATE_LOST).astype(np.int64), starts) > 0
                ch["state"] = np.where(lost, STATE_LOST, st[ends]).astype(float)
            else:
                ch["state"] = np.full(len(starts), float(STATE_TRACK))
            ch["unlocked"] = (np.add.reduceat((g["pll_lock"] == 0).astype(float), starts) / counts
                              if "pll_lock" in g else np.zeros(len(starts)))
            ch["gap"] = _gaps(ch["time_s"], ch["t_end"], width)
            out[rf.channel_prn(name)] = ch
    return out


def _gaps(t0, t1, width):
    """True where a bin starts after a gap in the records (channel lost and re-acquired)."""
    if len(t0) < 2:
        return np.zeros(len(t0), bool)
    return np.concatenate([[False], (t0[1:] - t1[:-1]) > max(3.0 * width, 0.01)])


def _broken(t, y, gap):
    """Insert NaN rows where gap is True so that lines are not drawn across gaps."""
    if not np.any(gap):
        return t, y
    idx = np.nonzero(gap)[0]
    return np.insert(t, idx, np.nan), np.insert(np.asarray(y, float), idx, np.nan)


def _prn_colors(prns):
    import matplotlib
    cmap = matplotlib.colormaps["tab20"] if len(prns) > 10 else matplotlib.colormaps["tab10"]
    return {p: cmap(i % cmap.N) for i, p in enumerate(sorted(prns))}


def _runs(mask, breaks=None):
    """(start, end) index pairs of the True runs of a boolean array; a run also ends before every index
    where ``breaks`` is True."""
    mask = np.asarray(mask, bool)
    m = np.concatenate([[False], mask, [False]])
    d = np.diff(m.astype(int))
    runs = list(zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0] - 1))
    if breaks is None or not np.any(breaks):
        return runs
    cut = np.nonzero(breaks)[0]
    out = []
    for a, b in runs:
        for c in cut[(cut > a) & (cut <= b)]:
            out.append((a, c - 1))
            a = c
        out.append((a, b))
    return out


def _shade_vector(ax, t, mode, label=True):
    first = True
    for a, b in _runs(mode == 1):
        t0 = t[a]
        t1 = t[b] if b > a else t[a] + 0.05
        ax.axvspan(t0, t1, color=VECTOR_COLOR, alpha=0.45, lw=0,
                   label="vector mode" if (label and first) else None, zorder=0)
        first = False


# -------------------------------------------------------------------------------------------------- stats
def summary_stats(run: RunData, truth=None) -> dict:
    """Summary numbers of a run for the report's table: ``n_fixes``, ``duration_s`` and ``t0_s`` (the span
    read, s), and over the fixes with a finite position: ``ttff_s`` (first fix after the span start, s),
    ``mean_llh`` (deg, deg, m), ``scatter_enu_m`` (1-sigma about the mean), ``n_vector``, ``n_sats_mean``,
    ``pdop_mean``.  With a truth (:func:`load_truth`'s dict) also the errors in ENU at the truth:
    ``truth_n``, ``err_3d_rms_m``, ``err_h_rms_m``, ``err_v_rms_m``, ``err_mean_enu_m``, ``vel_3d_rms_mps``."""
    fx = run.fixes
    fs = float(run.attrs.get("sample_rate_hz", np.nan))
    first = float(run.attrs.get("first_sample", 0)) / fs if np.isfinite(fs) else 0.0
    s = {"n_fixes": int(len(fx)), "duration_s": float(run.attrs.get("n_samples", np.nan)) / fs,
         "t0_s": first}
    ok = np.all(np.isfinite(fx["ecef"]), axis=1) if len(fx) else np.zeros(0, bool)
    if ok.any():
        e = fx["ecef"][ok]
        s["ttff_s"] = float(fx["time_s"][ok][0] - first)
        mean = e.mean(axis=0)
        s["mean_llh"] = tuple(float(v) for v in ecef2lla(mean))
        lat, lon, _ = s["mean_llh"]
        rot = enu_matrix(lat, lon)
        s["scatter_enu_m"] = tuple(float(v) for v in ((e - mean) @ rot.T).std(axis=0))
        s["n_vector"] = int(np.count_nonzero(fx["mode"][ok] == 1))
        s["n_sats_mean"] = float(np.mean(fx["n_sats"][ok]))
        s["pdop_mean"] = float(np.nanmean(fx["pdop"][ok]))
        if truth is not None:
            tp, tv = truth_at(truth, fx["gps_week"][ok], fx["gps_tow"][ok])
            good = np.all(np.isfinite(tp), axis=1)
            if good.any():
                lat_t, lon_t, _ = ecef2lla(tp[good].mean(axis=0))
                rt = enu_matrix(lat_t, lon_t)
                err = (e[good] - tp[good]) @ rt.T
                d3 = np.linalg.norm(err, axis=1)
                s["truth_n"] = int(good.sum())
                s["err_3d_rms_m"] = float(np.sqrt(np.mean(d3 ** 2)))
                s["err_h_rms_m"] = float(np.sqrt(np.mean(err[:, 0] ** 2 + err[:, 1] ** 2)))
                s["err_v_rms_m"] = float(np.sqrt(np.mean(err[:, 2] ** 2)))
                s["err_mean_enu_m"] = tuple(float(v) for v in err.mean(axis=0))
                v = fx["velocity_ecef"][ok][good] - tv[good]
                v3 = np.linalg.norm(v, axis=1)
                v3 = v3[np.isfinite(v3)]
                if len(v3):
                    s["vel_3d_rms_mps"] = float(np.sqrt(np.mean(v3 ** 2)))
    return s


# -------------------------------------------------------------------------------------------------- figure
def make_figure(run: RunData, truth=None, channels=None):
    """The report as a matplotlib Figure (the panels of the module docstring), not saved.  ``truth``:
    :func:`load_truth`'s dict or None; ``channels``: :func:`read_channels` of the run (read from the run
    file when None).  Fills the missing azimuth/elevation of ``run.obs`` in place (:meth:`RunData.fill_azel`)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    if channels is None:
        channels = read_channels(run.path)
    run.fill_azel()
    fx, obs = run.fixes, run.obs
    prns = sorted(set(channels) | {int(p) for p in obs["prn"]})
    colors = _prn_colors(prns)
    stats = summary_stats(run, truth)

    vlog = read_vector_log(run.path)
    rows = 6 if vlog is not None else 5
    fig = plt.figure(figsize=(17, 4.2 * rows), dpi=100)
    gs = fig.add_gridspec(rows, 3, width_ratios=[1, 1, 0.82], height_ratios=[1] * rows,
                          hspace=0.38, wspace=0.36, left=0.05, right=0.955, top=1.0 - 0.065 * 5 / rows,
                          bottom=0.035 * 5 / rows)
    ax_cn0 = fig.add_subplot(gs[0, :2])
    ax_sky = fig.add_subplot(gs[0, 2], projection="polar")
    ax_dop = fig.add_subplot(gs[1, :2], sharex=ax_cn0)
    ax_hz = fig.add_subplot(gs[1, 2])
    ax_lock = fig.add_subplot(gs[2, :2], sharex=ax_cn0)
    ax_txt = fig.add_subplot(gs[2, 2])
    ax_pos = fig.add_subplot(gs[3, :2])             # over the fixes' span, not the file's (set below)
    ax_sat = fig.add_subplot(gs[3, 2])
    ax_vel = fig.add_subplot(gs[4, :2], sharex=ax_pos)
    ax_clk = fig.add_subplot(gs[4, 2])

    name = os.path.basename(run.path)
    mode_txt = "assisted" if run.assisted else "autonomous"
    fig.suptitle(f"gnssrx run report: {name}", fontsize=16, fontweight="bold", x=0.05, y=0.988, ha="left")
    fig.text(0.05, 0.962, f"gnssrx {run.attrs.get('gnssrx_version', '?')}  |  created "
             f"{run.attrs.get('created_utc', '?')}  |  input {os.path.basename(str(run.attrs.get('input_path', '?')))}"
             f"  |  {mode_txt} navigation  |  truth: {'yes' if truth is not None else 'none'}",
             fontsize=10, color="#444444")

    t_end = stats["t0_s"] + stats["duration_s"] if np.isfinite(stats.get("duration_s", np.nan)) else None

    # ---- C/N0 and Doppler
    for p in prns:
        ch = channels.get(p)
        if ch is None:
            continue
        ax_cn0.plot(*_broken(ch["time_s"], ch["cn0"], ch["gap"]), lw=0.9, color=colors[p],
                    label=sat_label(p, run.system))
        ax_dop.plot(*_broken(ch["time_s"], ch["doppler"] / 1e3, ch["gap"]), lw=1.2, color=colors[p],
                    label=sat_label(p, run.system))
    _cn0_ylim(ax_cn0, channels)
    ax_cn0.set_ylabel("C/N0 (dB-Hz)")
    ax_cn0.set_title("C/N0 per channel")
    ax_cn0.grid(alpha=0.3)
    if channels:
        ax_cn0.legend(ncol=min(len(channels), 8), fontsize=8, loc="lower right", framealpha=0.85)
    ax_dop.set_ylabel("Doppler (kHz)")
    ax_dop.set_title("carrier Doppler (NCO) per channel")
    ax_dop.grid(alpha=0.3)
    if channels:
        ax_dop.legend(ncol=min(len(channels), 6), fontsize=8, loc="best", framealpha=0.85)
    if t_end:
        ax_cn0.set_xlim(stats["t0_s"], t_end)

    # ---- sky plot
    ax_sky.set_theta_zero_location("N")
    ax_sky.set_theta_direction(-1)
    ax_sky.set_rlim(90, 0)
    ax_sky.set_rticks([0, 15, 30, 45, 60, 75])
    ax_sky.set_yticklabels(["0", "15", "30", "45", "60", "75"], fontsize=7)
    ax_sky.set_title("sky plot (from the fixes)", pad=18)
    ends = []
    for p in sorted({int(x) for x in obs["prn"]}):
        sel = (obs["prn"] == p) & np.isfinite(obs["elevation_deg"]) & np.isfinite(obs["azimuth_deg"])
        if not sel.any():
            continue
        az = np.radians(obs["azimuth_deg"][sel].astype(float))
        el = obs["elevation_deg"][sel].astype(float)
        used = obs["used_in_fix"][sel].astype(bool)
        ax_sky.plot(az, el, "-", color=colors.get(p, "k"), lw=2.5)
        ax_sky.plot(az[-1], el[-1], "o", ms=9, color=colors.get(p, "k"),
                    mfc=colors.get(p, "k") if used[-1] else "white", mew=1.8)
        ends.append((p, az[-1], el[-1]))
    _sky_labels(ax_sky, ends, lambda p: sat_label(p, run.system), colors)
    ax_sky.plot([], [], "o", color="gray", label="used")
    ax_sky.plot([], [], "o", color="gray", mfc="white", label="not used")
    ax_sky.legend(loc="lower left", bbox_to_anchor=(-0.12, -0.12), fontsize=8, framealpha=0.85)

    # ---- lock status
    ylabels = []
    for row, p in enumerate(prns):
        ch = channels.get(p)
        ylabels.append(sat_label(p, run.system))
        if ch is None:
            continue
        t0 = ch["time_s"]
        # a bin ends where the next one starts, unless the records have a gap there
        t1 = np.append(t0[1:], ch["t_end"][-1])
        gap_next = np.append(ch["gap"][1:], False)
        t1 = np.where(gap_next, ch["t_end"], t1)
        for st, col in STATE_COLORS.items():
            for a, b in _runs(ch["state"] == st, ch["gap"]):
                ax_lock.broken_barh([(t0[a], max(t1[b] - t0[a], 1e-3))], (row - 0.35, 0.5),
                                    facecolors=col, lw=0)
        for a, b in _runs(ch["unlocked"] > 0.5, ch["gap"]):
            ax_lock.broken_barh([(t0[a], max(t1[b] - t0[a], 1e-3))], (row - 0.35, 0.5),
                                facecolors="none", edgecolor="#555555", hatch="////", lw=0)
        sel = obs["prn"] == p
        if sel.any():
            tu = obs["time_s"][sel]
            uu = obs["used_in_fix"][sel].astype(bool)
            step = np.median(np.diff(np.unique(obs["time_s"]))) if len(np.unique(obs["time_s"])) > 1 else 0.1
            for a, b in _runs(uu):
                ax_lock.plot([tu[a], tu[b] + step], [row + 0.27, row + 0.27], color="black", lw=2.2,
                             solid_capstyle="butt")
    ax_lock.set_yticks(range(len(prns)))
    ax_lock.set_yticklabels(ylabels, fontsize=8)
    for tick, p in zip(ax_lock.get_yticklabels(), prns):
        tick.set_color(colors[p])
        tick.set_fontweight("bold")
    ax_lock.set_ylim(len(prns) - 0.4, -0.6)
    ax_lock.set_title("lock status per channel")
    handles = [Patch(facecolor=c, label=STATE_LABELS[s]) for s, c in STATE_COLORS.items()]
    handles.append(Patch(facecolor="white", edgecolor="#555555", hatch="////", label="PLL not locked"))
    handles.append(plt.Line2D([], [], color="black", lw=2.2, label="used in fix"))
    handles.append(Patch(facecolor="white", edgecolor="#bbbbbb", label="no channel"))
    ax_lock.legend(handles=handles, ncol=7, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.07),
                   frameon=False)
    ax_lock.grid(axis="x", alpha=0.3)

    # ---- position / velocity
    ok = np.all(np.isfinite(fx["ecef"]), axis=1) if len(fx) else np.zeros(0, bool)
    f = fx[ok]
    t = f["time_s"]
    mode = f["mode"]
    enu_cols = (("E", "#1f77b4"), ("N", "#ff7f0e"), ("U", "#2ca02c"))
    if len(f):
        if truth is not None:
            tp, tv = truth_at(truth, f["gps_week"], f["gps_tow"])
            good = np.all(np.isfinite(tp), axis=1)
            ref = tp[good].mean(axis=0) if good.any() else f["ecef"].mean(axis=0)
        else:
            tp = np.repeat(f["ecef"].mean(axis=0)[None], len(f), axis=0)
            tv = np.zeros((len(f), 3))
            ref = tp[0]
        lat, lon, _ = ecef2lla(ref)
        rot = enu_matrix(lat, lon)
        denu = (f["ecef"] - tp) @ rot.T
        venu = (f["velocity_ecef"] - tv) @ rot.T
        for k, (lab, col) in enumerate(enu_cols):
            ax_pos.plot(t, denu[:, k], ".-", ms=2.5, lw=0.8, color=col, label=lab)
            ax_vel.plot(t, venu[:, k], ".-", ms=2.5, lw=0.8, color=col, label=lab)
        _shade_vector(ax_pos, t, mode)
        _shade_vector(ax_vel, t, mode)
        what = "error vs truth" if truth is not None else "deviation from the mean position"
        ax_pos.set_title(f"position {what} (ENU)")
        pad = max(0.02 * (t[-1] - t[0]), 0.05)
        ax_pos.set_xlim(t[0] - pad, t[-1] + pad)
        ax_vel.set_title("velocity error vs truth (ENU)" if truth is not None else "velocity (ENU)")
        note = (f"{stats.get('n_vector', 0)} of {len(f)} fixes in vector mode" if stats.get("n_vector")
                else "all fixes in scalar mode")
        note += f"; fixes from {t[0]:.1f} to {t[-1]:.1f} s (the panels below span them)"
        ax_pos.text(0.005, 0.96, note, transform=ax_pos.transAxes, fontsize=8, va="top",
                    bbox=dict(facecolor="white", alpha=0.8, lw=0))

        # horizontal scatter
        for m, col in ((0, "#1f77b4"), (1, "#8e44ad")):
            sel = mode == m
            if sel.any():
                ax_hz.scatter(denu[sel, 0], denu[sel, 1], s=6, c=col, alpha=0.7, lw=0, zorder=2 + m)
        ax_hz.plot(0, 0, "k+", ms=14, mew=1.5)
        lim = float(np.nanmax(np.abs(denu[:, :2]))) * 1.15 if np.isfinite(denu[:, :2]).any() else 1.0
        lim = max(lim, 0.5)
        ax_hz.set_xlim(-lim, lim)
        ax_hz.set_ylim(-lim, lim)
        ax_hz.set_aspect("equal")
        ax_hz.set_xlabel("East (m)")
        ax_hz.set_ylabel("North (m)")
        ax_hz.set_title("horizontal " + ("error vs truth (+)" if truth is not None else "scatter about the mean (+)"))
        ax_hz.grid(alpha=0.3)
        ax_hz.scatter([], [], s=12, c="#1f77b4", label="scalar")
        if stats.get("n_vector"):
            ax_hz.scatter([], [], s=12, c="#8e44ad", label="vector")
        ax_hz.legend(fontsize=8, loc="upper right")

        # satellites / DOP
        ax_sat.step(t, f["n_sats"], where="post", color="black", lw=1.2, label="satellites used")
        ax_sat.set_ylim(0, max(12, int(np.max(f["n_sats"])) + 1))
        ax_sat.set_ylabel("satellites used")
        ax_sat.set_xlabel("time (s)")
        ax2 = ax_sat.twinx()
        ax2.plot(t, f["pdop"], color="#d62728", lw=1.0, label="PDOP")
        ax2.plot(t, f["hdop"], color="#9467bd", lw=1.0, label="HDOP")
        ax2.set_ylabel("DOP")
        ax2.set_ylim(0, max(3.0, float(np.nanmax(f["pdop"])) * 1.3) if np.isfinite(f["pdop"]).any() else 3.0)
        h1, l1 = ax_sat.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax_sat.legend(h1 + h2, l1 + l2, fontsize=8, loc="lower right")
        ax_sat.set_title("satellites and DOP")
        ax_sat.grid(alpha=0.3)
        _shade_vector(ax_sat, t, mode, label=False)

        # clock
        ax_clk.plot(t, f["clock_drift_mps"], color="#17becf", lw=1.0, label="drift (m/s)")
        ax_clk.set_ylabel("clock drift (m/s)")
        ax_clk.set_xlabel("time (s)")
        ax3 = ax_clk.twinx()
        ax3.plot(t, f["clock_bias_m"], color="#8c564b", lw=1.0, label="bias (m)")
        ax3.set_ylabel("clock bias (m)")
        for a in (ax_clk, ax3):
            a.ticklabel_format(axis="y", useOffset=False, style="plain")
        h1, l1 = ax_clk.get_legend_handles_labels()
        h2, l2 = ax3.get_legend_handles_labels()
        ax_clk.legend(h1 + h2, l1 + l2, fontsize=8, loc="best")
        ax_clk.set_title("receiver clock")
        ax_clk.grid(alpha=0.3)
    else:
        for ax in (ax_pos, ax_vel, ax_hz, ax_sat, ax_clk):
            ax.text(0.5, 0.5, "no fixes", transform=ax.transAxes, ha="center", va="center", fontsize=14,
                    color="gray")
        ax_pos.set_title("position")
        ax_vel.set_title("velocity")
    ax_pos.set_ylabel("m")
    ax_vel.set_ylabel("m/s")
    ax_vel.set_xlabel("time since the first sample of the file (s)")
    if not len(f) and t_end:
        ax_pos.set_xlim(stats["t0_s"], t_end)
    for ax in (ax_pos, ax_vel):
        ax.grid(alpha=0.3)
        if len(f):
            ax.legend(ncol=4, fontsize=8, loc="lower right", framealpha=0.85)
        ax.axhline(0, color="k", lw=0.6)
    if len(f):
        _robust_ylim(ax_pos, denu)
        _robust_ylim(ax_vel, venu)
    for ax in (ax_cn0, ax_dop, ax_lock, ax_pos):
        ax.tick_params(labelbottom=True)

    # ---- vector loop: each channel's carrier R and the filter's standard deviations
    if vlog is not None:
        ax_vr = fig.add_subplot(gs[5, :2], sharex=ax_cn0)
        ax_vs = fig.add_subplot(gs[5, 2])
        tv = vlog["time_s"]
        for prn in prns:
            if 1 <= prn <= 32:
                r = vlog["r_carrier_m2s2"][:, prn - 1]
                if np.isfinite(r).any():
                    ax_vr.plot(tv, r, lw=0.9, color=colors[prn], label=sat_label(prn, run.system))
        ax_vr.set_yscale("log")
        ax_vr.set_ylabel("(m/s)$^2$")
        ax_vr.set_xlabel("time since the first sample of the file (s)")
        ax_vr.set_title("vector loop: carrier-discriminator R per channel (adaptive R: grows as the signal fades)")
        ax_vr.grid(alpha=0.3, which="both")
        ax_vr.legend(ncol=8, fontsize=7, loc="upper left", framealpha=0.85)
        ax_vs.plot(tv, np.linalg.norm(vlog["sigma_pos_m"], axis=1), color="#1f77b4", lw=1.0,
                   label="3D position (m)")
        ax_vs.plot(tv, np.linalg.norm(vlog["sigma_vel_mps"], axis=1), color="#ff7f0e", lw=1.0,
                   label="3D velocity (m/s)")
        ax_vs.set_yscale("log")
        ax_vs.set_xlabel("time (s)")
        ax_vs.set_title("vector filter standard deviation")
        ax_vs.grid(alpha=0.3, which="both")
        ax_vs.legend(fontsize=8, loc="best")
        ax_vel.tick_params(labelbottom=True)

    # ---- summary text
    ax_txt.axis("off")
    ax_txt.set_title("summary", loc="left")
    ax_txt.text(0.0, 1.0, _summary_text(run, stats, channels), transform=ax_txt.transAxes, va="top",
                family="monospace", fontsize=9)
    return fig


def _sky_labels(ax, ends, label, colors):
    """Satellite labels beside their sky-plot markers where they overlap neither another label, a marker
    nor the azimuth labels outside the horizon: for each satellite (highest first) the first free one of a
    ring of offsets, pointing inwards near the horizon; a thin leader line when the label sits away."""
    fig = ax.figure
    fig.canvas.draw()                     # the polar transform and the text extents
    renderer = fig.canvas.get_renderer()
    px = fig.dpi / 72.0
    centre = ax.transData.transform((0.0, 90.0))
    marks = [ax.transData.transform((az, el)) for _, az, el in ends]
    taken = [(m[0] - 6 * px, m[1] - 6 * px, m[0] + 6 * px, m[1] + 6 * px) for m in marks]
    taken += [_box(t.get_window_extent(renderer)) for t in ax.get_xticklabels() if t.get_text()]
    ring = [(8, 6), (8, -14), (-8, 6), (-8, -14), (0, 11), (0, -19), (12, -4), (-12, -4),
            (16, 14), (-16, 14), (16, -22), (-16, -22), (0, 24), (0, -30)]
    for (p, az, el), m in sorted(zip(ends, marks), key=lambda e: -e[0][2]):
        txt = label(p)
        w = 0.62 * 9 * px * len(txt) + 2 * px
        h = 11 * px
        inward = np.asarray(centre) - np.asarray(m)
        order = sorted(ring, key=lambda o: -np.dot(o, inward)) if el < 20 else ring
        best = None
        for ox, oy in order:
            x0 = m[0] + ox * px - (w if ox < 0 else (w / 2 if ox == 0 else 0))
            y0 = m[1] + oy * px
            box = (x0, y0, x0 + w, y0 + h)
            if not any(_overlap(box, b) for b in taken):
                best = (ox, oy, box)
                break
        if best is None:
            ox, oy = ring[0]
            x0, y0 = m[0] + ox * px, m[1] + oy * px
            best = (ox, oy, (x0, y0, x0 + w, y0 + h))
        ox, oy, box = best
        taken.append(box)
        ha = "right" if ox < 0 else ("center" if ox == 0 else "left")
        far = abs(ox) > 10 or oy > 12 or oy < -20
        ax.annotate(txt, (az, el), textcoords="offset points", xytext=(ox, oy), fontsize=9, ha=ha, va="bottom",
                    color="black", arrowprops=dict(arrowstyle="-", lw=0.6, color=colors.get(p, "k")) if far else None)


def _box(bb):
    return (bb.x0, bb.y0, bb.x1, bb.y1)


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _cn0_ylim(ax, channels):
    vals = [c["cn0"][c["state"] == STATE_BIT_SYNC] for c in channels.values()]
    vals = np.concatenate(vals) if vals else np.zeros(0)
    vals = vals[np.isfinite(vals)]
    if vals.size:
        ax.set_ylim(max(0.0, float(np.min(vals)) - 8.0), float(np.max(vals)) + 4.0)


def _robust_ylim(ax, arr):
    a = np.asarray(arr, float)
    a = a[np.isfinite(a)]
    if not a.size:
        return
    lo, hi = np.percentile(a, [0.5, 99.5])
    span = max(hi - lo, 1e-3)
    ax.set_ylim(lo - 0.15 * span, hi + 0.15 * span)


def _summary_text(run: RunData, s: dict, channels) -> str:
    lines = []
    dur = s.get("duration_s")
    if dur is not None and np.isfinite(dur):
        lines.append(f"signal       {dur:.1f} s")
    wall = run.attrs.get("wall_time_s")
    if wall is not None:
        lines.append(f"processing   {float(wall):.1f} s")
    lines.append(f"channels     {len(channels)}")
    cn = {p: float(np.nanmean(c["cn0"][c["state"] == STATE_BIT_SYNC]))
          for p, c in channels.items() if np.any(c["state"] == STATE_BIT_SYNC)}
    if cn:
        items = [f"{sat_label(p, run.system)} {v:.1f}" for p, v in sorted(cn.items())]
        lines.append("C/N0 (dB-Hz, bit sync):")
        for i in range(0, len(items), 3):
            lines.append("  " + "  ".join(items[i:i + 3]))
    lines.append(f"fixes        {s['n_fixes']}"
                 + (f" ({s['n_vector']} vector)" if s.get("n_vector") else ""))
    if "ttff_s" in s:
        lat, lon, h = s["mean_llh"]
        lines += [f"first fix    {s['ttff_s']:.2f} s",
                  f"sats used    {s['n_sats_mean']:.1f} (mean)",
                  f"PDOP         {s['pdop_mean']:.2f} (mean)",
                  f"mean lat     {lat:.7f}", f"mean lon     {lon:.7f}", f"mean h       {h:.2f} m",
                  "scatter 1sd  E {:.2f} N {:.2f} U {:.2f} m".format(*s["scatter_enu_m"])]
    if "err_3d_rms_m" in s:
        lines += ["vs truth:",
                  f"  3D RMS     {s['err_3d_rms_m']:.2f} m",
                  f"  horiz RMS  {s['err_h_rms_m']:.2f} m",
                  f"  vert RMS   {s['err_v_rms_m']:.2f} m",
                  "  mean E {:.2f} N {:.2f} U {:.2f} m".format(*s["err_mean_enu_m"])]
        if "vel_3d_rms_mps" in s:
            lines.append(f"  vel 3D RMS {s['vel_3d_rms_mps']:.3f} m/s")
    return "\n".join(lines)


def write_report(run, path, truth=None) -> dict:
    """Write the PNG report.  run: RunData or a run file path; truth: None, a path or load_truth()'s dict."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    if not isinstance(run, RunData):
        run = load_run(run)
    if truth is not None and not isinstance(truth, dict):
        truth = load_truth(truth)
    fig = make_figure(run, truth)
    try:
        fig.savefig(path, dpi=100)
    finally:
        plt.close(fig)
    return {"fixes": int(len(run.fixes))}
