"""``gnssrx info RUN.h5``: what is inside a run file (schema, counts, time span, fixes, config)."""
from __future__ import annotations

import os

import numpy as np

from ..gnss.satid import sat_label


def run_info(path) -> dict:
    """A JSON-friendly description of the run file."""
    from ..gnss.time import gps_datetime, week_seconds_since
    from ..runfile.reader import RunFile, load_run
    run = load_run(path)          # validates the file
    info: dict = {"file": os.path.abspath(run.path), "size_bytes": os.path.getsize(run.path)}
    a = run.attrs
    for k in ("schema", "gnssrx_version", "created_utc", "input_path", "sample_rate_hz", "if_hz",
              "first_sample", "n_samples", "wall_time_s", "realtime_factor", "command", "resample",
              "input_sample_rate_hz", "input_if_hz"):
        if k in a:
            v = a[k]
            info[k] = v.item() if isinstance(v, np.generic) else v
    fs = float(a.get("sample_rate_hz", np.nan))
    if "n_samples" in a and np.isfinite(fs) and fs > 0:
        info["duration_s"] = float(a["n_samples"]) / fs
    info["assisted"] = run.assisted
    info["system"] = run.system
    with RunFile(run.path) as rf:
        groups = {}
        for name, shape, dtype in rf.datasets():
            top = name.split("/")[0]
            groups.setdefault(top, 0)
            groups[top] += 1
        info["groups"] = groups
        facts = _channels_acquisition(rf)
        info["channels"] = facts["channels"]
        a_io = rf.iono_utc_attrs()
        if a_io is not None:
            info["iono_utc"] = {k: (np.asarray(a_io[k]).tolist() if k in ("alpha", "beta") else
                                    (a_io[k].item() if isinstance(a_io[k], np.generic) else a_io[k]))
                                for k in ("source", "alpha", "beta", "dt_ls") if k in a_io}
        if "acquisition" in facts:
            info["acquisition"] = facts["acquisition"]
    fx = run.fixes
    nav = {"fixes": int(len(fx))}
    if len(fx):
        ok = np.all(np.isfinite(fx["ecef"]), axis=1)
        w0, t0 = int(fx["gps_week"][0]), float(fx["gps_tow"][0])
        w1, t1 = int(fx["gps_week"][-1]), float(fx["gps_tow"][-1])
        nav.update({
            "first_fix": {"gps_week": w0, "gps_tow": t0, "gps_time": gps_datetime(w0, t0).isoformat(),
                          "utc": run.utc(w0, t0).isoformat(), "time_s": float(fx["time_s"][0])},
            "last_fix": {"gps_week": w1, "gps_tow": t1, "gps_time": gps_datetime(w1, t1).isoformat()},
            "span_s": float(week_seconds_since(w1, t1, w0) - t0),
            "rate_hz": (float(1.0 / np.median(np.diff(fx["time_s"]))) if len(fx) > 1 else None),
            "modes": {"scalar": int(np.count_nonzero(fx["mode"] == 0)),
                      "vector": int(np.count_nonzero(fx["mode"] == 1)),
                      "coast": int(np.count_nonzero(fx["mode"] == 2))},
            "n_sats_mean": float(np.mean(fx["n_sats"])),
            "pdop_mean": float(np.nanmean(fx["pdop"])),
        })
        # fixes per Klobuchar set (/navigation/iono_params; 'unknown': a file written before the column)
        from ..runfile.record import IONO_PARAMS_NAMES
        codes, counts = np.unique(fx["iono_params"], return_counts=True)
        nav["iono_params"] = {IONO_PARAMS_NAMES.get(int(c), "unknown"): int(k) for c, k in zip(codes, counts)}
        if ok.any():
            from ..gnss.geodesy import ecef2lla, ecef2enu
            e = fx["ecef"][ok]
            mean = e.mean(axis=0)
            lat, lon, h = ecef2lla(mean)
            nav["mean_position"] = {"lat_deg": float(lat), "lon_deg": float(lon), "height_m": float(h),
                                    "ecef_m": [float(v) for v in mean]}
            nav["scatter_enu_m"] = [float(v) for v in ecef2enu(e, mean).std(axis=0)]
            sp = np.linalg.norm(fx["velocity_ecef"][ok], axis=1)
            sp = sp[np.isfinite(sp)]
            if sp.size:
                nav["speed_mean_mps"] = float(np.mean(sp))
    info["navigation"] = nav
    ob = run.obs
    info["observables"] = {"rows": int(len(ob)), "epochs": int(len(np.unique(ob["time_s"]))) if len(ob) else 0,
                           "prns": sorted({int(p) for p in ob["prn"]})}
    info["ephemerides"] = sorted({int(run.eph_key(e)) for e in run.ephemerides})
    from ..gnss.satid import SYSTEM_NAMES, sat_system
    prns = set(info["observables"]["prns"]) | {int(p) for p in info.get("acquisition", {}).get("detected_prns", [])}
    letters = sorted({sat_system(p, run.system) for p in prns} or {sat_system(1, run.system)}, key="GCEJ".index)
    info["systems"] = [SYSTEM_NAMES[c] for c in letters]
    info["config"] = run.attrs.get("config", "")
    return info


