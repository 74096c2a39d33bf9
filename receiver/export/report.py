"""One-page PNG report of a run (matplotlib, Agg backend).

Panels: C/N0 per channel, sky plot (labels placed clear of each other), Doppler per channel (with a legend),
horizontal scatter, lock status per channel (tracking state, PLL lock, satellite used in the fix), a summary
table, position and velocity over the span of the fixes (not the whole file) in the local East/North/Up frame
(errors against a truth file when one is given, else deviations from the mean position / the velocity
itself), satellites used and DOP, and the receiver clock.  Periods in vector-tracking mode
(``/navigation/mode`` = 1) are shaded in the time panels.

Channel records are reduced to at most ``MAX_POINTS`` time bins per channel (mean C/N0 and Doppler, the
lock state), one channel at a time.

The run's data for the report (channel bins, statistics, summary text) and the figure's assembly are here;
the panels are drawn by receiver.export.report_panels.
"""
from __future__ import annotations

import numpy as np

from ..gnss.geodesy import ecef2lla, enu_matrix
from ..gnss.satid import sat_label
from ..runfile.reader import RunData, RunFile, load_run
from ..runfile.record import STATE_BIT_SYNC, STATE_LOST, STATE_TRACK
from ..runfile.truth import load_truth, truth_at
from .report_panels import (cn0_doppler_panels, fix_panels, header, layout, lock_panel, prn_colors, sky_panel,
                            vector_panels)

MAX_POINTS = 3000


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

    if channels is None:
        channels = read_channels(run.path)
    run.fill_azel()
    obs = run.obs
    prns = sorted(set(channels) | {int(p) for p in obs["prn"]})
    colors = prn_colors(prns)
    stats = summary_stats(run, truth)

    vlog = read_vector_log(run.path)
    fig, gs, ax = layout(plt, 6 if vlog is not None else 5)
    header(fig, run, truth)
    t_end = stats["t0_s"] + stats["duration_s"] if np.isfinite(stats.get("duration_s", np.nan)) else None
    cn0_doppler_panels(ax, channels, prns, colors, run.system, stats, t_end)
    sky_panel(ax["sky"], obs, colors, run.system)
    lock_panel(ax["lock"], channels, prns, obs, colors, run.system)
    fix_panels(ax, run.fixes, truth, stats, t_end)
    if vlog is not None:
        vector_panels(fig, gs, ax, vlog, prns, colors, run.system)
    # ---- summary text
    ax_txt = ax["txt"]
    ax_txt.axis("off")
    ax_txt.set_title("summary", loc="left")
    ax_txt.text(0.0, 1.0, _summary_text(run, stats, channels), transform=ax_txt.transAxes, va="top",
                family="monospace", fontsize=9)
    return fig


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
