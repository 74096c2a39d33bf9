#!/usr/bin/env python
"""High-sample-rate acceptance (issue 18): a 16.368 MS/s real-IF 2-bit recording with 12 satellites
through the input stage (input.decimate: auto -> 4 MS/s complex baseband) against the same scenario
simulated directly at 4 MS/s (2-bit I/Q), per seed: CPU-time and wall-clock real-time factor of the
whole `run` (acquisition, 12 channels, navigation, HDF5), 3D RMS against the truth, mean C/N0.

    python scripts/bench/accuracy_highrate.py [--seeds 1,2] [--duration 20] [--dir out/highrate] [--decimate auto]

Recordings are simulated once into --dir and reused.  The scenario
(configs/scenarios/static_16mhz_2bit.yaml) takes the satellites from ../shared/data/brdc0010.22n, so the
receiver runs assisted (navigation.ephemeris) and fixes from ~1.5 s; 3D RMS is scored after 5 s.
The CPU-time factor (signal seconds per CPU second of this process) is what a quiet 2-core machine's
wall-clock factor approaches; on a loaded machine the wall-clock factor is only a lower bound.
"""
import argparse
import os
import sys
import time


import h5py  # noqa: E402
import numpy as np  # noqa: E402

from receiver.schema import load_receiver_config  # noqa: E402
from receiver.evaluate import evaluate  # noqa: E402
from receiver.pipeline import run  # noqa: E402
from receiver.sim.simulate import simulate  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENARIO = os.path.join(ROOT, "configs", "scenarios", "static_16mhz_2bit.yaml")
NAV = os.path.join(ROOT, "..", "shared", "data", "brdc0010.22n")
LOW = [("frontend.sample_rate_hz", 4e6), ("frontend.if_hz", 0.0), ("frontend.format", "packed2_iq")]
SETTLE_S = 5.0


def recording(d, name, seed, duration, extra):
    path = os.path.join(d, f"{name}_s{seed}.bin")
    if not os.path.exists(path):
        simulate(SCENARIO, path, [("time.seed", seed), ("time.duration_s", duration)] + extra, progress=False)
    stem = path[:-4]
    return {"if": path, "yaml": stem + ".yaml", "truth": stem + ".truth.h5"}


def receive(paths, out, decimate):
    cfg = load_receiver_config(paths["yaml"], [("output.path", out), ("navigation.ephemeris", NAV),
                                               ("input.decimate", decimate)])
    c0, w0 = time.process_time(), time.perf_counter()
    s = run(cfg, quiet=True, log=lambda *a: None)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    ev = evaluate(out, paths["truth"])
    with h5py.File(out) as f:
        t = f["navigation"]["time_s"][:]
        e = f["navigation"]["ecef"][:]
        fs = float(f.attrs["sample_rate_hz"])
    with h5py.File(paths["truth"]) as f:
        ref = f["receiver"]["ecef"][0]                    # static scenario
    err = np.linalg.norm(e - ref, axis=1)
    late = float(np.sqrt(np.mean(err[t >= SETTLE_S] ** 2)))
    return {"cpu_rtf": s.duration_s / cpu, "wall_rtf": s.duration_s / wall, "cpu_s": cpu,
            "rms_all": ev["pos_3d_rms_m"], "rms": late,
            "n_sat": len(s.tracked), "cn0": float(np.mean(list(s.mean_cn0.values()))) if s.mean_cn0 else np.nan,
            "fs": fs, "n_fixes": s.n_fixes}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1")
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--dir", default=os.path.join("out", "highrate"))
    ap.add_argument("--decimate", default="auto", help="input.decimate for the 16.368 MS/s file")
    a = ap.parse_args(argv)
    if not os.path.exists(NAV):
        sys.exit(f"needs {NAV} (the shared data directory)")
    os.makedirs(a.dir, exist_ok=True)
    dec = a.decimate if a.decimate == "auto" else int(a.decimate)
    print(f"{'seed':>4} {'file':>10} {'MS/s':>6} {'sats':>4} {'C/N0':>5} {'fixes':>5} {'3D RMS m':>8} "
          f"{'(all)':>6} {'CPU s':>6} {'CPU RTF':>7} {'wall RTF':>8}")
    ratios = []
    for seed in map(int, a.seeds.split(",")):
        rows = {}
        for name, extra, d in (("hr16", [], dec), ("hr4", LOW, "auto")):
            p = recording(a.dir, name, seed, a.duration, extra)
            r = rows[name] = receive(p, os.path.join(a.dir, f"{name}_s{seed}.h5"), d)
            print(f"{seed:4d} {name:>10} {r['fs'] / 1e6:6.3f} {r['n_sat']:4d} {r['cn0']:5.1f} {r['n_fixes']:5d} "
                  f"{r['rms']:8.3f} {r['rms_all']:6.2f} {r['cpu_s']:6.1f} {r['cpu_rtf']:7.2f} {r['wall_rtf']:8.2f}",
                  flush=True)
        ratios.append(rows["hr16"]["rms"] / rows["hr4"]["rms"])
    print("3D RMS ratio 16.368 MS/s (resampled) / 4 MS/s: " + ", ".join(f"{x:.3f}" for x in ratios)
          + f"  (mean {np.mean(ratios):.3f})")


if __name__ == "__main__":
    main()
