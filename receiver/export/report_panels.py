"""The panels of the run report (receiver.export.report): figure layout, header, C/N0 and Doppler, sky plot,
lock status, position / velocity / horizontal scatter / satellites and DOP / clock over the fixes, the vector
loop's diagnostics.  Each panel function draws on the axes it is given, in the order make_figure calls
them."""
from __future__ import annotations

import os

import numpy as np

from ..gnss.geodesy import ecef2lla, enu_matrix
from ..gnss.satid import sat_label
from ..runfile.record import STATE_BIT_SYNC, STATE_LOST, STATE_PULL_IN, STATE_TRACK
from ..runfile.truth import truth_at

STATE_COLORS = {STATE_PULL_IN: "#f4a340", STATE_TRACK: "#8fb8de", STATE_BIT_SYNC: "#4daf4a",
                STATE_LOST: "#d62728"}


STATE_LABELS = {STATE_PULL_IN: "pull-in (FLL)", STATE_TRACK: "PLL, no bit sync",
                STATE_BIT_SYNC: "PLL, bit sync", STATE_LOST: "lost"}
VECTOR_COLOR = "#c9b3e6"


def _broken(t, y, gap):
    """Insert NaN rows where gap is True so that lines are not drawn across gaps."""
    if not np.any(gap):
        return t, y
    idx = np.nonzero(gap)[0]
    return np.insert(t, idx, np.nan), np.insert(np.asarray(y, float), idx, np.nan)


def prn_colors(prns):
    """{prn: colour} (tab10, tab20 for more than 10 satellites)."""
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


def layout(plt, rows):
    """(figure, grid spec, {panel name: axes}) of a report with ``rows`` rows (6 with the vector panels,
    whose axes are added by :func:`vector_panels`)."""
    fig = plt.figure(figsize=(17, 4.2 * rows), dpi=100)
    gs = fig.add_gridspec(rows, 3, width_ratios=[1, 1, 0.82], height_ratios=[1] * rows,
                          hspace=0.38, wspace=0.36, left=0.05, right=0.955, top=1.0 - 0.065 * 5 / rows,
                          bottom=0.035 * 5 / rows)
    ax = {"cn0": fig.add_subplot(gs[0, :2])}
    ax["sky"] = fig.add_subplot(gs[0, 2], projection="polar")
    ax["dop"] = fig.add_subplot(gs[1, :2], sharex=ax["cn0"])
    ax["hz"] = fig.add_subplot(gs[1, 2])
    ax["lock"] = fig.add_subplot(gs[2, :2], sharex=ax["cn0"])
    ax["txt"] = fig.add_subplot(gs[2, 2])
    ax["pos"] = fig.add_subplot(gs[3, :2])             # over the fixes' span, not the file's (set below)
    ax["sat"] = fig.add_subplot(gs[3, 2])
    ax["vel"] = fig.add_subplot(gs[4, :2], sharex=ax["pos"])
    ax["clk"] = fig.add_subplot(gs[4, 2])
    return fig, gs, ax


def header(fig, run, truth):
    """Title line and the run's provenance line."""
    name = os.path.basename(run.path)
    mode_txt = "assisted" if run.assisted else "autonomous"
    fig.suptitle(f"gnssrx run report: {name}", fontsize=16, fontweight="bold", x=0.05, y=0.988, ha="left")
    fig.text(0.05, 0.962, f"gnssrx {run.attrs.get('gnssrx_version', '?')}  |  created "
             f"{run.attrs.get('created_utc', '?')}  |  input {os.path.basename(str(run.attrs.get('input_path', '?')))}"
             f"  |  {mode_txt} navigation  |  truth: {'yes' if truth is not None else 'none'}",
             fontsize=10, color="#444444")


def cn0_doppler_panels(ax, channels, prns, colors, system, stats, t_end):
    """C/N0 and Doppler per channel."""
    ax_cn0, ax_dop = ax["cn0"], ax["dop"]
    for p in prns:
        ch = channels.get(p)
        if ch is None:
            continue
        ax_cn0.plot(*_broken(ch["time_s"], ch["cn0"], ch["gap"]), lw=0.9, color=colors[p],
                    label=sat_label(p, system))
        ax_dop.plot(*_broken(ch["time_s"], ch["doppler"] / 1e3, ch["gap"]), lw=1.2, color=colors[p],
                    label=sat_label(p, system))
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


