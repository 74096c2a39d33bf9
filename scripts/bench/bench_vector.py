#!/usr/bin/env python3
"""Real-time factor of vector tracking.

Runs the receiver on a recording with the vector loop enabled and times the vector tracker's
``process`` calls separately from the scalar part:

    python scripts/bench/bench_vector.py                          # third-party recording, 8 channels, all variants
    python scripts/bench/bench_vector.py --config configs/vector_tokyo.yaml --channels 12 --variants adaptive_r

Real-time factor = seconds of signal processed in vector mode / wall-clock seconds spent in the tracker
(> 1 is faster than real time).  The numba code is compiled (and cached) by a warm-up run first.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def bench(config, variant, channels, extra=()):
    from receiver.schema import load_receiver_config
    from receiver.pipeline import run
    from receiver.tracking.vector import tracker as T

    timing = {"wall": 0.0, "cpu": 0.0, "signal": 0.0, "calls": 0, "channels": []}
    orig = T.VectorTracker.process

    def timed(self, block, start):
        t0, c0 = time.perf_counter(), time.process_time()
        out = orig(self, block, start)
        timing["wall"] += time.perf_counter() - t0
        timing["cpu"] += time.process_time() - c0
        timing["signal"] += self.stats["epochs"] * self.T_ms * 1e-3 - timing["signal"]
        timing["calls"] += 1
        timing["channels"].append(len(self.prns))
        return out

    T.VectorTracker.process = timed
    try:
        with tempfile.TemporaryDirectory() as tmp:
            cfg = load_receiver_config(config, [("vector.enabled", True), ("vector.variant", variant),
                                                ("tracking.max_channels", channels),
                                                ("vector.add_predicted", False),
                                                ("output.path", os.path.join(tmp, "bench.h5")), *extra])
            t0 = time.perf_counter()
            summary = run(cfg, quiet=True, log=lambda *a: None)
            total = time.perf_counter() - t0
    finally:
        T.VectorTracker.process = orig
    timing["total_wall"] = total
    timing["duration"] = summary.duration_s
    return timing


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default=os.path.join(REPO, "configs", "vector_tokyo.yaml"))
    ap.add_argument("--channels", type=int, default=8)
    ap.add_argument("--variants", default="fixed_r,adaptive_r,polynomial,cv")
    ap.add_argument("--start-s", type=float, default=None, help="override vector.start_s")
    args = ap.parse_args(argv)
    os.chdir(REPO)
    extra = [] if args.start_s is None else [("vector.start_s", args.start_s)]
    bench(args.config, "fixed_r", args.channels, extra)          # warm-up: numba compilation / cache
    print(f"load average {os.getloadavg()[0]:.1f} (wall-clock figures mean little on a shared machine; "
          "RTF/CPU = signal / CPU seconds in the tracker)")
    print(f"{'variant':<12} {'channels':>8} {'vector s':>9} {'wall s':>7} {'RTF':>6} {'CPU s':>6} {'RTF/CPU':>7}"
          f"   (whole run: signal / wall)")
    for v in args.variants.split(","):
        t = bench(args.config, v.strip(), args.channels, extra)
        ch = max(t["channels"]) if t["channels"] else 0
        rtf = t["signal"] / t["wall"] if t["wall"] > 0 else float("nan")
        rtc = t["signal"] / t["cpu"] if t["cpu"] > 0 else float("nan")
        print(f"{v:<12} {ch:>8d} {t['signal']:>9.2f} {t['wall']:>7.2f} {rtf:>6.2f} {t['cpu']:>6.2f} {rtc:>7.2f}   "
              f"({t['duration']:.1f} s / {t['total_wall']:.1f} s)")


if __name__ == "__main__":
    main()