def _channels_acquisition(rf) -> dict:
    """The ``channels`` (records, time span, mean C/N0 while tracked) and ``acquisition`` (searches, detected
    PRNs) entries of :func:`run_info` from an open :class:`receiver.runfile.RunFile`."""
    ch = {}
    for name in rf.channel_names():
        g = rf.channel(name, ("time_s", "cn0_dbhz", "state"))
        if "time_s" in g and g["time_s"].shape[0]:
            t = g["time_s"]
            d = {"records": int(t.shape[0]), "t_first_s": float(t[0]), "t_last_s": float(t[-1])}
            if "cn0_dbhz" in g and "state" in g:
                c = g["cn0_dbhz"][g["state"] == 2]
                if c.size:
                    d["mean_cn0_dbhz"] = float(np.mean(c))
            ch[name] = d
    out = {"channels": ch}
    acq = rf.acquisition(("prn", "detected"))
    if "prn" in acq:
        det = acq["detected"] if "detected" in acq else np.zeros(0, bool)
        out["acquisition"] = {"searches": int(acq["prn"].shape[0]),
                              "detected_prns": sorted({int(p) for p in acq["prn"][det]})}
    return out


def run_facts(path) -> dict:
    """The few entries of :func:`run_info` that say why a run has no fix -- ``channels``, ``acquisition`` and
    ``ephemerides`` (the satellites with a decoded ephemeris), the same values -- from one opening of the
    file, without reading its fixes, observables and configuration (the end of every ``gnssrx run``
    without a fix: receiver.probe.hints)."""
    from ..gnss.satid import MIXED, sat_key
    from ..runfile.reader import RunFile
    with RunFile(path) as rf:
        out = _channels_acquisition(rf)
        mixed = rf.system == MIXED
        out["ephemerides"] = sorted({int(sat_key(getattr(e, "system", "G"), e.prn) if mixed else e.prn)
                                     for e in rf.ephemerides()})
    return out


