"""Acceptance of BeiDou B1I navigation (issue 21) on the project's own simulator.

Simulates configs/scenarios/bds_static_tokyo.yaml (45 s, 45 dB-Hz, nominal BeiDou GEO/IGSO/MEO with genuine
D1/D2 messages), runs configs/bds_b1i_nav.yaml on it and prints: satellites tracked / used (GEO, IGSO, MEO),
time to first fix, 3D RMS against the truth, and for every decoded ephemeris the largest difference to the
broadcast one in units of the field's LSB (D1 satellites and GEO D2 satellites); then exports RINEX 3
observation + navigation files and, when RTKLIB's rnx2rtkp is installed, solves them with it (-sys C,
single point, broadcast Klobuchar, Saastamoinen) and prints the distance to gnssrx's own fixes.

    PYTHONPATH=. python scripts/bench/accuracy_bds.py [--out DIR] [--set scenario.key=value ...]
"""
from __future__ import annotations

import argparse
import os
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from receiver.schema import load_receiver_config  # noqa: E402
from receiver.evaluate import evaluate  # noqa: E402
from receiver.gnss.bds_nav import EPH_LSB  # noqa: E402
from receiver.pipeline import run  # noqa: E402
from receiver.runfile.reader import load_run  # noqa: E402
from receiver.sim.bds_constellation import bds_nominal_ephemerides  # noqa: E402
from receiver.sim.simulate import simulate  # noqa: E402


def kind(prn):
    return "GEO" if prn <= 5 else "IGSO" if prn in (6, 7, 8, 9, 10, 13, 16) else "MEO"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None)
    ap.add_argument("--set", action="append", default=[], help="scenario override key=value")
    a = ap.parse_args(argv)
    out = a.out or tempfile.mkdtemp(prefix="bds_acc_")
    os.makedirs(out, exist_ok=True)
    rec = os.path.join(out, "bds.bin")
    sc = os.path.join(ROOT, "configs/scenarios/bds_static_tokyo.yaml")
    simulate(sc, rec, overrides=a.set, progress=False)
    cfg = load_receiver_config(os.path.join(ROOT, "configs/bds_b1i_nav.yaml"),
                               [("input.path", rec), ("output.path", os.path.join(out, "bds.h5"))])
    summary = run(cfg, quiet=True, log=lambda *x: None)
    print(summary.text())
    ev = evaluate(os.path.join(out, "bds.h5"), os.path.join(out, "bds.truth.h5"))
    print(f"time to first fix   {ev['ttff_s']:.2f} s")
    print(f"3D RMS              {ev['pos_3d_rms_m']:.3f} m   (horizontal {ev['pos_h_rms_m']:.3f}, vertical "
          f"{ev['pos_v_rms_m']:.3f}; {ev['n_scored']} fixes)")
    print(f"velocity 3D RMS     {ev['vel_3d_rms_mps']:.3f} m/s")
    r = load_run(os.path.join(out, "bds.h5"))
    used = sorted({int(p) for p in r.obs["prn"][r.obs["used_in_fix"] == 1]})
    print("used in fixes       " + " ".join(f"C{p:02d}({kind(p)})" for p in used))
    import h5py
    with h5py.File(os.path.join(out, "bds.truth.h5"), "r") as t:
        week, tow = int(t.attrs["gps_week"]), float(t.attrs["start_gps_tow_s"])
    truth, _ = bds_nominal_ephemerides(os.path.join(ROOT, "data/bds_nominal_constellation.yaml"), week, tow)
    print("decoded ephemerides (largest |decoded - broadcast| / LSB over the fields):")
    for e in sorted(r.ephemerides, key=lambda x: x.prn):
        b = truth[e.prn]
        worst = max(abs(getattr(e, attr) - getattr(b, attr)) / lsb for attr, lsb in EPH_LSB.values())
        ints = all(getattr(e, k) == getattr(b, k) for k in ("week", "iode", "iodc", "health", "ura_index"))
        print(f"  C{e.prn:02d} {kind(e.prn):4s} {'D2' if e.prn <= 5 else 'D1'}  {worst:.3g} LSB"
              f"  integer fields {'equal' if ints else 'DIFFER'}")
    import shutil
    import subprocess
    from receiver.export import export_all
    files = export_all(os.path.join(out, "bds.h5"), {"rinex": True, "nmea": True})
    if shutil.which("rnx2rtkp"):
        conf = os.path.join(out, "spp.conf")
        with open(conf, "w") as fh:
            fh.write("pos1-posmode=single\npos1-frequency=l1\npos1-elmask=5\npos1-ionoopt=brdc\n"
                     "pos1-tropopt=saas\npos1-sateph=brdc\npos1-navsys=32\nout-solformat=xyz\n"
                     "out-timesys=gpst\nout-timeform=tow\nout-timendec=6\n")
        pos = os.path.join(out, "spp.pos")
        subprocess.run(["rnx2rtkp", "-k", conf, "-sys", "C", "-o", pos, files["obs"], files["nav"]],
                       capture_output=True, check=True)
        rtk = np.loadtxt(pos, comments="%", ndmin=2)
        rtk = rtk[rtk[:, 5] == 5]
        fx = r.fixes
        k = np.abs(fx["gps_tow"][:, None] - rtk[None, :, 1]).argmin(axis=1)
        ok = np.abs(fx["gps_tow"] - rtk[k, 1]) < 1e-3
        d = np.linalg.norm(fx["ecef"][ok] - rtk[k[ok], 2:5], axis=1)
        print(f"rnx2rtkp -sys C     {ok.sum()} / {len(fx)} epochs; |gnssrx - RTKLIB| median {np.median(d):.3f} "
              f"RMS {np.sqrt(np.mean(d ** 2)):.3f} max {d.max():.3f} m")
    print(f"files in {out}")


if __name__ == "__main__":
    main()
