#!/usr/bin/env python3
"""Carrier-loop plugins against the built-ins: CPU time of the channels' epoch loop per second of signal.

Tracks the same block with fresh channels for each loop, one thread, and prints the median over
``--repeat`` runs of the CPU seconds per signal second, and each plugin's ratio to the built-in it is
compared with.  Loops: the built-in cpll_atan (compiled twin), the same algorithm as a plugin through the
public interface (tests/unit/tracking/plugins/cpll_again.py, compiled path), the example plugin fll_pll
(docs/examples/gnssrx-fll-pll, compiled path) and, for scale, the kernel's own PLL and cpll_atan stepped from
Python.  Uses the reference recording (../shared/data/gpssim_static_tokyo.bin) when present, else a
synthetic signal.  No acquisition, navigation or file output: only tracking.

    python scripts/bench/bench_plugin.py [--seconds 10] [--channels 8] [--repeat 3] [--recording FILE]
"""
import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "unit" / "tracking" / "plugins"),
                str(ROOT / "docs" / "examples" / "gnssrx-fll-pll" / "src")]

import numpy as np  # noqa: E402

from receiver.gnss.signals import CA_CHIP_RATE, L1_HZ, ca_code, sample_code  # noqa: E402
from receiver.schema import load_receiver_config  # noqa: E402
from receiver.threads import set_threads  # noqa: E402
from receiver.tracking.scalar import Channel  # noqa: E402

FS = 2.6e6
SHARED = ROOT.parent / "shared" / "data" / "gpssim_static_tokyo.bin"
# PRN, Doppler, code phase at sample 0 (chips) of the reference recording
REF = [(23, -1867.2, 476.88), (10, 727.1, 930.93), (12, 1007.3, 76.33), (24, -2687.7, 877.03),
       (15, -3357.4, 489.47), (25, 2705.0, 982.87), (32, 1979.0, 131.02), (18, -3658.1, 597.27)]
LOOPS = [  # (label, variant, compare with, python-stepped)
    ("pll (kernel)", "pll", None, False),
    ("cpll_atan (built-in)", "cpll_atan", None, False),
    ("cpll_again (plugin)", "cpll_again:CpllAgain", "cpll_atan (built-in)", False),
    ("fll_pll (plugin)", "gnssrx_fll_pll:FllPll", "cpll_atan (built-in)", False),
    ("cpll_atan (Python-stepped)", "cpll_atan", "cpll_atan (built-in)", True),
]


def signal(seconds, path):
    n = int(seconds * FS)
    if path.exists():
        raw = np.memmap(path, np.int8, "r")[:2 * n]
        return (raw[0::2] + 1j * raw[1::2]).astype(np.complex64), "reference recording"
    rng = np.random.default_rng(1)
    x = (rng.normal(size=n) + 1j * rng.normal(size=n)).astype(np.complex64) * 4
    t = np.arange(n) / FS
    for prn, dop, cp in REF:
        code = sample_code(ca_code(prn), CA_CHIP_RATE * (1 + dop / L1_HZ), FS, n, cp)
        x += (0.6 * code * np.exp(2j * np.pi * dop * t)).astype(np.complex64)
    return x, "synthetic signal"


def cpu_per_signal_s(x, sats, variant, python_loop):
    cfg = load_receiver_config(None, [("tracking.carrier.variant", variant)])
    chans = [Channel(p, d, c, 0, cfg.tracking, FS, 0.0) for p, d, c in sats]
    for ch in chans:
        ch.use_compiled_loop = ch.use_compiled_loop and not python_loop
    chunk, pad = int(0.5 * FS), int(0.03 * FS)
    c0 = time.process_time()
    for start in range(0, len(x) - chunk, chunk):
        for ch in chans:
            s = ch.next_sample if start else 0
            ch.process(x[s:start + chunk + pad], s)
    return (time.process_time() - c0) / (len(x) / FS)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--channels", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--recording", type=Path, default=SHARED, help="int8 I/Q at 2.6 MS/s (default: the "
                    "reference recording; absent: a synthetic signal)")
    args = ap.parse_args()
    set_threads(1)
    x, what = signal(args.seconds, args.recording)
    sats = REF[:args.channels]
    warm = x[:int(3 * FS)]
    for _, variant, _, py in LOOPS:                 # compile / load the caches, hand-over included
        cpu_per_signal_s(warm, sats[:1], variant, py)
    res = {}
    for _ in range(args.repeat):                    # interleaved: a load change hits every loop alike
        for label, variant, _, py in LOOPS:
            res.setdefault(label, []).append(cpu_per_signal_s(x, sats, variant, py))
    print(f"{what}, {args.seconds:g} s, {len(sats)} channels, 1 thread, median of {args.repeat}")
    print(f"{'loop':<28} {'CPU s / signal s':>17} {'ratio':>7}")
    med = {k: statistics.median(v) for k, v in res.items()}
    for label, _, ref, _ in LOOPS:
        ratio = f"{med[label] / med[ref]:7.2f}" if ref else ""
        print(f"{label:<28} {med[label]:17.4f} {ratio:>7}")


if __name__ == "__main__":
    main()