def format_info(info: dict, show_config: bool = True) -> str:
    """The :func:`run_info` dict as the text ``gnssrx info`` prints (the configuration too when ``show_config``)."""
    L = []
    add = L.append
    add(f"file            {info['file']} ({info['size_bytes'] / 1e6:.1f} MB)")
    add(f"schema          {info.get('schema', '?')}  (gnssrx {info.get('gnssrx_version', '?')}, "
        f"created {info.get('created_utc', '?')})")
    if "input_path" in info:
        add(f"input           {info['input_path']}")
    if "duration_s" in info:
        add(f"signal          {info['duration_s']:.2f} s at {info['sample_rate_hz'] / 1e6:g} MS/s, "
            f"IF {info.get('if_hz', 0):g} Hz"
            + (f" (resampled x{info['resample']} from {info['input_sample_rate_hz'] / 1e6:g} MS/s, IF "
               f"{info.get('input_if_hz', 0):g} Hz)" if info.get("resample", "1/1") != "1/1" else ""))
    if "wall_time_s" in info:
        add(f"processing      {info['wall_time_s']:.1f} s (real-time factor {info.get('realtime_factor', 0):.1f}x)")
    add(f"navigation mode {'assisted (RINEX ephemerides)' if info['assisted'] else 'autonomous'}")
    if "systems" in info:
        add(f"systems         {', '.join(info['systems'])}")
    sys_ = info.get("system", "G")
    if "command" in info:
        add(f"command         {info['command']}")
    add("groups          " + ", ".join(f"/{k} ({v} datasets)" for k, v in sorted(info["groups"].items())))
    if "acquisition" in info:
        a = info["acquisition"]
        add(f"acquisition     {a['searches']} searches; detected "
            + (" ".join(sat_label(p, sys_) for p in a["detected_prns"]) or "none"))
    ch = info["channels"]
    add(f"channels        {len(ch)}")
    for name, d in sorted(ch.items()):
        cn0 = f"  C/N0 {d['mean_cn0_dbhz']:.1f} dB-Hz" if "mean_cn0_dbhz" in d else ""
        add(f"  {name}  {d['records']:8d} records  {d['t_first_s']:8.3f} .. {d['t_last_s']:8.3f} s{cn0}")
    nav = info["navigation"]
    add(f"fixes           {nav['fixes']}")
    if nav["fixes"]:
        f0, f1 = nav["first_fix"], nav["last_fix"]
        add(f"  time span     GPS week {f0['gps_week']} TOW {f0['gps_tow']:.3f} .. week {f1['gps_week']} "
            f"TOW {f1['gps_tow']:.3f} ({nav['span_s']:.1f} s)")
        add(f"                {f0['gps_time']} .. {f1['gps_time']} GPS time (first fix {f0['utc']} UTC)")
        add(f"  first fix     {f0['time_s']:.2f} s after the first sample of the file")
        if nav.get("rate_hz"):
            add(f"  rate          {nav['rate_hz']:.2f} Hz")
        add(f"  modes         scalar {nav['modes']['scalar']}, vector {nav['modes']['vector']}, "
            f"coast {nav['modes']['coast']}")
        add(f"  satellites    {nav['n_sats_mean']:.1f} used on average, mean PDOP {nav['pdop_mean']:.2f}")
        if nav.get("iono_params"):
            add("  ionosphere    " + ", ".join(f"{k} {v}" for k, v in nav["iono_params"].items())
                + " fixes (Klobuchar set)")
        if "mean_position" in nav:
            m = nav["mean_position"]
            add(f"  mean position lat {m['lat_deg']:.7f} lon {m['lon_deg']:.7f} h {m['height_m']:.2f} m")
            add("  scatter (1sd) E {:.2f} N {:.2f} U {:.2f} m".format(*nav["scatter_enu_m"]))
        if "speed_mean_mps" in nav:
            add(f"  mean speed    {nav['speed_mean_mps']:.3f} m/s")
    ob = info["observables"]
    add(f"observables     {ob['rows']} rows, {ob['epochs']} epochs, satellites "
        + (" ".join(sat_label(p, sys_) for p in ob["prns"]) or "none"))
    add("ephemerides     (decoded) " + (" ".join(sat_label(p, sys_) for p in info["ephemerides"]) or "none"))
    if "iono_utc" in info:
        io = info["iono_utc"]
        add(f"iono/UTC        {io.get('source', '?')}: Klobuchar alpha "
            + " ".join(f"{v:.3g}" for v in io.get("alpha", []))
            + ", beta " + " ".join(f"{v:.3g}" for v in io.get("beta", []))
            + (f"; GPS-UTC {io['dt_ls']} s" if "dt_ls" in io else ""))
    if show_config:
        add("config:")
        L.extend("  " + ln for ln in str(info["config"]).rstrip().splitlines())
    return "\n".join(L)


__all__ = ["run_info", "run_facts", "format_info"]
