"""GPS + BeiDou in one run (issue 21): runs one wideband recording with both signals, GPS only, BeiDou only
and GPS reduced to its 3 highest satellites + BeiDou (and those 3 alone), scores the fixes against the truth,
writes the combined run's mixed RINEX 3 obs/nav and NMEA and solves the RINEX files with RTKLIB's
rnx2rtkp -sys G,C (when installed).

    PYTHONPATH=. python scripts/bench/accuracy_multi.py REC.bin [--keep]      # REC.truth.h5 beside it
    gnssrx simulate configs/scenarios/gps_bds_static_tokyo.yaml -o REC.bin     (40 s, 1.6 GB)

Receiver: configs/gps_bds_nav.yaml (signals: [gps_l1ca, bds_b1i]); the one-signal cases use the same
config with `signals` reduced (GPS at input.if_hz, BeiDou at if_hz - 14.322 MHz).
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from receiver.schema import load_receiver_config  # noqa: E402
from receiver.export import export_all  # noqa: E402
from receiver.pipeline import run  # noqa: E402
from receiver.runfile.reader import load_run  # noqa: E402


def score(h5, x_true):
    """(fixes, first fix s, mean satellites, mean PDOP, 3D RMS m, {gps_tow: ecef})"""
    r = load_run(h5)
    fx = r.fixes
    if not len(fx):
        return 0, None, np.nan, np.nan, np.nan, {}
    d = np.linalg.norm(fx["ecef"] - x_true, axis=1)
    first = float(fx["time_s"][0]) - float(r.attrs.get("first_sample", 0)) / float(r.attrs["sample_rate_hz"])
    return (len(fx), first, float(np.mean(fx["n_sats"])), float(np.mean(fx["pdop"])),
            float(np.sqrt(np.mean(d ** 2))), {round(float(t), 3): e for t, e in zip(fx["gps_tow"], fx["ecef"])})


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recording")
    ap.add_argument("--out", default=None, help="directory of the run files (default: beside the recording)")
    ap.add_argument("--reuse", action="store_true", help="score run files already there instead of running")
    ap.add_argument("--cases", default="gb,g,g8,c,g3c,g3", help="comma list of gb g g8 c g3c g3")
    a = ap.parse_args(argv)
    stem = a.recording[:-4] if a.recording.endswith(".bin") else a.recording
    out = a.out or os.path.dirname(os.path.abspath(a.recording))
    with h5py.File(stem + ".truth.h5", "r") as t:
        x_true = t["receiver"]["ecef"][0]
        sats = {k: (int(g.attrs["prn"]), float(np.mean(g["elevation_deg"][:]))) for k, g in t["satellites"].items()}
    gps = sorted((p for k, (p, el) in sats.items() if k[0] == "G"), key=lambda p: -dict(sats.values())[p])
    g3 = sorted(gps[:3])
    if_gps = 7.161e6
    absent = min(set(range(1, 38)) - {p - 400 for k, (p, _) in sats.items() if k[0] == "C"})
    cfg0 = os.path.join(ROOT, "configs/gps_bds_nav.yaml")
    cases = {
        "gb": ("GPS + BeiDou", ["signals=[gps_l1ca, bds_b1i]", "output.rinex=true", "output.nmea=true"]),
        "g": ("GPS only", ["signals=[gps_l1ca]"]),
        # GPS alone through the combined run's input stage (8 MS/s; the B1I search asks for a PRN not in view)
        "g8": ("GPS only (8 MS/s stage)", ["signals=[gps_l1ca, bds_b1i]",
                                           f"acquisition.prns_by_signal={{bds_b1i: [{absent}]}}"]),
        "c": ("BeiDou only", ["signals=[bds_b1i]", f"input.if_hz={if_gps - 14.322e6}",
                              f"acquisition.prns={list(range(1, 38))}"]),
        "g3c": (f"GPS {','.join(f'G{p:02d}' for p in g3)} + BeiDou", ["signals=[gps_l1ca, bds_b1i]",
                                                                       f"acquisition.prns={g3}"]),
        "g3": (f"GPS {','.join(f'G{p:02d}' for p in g3)} alone", ["signals=[gps_l1ca]", f"acquisition.prns={g3}"]),
    }
    res = {}
    for key in a.cases.split(","):
        name, ov = cases[key]
        h5 = os.path.join(out, f"multi_{key}.h5")
        cfg = load_receiver_config(cfg0, [f"input.path={a.recording}", f"output.path={h5}"] + ov)
        if a.reuse and os.path.exists(h5):
            wall = float(load_run(h5).attrs.get("wall_time_s", np.nan))
        else:
            wall = run(cfg, quiet=True, log=lambda *x: None).wall_s
            if key == "gb":
                export_all(h5, cfg.output)
        res[key] = score(h5, x_true) + (wall,)
        n, first, ns, pdop, rms, _, wall = res[key]
        print(f"{name:28s} fixes {n:3d} first {first if first is not None else float('nan'):6.2f} s  sats "
              f"{ns:5.1f}  PDOP {pdop:5.2f}  3D RMS {rms:6.3f} m   ({wall:.0f} s wall)", flush=True)
        if "gb" in res and key in ("g", "g8") and res[key][5]:
            com = sorted(set(res[key][5]) & set(res["gb"][5]))
            if com:
                cr = [float(np.sqrt(np.mean([np.sum((r[5][t] - x_true) ** 2) for t in com])))
                      for r in (res["gb"], res[key])]
                print(f"  {len(com)} epochs in common with GPS + BeiDou: 3D RMS {cr[1]:.3f} m here, {cr[0]:.3f} m "
                      f"combined", flush=True)
    if "gb" in res and shutil.which("rnx2rtkp"):
        h5 = os.path.join(out, "multi_gb.h5")
        obs, nav = h5[:-3] + ".obs", h5[:-3] + ".nav"
        r = load_run(h5)
        conf = os.path.join(out, "multi_spp.conf")
        with open(conf, "w") as fh:
            fh.write(f"pos1-posmode=single\npos1-frequency=l1\npos1-elmask={r.cfg('navigation.elevation_mask_deg')}\n"
                     "pos1-ionoopt=brdc\npos1-tropopt=saas\npos1-sateph=brdc\npos1-navsys=33\n"
                     "out-solformat=xyz\nout-timesys=gpst\nout-timeform=tow\nout-timendec=6\n")
        pos = os.path.join(out, "multi_spp.pos")
        subprocess.run(["rnx2rtkp", "-k", conf, "-sys", "G,C", "-o", pos, obs, nav], capture_output=True,
                       check=True)
        rtk = np.loadtxt(pos, comments="%", ndmin=2)
        rtk = rtk[rtk[:, 5] == 5]
        ours = res["gb"][5]
        d = [np.linalg.norm(ours[round(t, 3)] - rtk[i, 2:5]) for i, t in enumerate(rtk[:, 1]) if round(t, 3) in ours]
        d = np.array(d)
        if len(d):
            print(f"rnx2rtkp -sys G,C on {os.path.basename(obs)} / {os.path.basename(nav)}: {len(d)} of {res['gb'][0]} "
                  f"epochs, satellites {int(np.median(rtk[:, 6]))} (median); |gnssrx - RTKLIB| median "
                  f"{np.median(d):.3f} RMS {np.sqrt(np.mean(d ** 2)):.3f} max {d.max():.3f} m; RTKLIB 3D RMS vs "
                  f"truth {np.sqrt(np.mean(np.sum((rtk[:, 2:5] - x_true) ** 2, axis=1))):.3f} m")
        else:
            print("rnx2rtkp: no epoch in common")


if __name__ == "__main__":
    main()
