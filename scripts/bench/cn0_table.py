#!/usr/bin/env python3
"""Measured vs simulated C/N0: simulate 3 satellites (no clock noise) at each level, receive, print
the median estimate after 2 s of each channel.  (tests/system/test_sim_receiver.py asserts +/- 1 dB.)

    python scripts/bench/cn0_table.py [--levels 30 35 40 45 50] [--seconds 5]
"""
import argparse
import tempfile
from pathlib import Path

import numpy as np

from receiver.schema import load_receiver_config
from receiver.pipeline import run
from receiver.runfile.reader import RunFile
from receiver.sim.simulate import simulate

ROOT = Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=float, nargs="+", default=[30, 35, 40, 45, 50])
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args()
    print("| simulated (dB-Hz) | measured G01 / G06 / G09 (dB-Hz) | worst error (dB) |")
    print("|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        for cn0 in args.levels:
            p = simulate(ROOT / "configs/scenarios/static_default.yaml", Path(d) / "c.bin",
                         [("time.duration_s", args.seconds), ("cn0.dbhz", cn0), ("clock.noise", "none"),
                          ("constellation.prns", [1, 6, 9])], progress=False)
            cfg = load_receiver_config(p["yaml"], [("output.path", str(Path(d) / "c.h5")),
                                                   ("navigation.enabled", False),
                                                   ("acquisition.prns", [1, 6, 9]),
                                                   ("acquisition.noncoherent", 40),
                                                   ("tracking.pll_bw_hz", 15.0), ("tracking.pll_order", 2)])
            run(cfg, quiet=True)
            with RunFile(Path(d) / "c.h5") as rf:
                meds = []
                for name in ("G01", "G06", "G09"):
                    g = rf.channel(name, ("time_s", "pll_lock", "cn0_dbhz"))
                    m = (g["time_s"] > 2.0) & (g["pll_lock"] > 0)
                    meds.append(float(np.median(g["cn0_dbhz"][m])) if m.any() else float("nan"))
            worst = max(abs(m - cn0) for m in meds)
            print(f"| {cn0:.0f} | {' / '.join(f'{m:.2f}' for m in meds)} | {worst:.2f} |")


if __name__ == "__main__":
    main()
