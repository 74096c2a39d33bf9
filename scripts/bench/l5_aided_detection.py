#!/usr/bin/env python3
"""GPS L5 (Q5 + NH20) detection versus C/N0: the search aided by the L1 channel (a few code phases around
the prediction, the L1 Doppler) against the full search (every code phase, +/- ``--doppler`` Hz), the same
statistic and integration (``--ms`` 1-ms correlations summed non-coherently, pfa 1e-3 over the cells
searched), on synthetic complex signals at ``--fs`` with random code phase, Doppler and NH20 phase.

    python scripts/bench/l5_aided_detection.py [--trials 20] [--ms 10] [--fs 10.23e6] [--doppler 5000]
"""
from __future__ import annotations

import argparse

import numpy as np

from receiver.acquisition.aided import search
from receiver.gnss.l5_codes import nh_signs
from receiver.gnss.signals_l5 import GPS_L5


def signal(rng, fs, n_ms, prn, cn0, code_phase, doppler, ms0):
    """Q5 x NH20 plus unit-variance complex noise (C/N0 = A^2 fs / 2)."""
    n = int(fs * 1e-3) * (n_ms + 1)
    t = np.arange(n) / fs
    chips = code_phase + t * GPS_L5.chip_rate * (1 + doppler / GPS_L5.carrier_hz)
    s = GPS_L5.code(prn)[np.floor(chips).astype(np.int64) % 10230] * \
        nh_signs(20)[(ms0 + (chips // 10230).astype(np.int64)) % 20]
    x = np.sqrt(2 * 10 ** (cn0 / 10) / fs) * s * np.exp(2j * np.pi * doppler * t)
    return (x + rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--ms", type=int, default=10)
    ap.add_argument("--fs", type=float, default=10.23e6)
    ap.add_argument("--doppler", type=float, default=5000.0)
    ap.add_argument("--cn0", type=float, nargs="*", default=[45, 40, 38, 36, 35, 34, 32, 30])
    a = ap.parse_args()
    rng = np.random.default_rng(38)
    print(f"{a.trials} trials per row, {a.ms} x 1 ms non-coherent, fs {a.fs / 1e6:g} MS/s, pfa 1e-3 per search")
    print(f"{'C/N0':>6} {'aided':>8} {'full':>8}   (detected at the right code phase)")
    for cn0 in a.cn0:
        hits = [0, 0]
        for _ in range(a.trials):
            prn = int(rng.integers(1, 33))
            cp, dop, ms0 = rng.uniform(0, 10230), rng.uniform(-4000, 4000), int(rng.integers(0, 20))
            x = signal(rng, a.fs, a.ms, prn, cn0, cp, dop, ms0)
            pred = (cp + rng.normal(0, 1.0)) % 10230          # the L1 prediction (group-delay difference)
            for k, r in enumerate((search(x, a.fs, 0.0, GPS_L5, prn, dop, 0.0, pred, 5.0, a.ms),
                                   search(x, a.fs, 0.0, GPS_L5, prn, 0.0, a.doppler, None, n_ms=a.ms))):
                err = abs((r.code_phase_chips - cp + 5115) % 10230 - 5115)
                hits[k] += bool(r.detected and err < 1.5)
        print(f"{cn0:>6.1f} {hits[0] / a.trials:>8.0%} {hits[1] / a.trials:>8.0%}")


if __name__ == "__main__":
    main()
