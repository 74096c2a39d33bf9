"""C/N0 loss of each input format: the same static scenario (same seed, so the same noise before
quantisation) simulated in each format, received, and the median C/N0 of every channel (after 2 s)
compared with the complex64 recording.

    .venv/bin/python scripts/bench/format_loss.py [--duration 10] [--formats complex64,int8_iq,packed2_iq,...]

Prints one row per format: PRNs acquired / simulated and the mean C/N0 loss (dB) against complex64.
"""
import argparse
import os
import tempfile

import h5py
import numpy as np

from receiver.schema import load_receiver_config
from receiver.pipeline import run
from receiver.sim.simulate import simulate
from receiver.source.io import FORMATS

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PRNS = [1, 6, 9, 12]


def measure(fmt, duration, d):
    f = FORMATS[fmt]
    real = not f.complex
    ov = [("time.duration_s", duration), ("constellation.prns", PRNS), ("cn0.dbhz", 45.0),
          ("clock.noise", "none"), ("frontend.format", fmt),
          ("frontend.sample_rate_hz", 5.2e6 if real else 2.6e6), ("frontend.if_hz", 1.3e6 if real else 0.0)]
    paths = simulate(os.path.join(ROOT, "configs/scenarios/static_default.yaml"), os.path.join(d, fmt + ".bin"),
                     ov, progress=False)
    out = os.path.join(d, fmt + ".h5")
    cfg = load_receiver_config(paths["yaml"], [("output.path", out), ("navigation.enabled", False),
                                               ("acquisition.prns", PRNS + [3, 20])])
    run(cfg, quiet=True, log=lambda *a: None)
    cn0 = {}
    with h5py.File(out) as h:
        for name, g in h["channels"].items():
            t = g["time_s"][:]
            m = (t > 2.0) & (g["pll_lock"][:] > 0)
            cn0[int(name[1:])] = float(np.median(g["cn0_dbhz"][:][m])) if m.any() else float("nan")
    for p in paths.values():
        if os.path.exists(p):
            os.remove(p)
    os.remove(out)
    return cn0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--formats", default=",".join(FORMATS))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        ref = measure("complex64", a.duration, d)
        print(f"{'format':14s} {'acquired':>9s} {'C/N0':>6s} {'loss dB':>8s}")
        print(f"{'complex64':14s} {len(ref):>5d}/{len(PRNS)} {np.mean(list(ref.values())):6.2f} {0.0:8.2f}")
        for fmt in a.formats.split(","):
            if fmt == "complex64":
                continue
            c = measure(fmt, a.duration, d)
            common = [p for p in PRNS if p in c and p in ref]
            loss = np.mean([ref[p] - c[p] for p in common]) if common else float("nan")
            print(f"{fmt:14s} {len(set(c) & set(PRNS)):>5d}/{len(PRNS)} {np.mean(list(c.values())):6.2f} "
                  f"{loss:8.2f}  extra PRNs: {sorted(set(c) - set(PRNS)) or '-'}", flush=True)
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