def sky_panel(ax_sky, obs, colors, system):
    """Sky plot of the satellites' tracks from the fixes' observables (filled: used at the end)."""
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
    _sky_labels(ax_sky, ends, lambda p: sat_label(p, system), colors)
    ax_sky.plot([], [], "o", color="gray", label="used")
    ax_sky.plot([], [], "o", color="gray", mfc="white", label="not used")
    ax_sky.legend(loc="lower left", bbox_to_anchor=(-0.12, -0.12), fontsize=8, framealpha=0.85)


def lock_panel(ax_lock, channels, prns, obs, colors, system):
    """Lock status per channel: tracking state bars, PLL-unlocked hatching, used-in-fix lines."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch
    ylabels = []
    for row, p in enumerate(prns):
        ch = channels.get(p)
        ylabels.append(sat_label(p, system))
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


def _enu_deviation(f, truth):
    """(position, velocity) of the fixes f in the local ENU frame: errors against the truth, else the
    deviation from the mean position and the velocity itself."""
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
    return (f["ecef"] - tp) @ rot.T, (f["velocity_ecef"] - tv) @ rot.T


def fix_panels(ax, fx, truth, stats, t_end):
    """The panels over the fixes' span: position and velocity (ENU), horizontal scatter, satellites and
    DOP, receiver clock ("no fixes" without any)."""
    ok = np.all(np.isfinite(fx["ecef"]), axis=1) if len(fx) else np.zeros(0, bool)
    f = fx[ok]
    ax_pos, ax_vel = ax["pos"], ax["vel"]
    if len(f):
        denu, venu = _enu_deviation(f, truth)
        _pos_vel_panels(ax_pos, ax_vel, f, denu, venu, truth, stats)
        _horizontal_panel(ax["hz"], f["mode"], denu, truth, stats)
        _sats_panel(ax["sat"], f)
        _clock_panel(ax["clk"], f)
    else:
        for a in (ax_pos, ax_vel, ax["hz"], ax["sat"], ax["clk"]):
            a.text(0.5, 0.5, "no fixes", transform=a.transAxes, ha="center", va="center", fontsize=14,
                   color="gray")
        ax_pos.set_title("position")
        ax_vel.set_title("velocity")
    ax_pos.set_ylabel("m")
    ax_vel.set_ylabel("m/s")
    ax_vel.set_xlabel("time since the first sample of the file (s)")
    if not len(f) and t_end:
        ax_pos.set_xlim(stats["t0_s"], t_end)
    for a in (ax_pos, ax_vel):
        a.grid(alpha=0.3)
        if len(f):
            a.legend(ncol=4, fontsize=8, loc="lower right", framealpha=0.85)
        a.axhline(0, color="k", lw=0.6)
    if len(f):
        _robust_ylim(ax_pos, denu)
        _robust_ylim(ax_vel, venu)
    for a in (ax["cn0"], ax["dop"], ax["lock"], ax_pos):
        a.tick_params(labelbottom=True)


def _pos_vel_panels(ax_pos, ax_vel, f, denu, venu, truth, stats):
    """Position and velocity (ENU) over time, vector-mode periods shaded."""
    t, mode = f["time_s"], f["mode"]
    enu_cols = (("E", "#1f77b4"), ("N", "#ff7f0e"), ("U", "#2ca02c"))
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


def _horizontal_panel(ax_hz, mode, denu, truth, stats):
    """Horizontal scatter of the fixes (scalar / vector mode)."""
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


def _sats_panel(ax_sat, f):
    """Satellites used and PDOP / HDOP."""
    t = f["time_s"]
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
    _shade_vector(ax_sat, t, f["mode"], label=False)


def _clock_panel(ax_clk, f):
    """Receiver clock drift and bias."""
    t = f["time_s"]
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


def vector_panels(fig, gs, ax, vlog, prns, colors, system):
    """Vector loop: each channel's carrier R and the filter's standard deviations (the sixth row)."""
    ax_vr = fig.add_subplot(gs[5, :2], sharex=ax["cn0"])
    ax_vs = fig.add_subplot(gs[5, 2])
    tv = vlog["time_s"]
    for prn in prns:
        if 1 <= prn <= 32:
            r = vlog["r_carrier_m2s2"][:, prn - 1]
            if np.isfinite(r).any():
                ax_vr.plot(tv, r, lw=0.9, color=colors[prn], label=sat_label(prn, system))
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
    ax["vel"].tick_params(labelbottom=True)


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
