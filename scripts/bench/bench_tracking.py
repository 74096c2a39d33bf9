#!/usr/bin/env python3
"""Tracking real-time factor: seconds of signal tracked per second of wall time, 8 channels, 1 and N threads.

Uses the third-party recording (../shared/data/gpssim_static_tokyo.bin) when present, else a synthetic
2.6 MS/s int8-like signal with 8 satellites.  Acquisition, HDF5 output and navigation are excluded: only
the channels' epoch loop (correlators, discriminators, loop filters) is timed, first on one thread and
then on all cores (channels in parallel, as ``gnssrx run`` does); "per CPU second" is the one-core figure.

    python scripts/bench/bench_tracking.py [--seconds 20] [--channels 8]
           [--carrier pll|cpll_atan|ekf|pli_ekf|kf|adaptive_kf] [--threads 1,2] [--python-loop]
"""
import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from receiver.schema import load_receiver_config  # noqa: E402
from receiver.gnss.signals import CA_CHIP_RATE, L1_HZ, ca_code, sample_code  # noqa: E402
from receiver.threads import cores, map_ordered, set_threads  # noqa: E402
from receiver.tracking.scalar import Channel  # noqa: E402

FS = 2.6e6
SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "gpssim_static_tokyo.bin"
# PRN, Doppler, code phase at sample 0 (chips) of the reference recording (from `gnssrx acquire`)
REF = [(23, -1867.2, 476.88), (10, 727.1, 930.93), (12, 1007.3, 76.33), (24, -2687.7, 877.03),
       (15, -3357.4, 489.47), (25, 2705.0, 982.87), (32, 1979.0, 131.02), (18, -3658.1, 597.27),
       (13, -3515.0, 349.39), (19, 381.4, 378.51)]


def synthetic(seconds, sats):
    n = int(seconds * FS)
    rng = np.random.default_rng(1)
    x = (rng.normal(size=n) + 1j * rng.normal(size=n)).astype(np.complex64) * 4
    t = np.arange(n) / FS
    for prn, dop, cp in sats:
        code = sample_code(ca_code(prn), CA_CHIP_RATE * (1 + dop / L1_HZ), FS, n, cp)
        x += (0.6 * code * np.exp(2j * np.pi * dop * t)).astype(np.complex64)
    return x


def measure(x, sats, cfg, n_threads, python_loop=False):
    """Track x with fresh channels on n_threads threads; (signal s, wall s, CPU s, channel-epochs, locked)."""
    set_threads(n_threads)
    chans = [Channel(p, d, c, 0, cfg.tracking, FS, 0.0) for p, d, c in sats]
    for ch in chans:
        ch.use_compiled_loop = ch.use_compiled_loop and not python_loop
    warm = int(0.1 * FS)
    for ch in chans:                      # JIT warm-up (cached after the first run)
        ch.process(x[:warm], 0)
    chunk = int(0.5 * FS)
    end_pad = int(0.03 * FS)
    t0 = time.perf_counter()
    c0 = time.process_time()
    n_epochs = 0
    for start in range(warm, len(x) - chunk, chunk):
        # channels are behind `start` by < 1 ms after warm-up; give them the block from their sample
        def run(ch):
            s = ch.next_sample
            return len(ch.process(x[s:start + chunk + end_pad], s))
        n_epochs += sum(map_ordered(run, chans))
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    sig = (len(x) - warm - chunk) / FS
    return sig, wall, cpu, n_epochs, sum(not ch.lost for ch in chans)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--channels", type=int, default=8)
    ap.add_argument("--carrier", default="pll", help="tracking.carrier.variant (default: the built-in pll)")
    ap.add_argument("--threads", default=f"1,{cores()}",
                    help="comma-separated thread counts, measured one after the other (default: 1 and all "
                         "cores)")
    ap.add_argument("--python-loop", action="store_true",
                    help="also measure the carrier loop stepped from Python (the reference implementation)")
    args = ap.parse_args()
    sats = REF[:args.channels]
    if SHARED.exists():
        raw = np.memmap(SHARED, np.int8, "r")[:int(2 * args.seconds * FS)]
        x = (raw[0::2] + 1j * raw[1::2]).astype(np.complex64)
        src = "reference recording"
    else:
        x = synthetic(args.seconds, sats)
        src = "synthetic signal"
    cfg = load_receiver_config(None, [("tracking.carrier.variant", args.carrier)])
    print(f"source: {src}; {len(sats)} channels at {FS / 1e6:.1f} MS/s; carrier loop {args.carrier}; "
          f"{cores()} cores; load average {os.getloadavg()[0]:.1f} (wall-clock figures are only meaningful "
          "on an otherwise idle machine)")
    for n in [int(v) for v in args.threads.split(",")]:
        sig, wall, cpu, n_epochs, locked = measure(x, sats, cfg, n)
        print(f"threads {n}: signal {sig:.1f} s, wall {wall:.2f} s, CPU {cpu:.2f} s, {n_epochs} channel-epochs, "
              f"{locked} still locked")
        print(f"  tracking real-time factor: {sig / wall:.1f}x wall clock, {sig / cpu:.1f}x per CPU second "
              f"({cpu / n_epochs * 1e6:.1f} us CPU per channel-epoch)")
    if args.python_loop and args.carrier != "pll":
        sig, wall, cpu, n_epochs, locked = measure(x, sats, cfg, 1, python_loop=True)
        print(f"Python-stepped loop, threads 1: wall {wall:.2f} s, CPU {cpu:.2f} s: {sig / wall:.1f}x wall clock, "
              f"{sig / cpu:.1f}x per CPU second ({cpu / n_epochs * 1e6:.1f} us CPU per channel-epoch)")


if __name__ == "__main__":
    main()
