#!/usr/bin/env python3
"""Dual-frequency acceptance (issue 38): L1-only versus L1/L5 ionosphere-free fixes against the truth of the
project's simulator, static, an ionosphere ``--iono-scale`` times the broadcast Klobuchar model.

    python scripts/bench/accuracy_dual.py --out /tmp/dual_acc [--duration 12] [--iono-scale 1.5] [--seed 1]
                                          [--cn0 45] [--l5-fs 21e6] [--reuse] [--galileo [--lat 46.52 --lon 6.63]]

Simulates configs/scenarios/l1l5_static_tokyo.yaml (L1 4 MS/s + L5 21 MS/s, int8 I/Q, one clock),
runs the receiver on the fragment it writes (signals [gps_l1ca, gps_l5], assisted with the scenario's RINEX
navigation file for a fix within seconds) and prints the 3D / horizontal / vertical RMS and mean errors of
/navigation (L1 only, broadcast Klobuchar) and /navigation_ionofree, and the L5 pseudorange error against
the L5 truth (after removing the common receiver clock of each epoch).

``--galileo``: the same with Galileo E1 + E5a (configs/scenarios/gal_e1e5a_static.yaml, no RINEX: the I/NAV
ephemerides arrive ~15.5 s after the start, so the default duration is 25 s and fixes are scored from 15 s;
the E1-only fix applies no ionospheric model), at ``--lat`` / ``--lon``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import h5py
import numpy as np

from receiver.gnss.geodesy import ecef2enu
from receiver.pipeline import run
from receiver.schema import load_receiver_config
from receiver.sim.simulate import simulate

ROOT = Path(__file__).resolve().parents[2]
RINEX = ROOT.parent / "shared" / "data" / "brdc0010.22n"


def errors(h5, group, truth_ecef, skip_s):
    """(n, 3D RMS, horizontal RMS, vertical RMS, mean E, N, U) of the fixes of /group after ``skip_s``."""
    g = h5[group]
    t = g["time_s"][:]
    e = ecef2enu(g["ecef"][:][t >= skip_s], truth_ecef)
    if not len(e):
        return (0,) + (float("nan"),) * 6
    rms = lambda v: float(np.sqrt(np.mean(v ** 2)))           # noqa: E731
    return (len(e), rms(np.linalg.norm(e, axis=1)), rms(np.linalg.norm(e[:, :2], axis=1)), rms(e[:, 2]),
            *map(float, e.mean(axis=0)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/dual_acc")
    ap.add_argument("--duration", type=float, default=12.0)
    ap.add_argument("--iono-scale", type=float, default=1.5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cn0", type=float, default=45.0)
    ap.add_argument("--l5-fs", type=float, default=21e6, help="L5 file sample rate")
    ap.add_argument("--skip-s", type=float, default=3.0, help="fixes before this time are not scored")
    ap.add_argument("--reuse", action="store_true", help="keep an existing recording")
    ap.add_argument("--galileo", action="store_true", help="Galileo E1 + E5a instead of GPS L1 + L5")
    ap.add_argument("--lat", type=float, default=46.5197, help="--galileo: receiver latitude (deg)")
    ap.add_argument("--lon", type=float, default=6.6323, help="--galileo: receiver longitude (deg)")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.galileo:
        return galileo(a, out)
    rec = out / "l1l5.bin"
    if not (a.reuse and rec.exists()):
        simulate(ROOT / "configs/scenarios/l1l5_static_tokyo.yaml", str(rec), progress=False, overrides=[
            f"time.duration_s={a.duration}", f"atmosphere.iono_scale={a.iono_scale}", f"time.seed={a.seed}",
            f"cn0.dbhz={a.cn0}", f"constellation.rinex={RINEX}", f"l5.sample_rate_hz={a.l5_fs}"])
    cfg = load_receiver_config(out / "l1l5.yaml", [("navigation.ephemeris", str(RINEX)),
                                                  ("output.path", str(out / "run.h5"))])
    s = run(cfg, quiet=True)
    print(s.text())
    with h5py.File(out / "l1l5.truth.h5") as t, h5py.File(out / "run.h5") as h:
        truth = t["receiver/ecef"][0]
        print(f"\niono_scale {a.iono_scale}, C/N0 {a.cn0} dB-Hz, seed {a.seed}, fixes after {a.skip_s} s")
        print(f"{'fix':<22}{'n':>5}{'3D RMS':>9}{'H RMS':>8}{'V RMS':>8}{'mean E':>9}{'mean N':>9}{'mean U':>9}")
        for name, grp in (("L1 only (Klobuchar)", "navigation"), ("L1/L5 iono-free", "navigation_ionofree")):
            n, d3, hh, vv, me, mn, mu = errors(h, grp, truth, a.skip_s)
            print(f"{name:<22}{n:>5}{d3:>9.2f}{hh:>8.2f}{vv:>8.2f}{me:>9.2f}{mn:>9.2f}{mu:>9.2f}")
        l5_pr_errors(h, out / "l1l5_l5.truth.h5")


def galileo(a, out):
    """--galileo: E1-only versus E1/E5a ionosphere-free fixes."""
    rec = out / "e1e5a.bin"
    duration = a.duration if a.duration != 12.0 else 25.0
    skip = max(a.skip_s, 15.0)
    if not (a.reuse and rec.exists()):
        simulate(ROOT / "configs/scenarios/gal_e1e5a_static.yaml", str(rec), progress=False, overrides=[
            f"time.duration_s={duration}", f"atmosphere.iono_scale={a.iono_scale}", f"time.seed={a.seed}",
            f"cn0.dbhz={a.cn0}", f"e5a.sample_rate_hz={a.l5_fs}", f"receiver.lat_deg={a.lat}",
            f"receiver.lon_deg={a.lon}"])
    cfg = load_receiver_config(ROOT / "configs/gal_e1_e5a_ionofree.yaml", [
        ("input.path", str(rec)), ("output.path", str(out / "run_gal.h5")),
        ("input.signal_files", {"gal_e5a": {"path": str(out / "e1e5a_e5a.bin"), "format": "int8_iq",
                                            "sample_rate_hz": a.l5_fs, "if_hz": 0.0}})])
    s = run(cfg, quiet=True)
    print(s.text())
    with h5py.File(out / "e1e5a.truth.h5") as t, h5py.File(out / "run_gal.h5") as h:
        truth = t["receiver/ecef"][0]
        print(f"\nGalileo, iono_scale {a.iono_scale}, C/N0 {a.cn0} dB-Hz, seed {a.seed}, "
              f"({a.lat:g}, {a.lon:g}), fixes after {skip} s")
        print(f"{'fix':<22}{'n':>5}{'3D RMS':>9}{'H RMS':>8}{'V RMS':>8}{'mean E':>9}{'mean N':>9}{'mean U':>9}")
        for name, grp in (("E1 only (no model)", "navigation"), ("E1/E5a iono-free", "navigation_ionofree")):
            n, d3, hh, vv, me, mn, mu = errors(h, grp, truth, skip)
            print(f"{name:<22}{n:>5}{d3:>9.2f}{hh:>8.2f}{vv:>8.2f}{me:>9.2f}{mn:>9.2f}{mu:>9.2f}")
        l5_pr_errors(h, out / "e1e5a_e5a.truth.h5", table="observables_e5a", letter="E")


def l5_pr_errors(h, truth_path, table="observables_l5", letter="G"):
    """L5 pseudorange minus truth, the epoch's mean removed (the receiver clock): RMS per satellite."""
    o = h[table]
    tm, prn, pr = o["time_s"][:], o["prn"][:], o["pseudorange_m"][:]
    with h5py.File(truth_path) as t:
        d = np.full(len(pr), np.nan)
        for p in np.unique(prn):
            g = t[f"satellites/{letter}{p:02d}"]
            k = prn == p
            d[k] = pr[k] - np.interp(tm[k], g["time_s"][:], g["pseudorange_m"][:])
    for e in np.unique(tm):
        k = tm == e
        d[k] -= np.mean(d[k])
    rows = [f"{letter}{p:02d} {np.mean(d[prn == p]):+.2f}/{np.std(d[prn == p]):.2f}" for p in np.unique(prn)]
    print(f"{table[12:].upper()} pseudorange error mean/sd (m, epoch mean removed): " + ", ".join(rows))


if __name__ == "__main__":
    main()
