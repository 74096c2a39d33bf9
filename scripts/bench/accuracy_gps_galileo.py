#!/usr/bin/env python3
"""Score run files of one recording against its truth (issue 33: GPS + Galileo (+ BeiDou) combined against
each system alone): per run the number of fixes, the first fix, the mean satellites and PDOP, the 3D RMS over
all its fixes and over the epochs (GPS time) that every run given has a fix at, and the mean ENU error there.

    python scripts/bench/accuracy_gps_galileo.py REC.truth.h5 LABEL=RUN.h5 [LABEL=RUN.h5 ...] [--after S]

e.g. the runs of docs/galileo.md on configs/scenarios/gps_gal_static.yaml:

    gnssrx run configs/gps_gal_bds_nav.yaml --input gg.bin -o mixed.h5 --set "signals=[gps_l1ca, gal_e1]" \\
        --set input.sample_rate_hz=4000000 --set input.if_hz=0
    gnssrx run configs/gps_gal_bds_nav.yaml --input gg.bin -o gps.h5 --set "signals=[]" --set signal=gps_l1ca \\
        --set "acquisition.prns_by_signal={}" --set input.sample_rate_hz=4000000 --set input.if_hz=0
    gnssrx run configs/gal_e1_nav.yaml --input gg.bin -o gal.h5 --set navigation.ionosphere=klobuchar
    python scripts/bench/accuracy_gps_galileo.py gg.truth.h5 G+E=mixed.h5 G=gps.h5 E=gal.h5

``--after S``: only fixes at least S seconds after the first sample (e.g. once every system has ephemerides).
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from receiver.gnss.geodesy import ecef2enu
from receiver.runfile.reader import RunFile
from receiver.runfile.truth import TruthFile


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("truth")
    ap.add_argument("runs", nargs="+", help="LABEL=RUN.h5")
    ap.add_argument("--after", type=float, default=0.0)
    a = ap.parse_args(argv)
    with TruthFile(a.truth) as tf:
        x = np.asarray(tf.receiver(("ecef",))["ecef"], float).mean(axis=0)
    runs = {}
    for item in a.runs:
        label, _, path = item.partition("=")
        with RunFile(path) as r:
            fx = r.fixes()
            t0 = float(r.attrs.get("first_sample", 0)) / float(r.attrs["sample_rate_hz"])
        fx = fx[fx["time_s"] - t0 >= a.after]
        runs[label] = (fx, t0)
    common = None
    for fx, _ in runs.values():
        t = set(np.round(fx["gps_tow"], 2).tolist())
        common = t if common is None else common & t
    print(f"{'run':8s} {'fixes':>6s} {'first s':>8s} {'sats':>5s} {'PDOP':>5s} {'3D RMS':>7s} | common epochs "
          f"({len(common)}): {'sats':>5s} {'PDOP':>5s} {'3D RMS':>7s}  mean E/N/U m")
    for label, (fx, t0) in runs.items():
        if not len(fx):
            print(f"{label:8s} {'0':>6s}")
            continue
        d = np.linalg.norm(fx["ecef"] - x, axis=1)
        sel = np.isin(np.round(fx["gps_tow"], 2), sorted(common))
        c = fx[sel]
        line = (f"{label:8s} {len(fx):6d} {float(fx['time_s'][0]) - t0:8.2f} {np.mean(fx['n_sats']):5.1f} "
                f"{np.mean(fx['pdop']):5.2f} {np.sqrt(np.mean(d ** 2)):7.3f} | ")
        if len(c):
            enu = ecef2enu(c["ecef"], x)
            line += (f"{'':16s}{np.mean(c['n_sats']):5.1f} {np.mean(c['pdop']):5.2f} "
                     f"{np.sqrt(np.mean(np.sum(enu ** 2, axis=1))):7.3f}  "
                     + "/".join(f"{v:+.2f}" for v in enu.mean(axis=0)))
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
