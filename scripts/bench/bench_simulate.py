#!/usr/bin/env python
"""Simulator speed: seconds of signal generated per wall-clock second.

10 satellites with signal, 2.6 MS/s complex int8, embedded constellation, noise on, one core
(run with NUMBA_NUM_THREADS=1; the simulator itself is single-threaded).  The first, short run compiles /
loads the numba kernels and is not timed.

    NUMBA_NUM_THREADS=1 python scripts/bench/bench_simulate.py [--duration 20]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time


from receiver.sim.simulate import simulate  # noqa: E402

SCENARIO = {
    "time": {"gps_week": 2300, "tow_s": 345600.0, "seed": 7},
    "constellation": {"source": "embedded", "elevation_mask_deg": -5.0},
    "receiver": {"trajectory": "static", "lat_deg": 46.5197, "lon_deg": 6.6323, "height_m": 400.0},
    "clock": {"freq_error_ppm": 0.5, "noise": "tcxo"},
    "cn0": {"mode": "constant", "dbhz": 45.0},
    "blockage": {"visible_count": [[0.0, 10]]},          # exactly the 10 highest satellites
    "frontend": {"sample_rate_hz": 2.6e6, "format": "int8_iq", "if_hz": 0.0},
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="seconds of signal timed")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "bench.bin")
        simulate(SCENARIO, out, overrides=["time.duration_s=0.2"], progress=False)      # warm-up
        t, c = time.perf_counter(), time.process_time()
        paths = simulate(SCENARIO, out, overrides=[f"time.duration_s={args.duration}"], progress=False)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        from receiver.runfile.truth import TruthFile
        with TruthFile(paths["truth"]) as tf:
            vis = [s["visible"] for s in tf.satellites(("visible",)).values()]
        n_sig = max(int(sum(v[i] for v in vis)) for i in range(0, vis[0].size, 100))
    threads = os.environ.get("NUMBA_NUM_THREADS", "(unset)")
    print(f"simulate: {args.duration:.1f} s of signal, {n_sig} satellites, 2.6 MS/s int8_iq in {wall:.2f} s "
          f"wall (NUMBA_NUM_THREADS={threads})")
    print(f"speed: {args.duration / wall:.2f} x real time (wall clock); {args.duration / cpu:.2f} x real time "
          f"per CPU second ({cpu:.2f} s CPU; the two differ when the machine is shared)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
