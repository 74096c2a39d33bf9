"""Acquisition sensitivity, Monte Carlo: P_detect vs C/N0 for the fast search and the high-sensitivity
pass, and false alarms per 32-PRN search (noise only), with the default acquisition settings.

Each trial synthesises (plain numpy, seeded) one GPS L1 C/A satellite with 50-bps data bits at a random
bit phase, random code phase, Doppler uniform in +/-4 kHz around a common offset of -790 Hz (0.5 ppm) and
a random carrier phase, in complex white noise at 2.6 MS/s; the file is as long as the pass needs (search
dwell + verification dwell).  A detection counts when it is within 1 chip and 1 Doppler bin of the truth.
The fast pass searches +/- 10 kHz around 0 (as the first search of a run); the high-sensitivity pass
searches the offset +/- 5 kHz (its range once satellites are found).  False alarms: noise-only files, all
32 PRNs searched by each pass (any detection is false).

    nice -n 19 python scripts/bench/acq_sensitivity.py --trials 20 --noise-trials 3
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

from receiver.acquisition import reject_cross_correlations, search, verify  # noqa: E402
from receiver.acquisition.high_sensitivity import search_hs  # noqa: E402
from receiver.schema import RECEIVER_SCHEMA  # noqa: E402
from receiver.gnss.signals import CA_CHIP_RATE, CA_CODE_LEN, L1_HZ, ca_code  # noqa: E402

FS = 2.6e6
OFFSET_HZ = -790.0


def _d(section, key):
    return section[key].default


A = RECEIVER_SCHEMA["acquisition"]
HS = A["high_sensitivity"]


def synth(rng, n, prn, cn0, doppler, code_phase):
    t = np.arange(n) / FS
    rate = CA_CHIP_RATE * (1 + doppler / L1_HZ)
    chips = code_phase + t * rate
    code = ca_code(prn)[np.floor(chips).astype(np.int64) % CA_CODE_LEN]
    bits = rng.choice([-1.0, 1.0], size=int(n / FS * 50) + 3)
    period = np.floor(chips / CA_CODE_LEN).astype(np.int64) + int(rng.integers(0, 20))
    amp = np.sqrt(10 ** (cn0 / 10) / FS)
    x = amp * code * bits[period // 20] * np.exp(1j * (2 * np.pi * doppler * t + rng.uniform(0, 2 * np.pi)))
    noise = (rng.normal(size=n) + 1j * rng.normal(size=n)) / np.sqrt(2)
    return (x + noise).astype(np.complex64)


def fast_pass(x, prns):
    m, k = _d(A, "coherent_ms"), _d(A, "noncoherent")
    dwell = int(m * k * 1e-3 * FS)
    res = search(x[:dwell], 0, FS, 0.0, prns, m, k, _d(A, "doppler_max_hz"), None, _d(A, "pfa"),
                 _d(A, "threshold"), width_ratio=_d(A, "width_ratio"))
    for r in res:
        if r.detected and not verify(x[dwell:2 * dwell], dwell, FS, 0.0, r, m, k, None, _d(A, "pfa"),
                                     _d(A, "threshold")):
            r.detected = False
    reject_cross_correlations(res, m, fs=FS)
    return res


def hs_pass(x, prns):
    m, k = _d(HS, "coherent_ms"), _d(HS, "noncoherent")
    n = int(m * k * 1e-3 * FS)
    return search_hs(x[:n], 0, FS, 0.0, prns, m, k, OFFSET_HZ, _d(HS, "sat_doppler_hz"), _d(HS, "pfa"),
                     1.0, _d(A, "width_ratio"), verify_samples=x[n:2 * n], fine=False)


def n_samples(which):
    if which == "fast":
        return 2 * int(_d(A, "coherent_ms") * _d(A, "noncoherent") * 1e-3 * FS)
    return 2 * int(_d(HS, "coherent_ms") * _d(HS, "noncoherent") * 1e-3 * FS)


def correct(r, doppler, code_phase, bin_hz):
    dc = (r.code_phase_chips - code_phase + CA_CODE_LEN / 2) % CA_CODE_LEN - CA_CODE_LEN / 2
    return r.detected and abs(dc) <= 1.0 and abs(r.doppler_hz - doppler) <= bin_hz


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cn0", type=float, nargs="+", default=[24, 26, 28, 30, 32, 34, 36])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--noise-trials", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    bins = {"fast": 1.0 / (2 * _d(A, "coherent_ms") * 1e-3), "hs": 1.0 / (2 * _d(HS, "coherent_ms") * 1e-3)}
    print("| C/N0 (dB-Hz) | fast pass P_detect | high-sensitivity pass P_detect |")
    print("|---|---|---|")
    t0 = time.time()
    for cn0 in a.cn0:
        hits = {"fast": 0, "hs": 0}
        for _ in range(a.trials):
            prn = int(rng.integers(1, 33))
            dop = OFFSET_HZ + rng.uniform(-4000, 4000)
            cp = rng.uniform(0, CA_CODE_LEN)
            x = synth(rng, n_samples("hs"), prn, cn0, dop, cp)
            for which, fn in (("fast", fast_pass), ("hs", hs_pass)):
                r = fn(x[:n_samples(which)], [prn])[0]
                hits[which] += correct(r, dop, cp, bins[which])
        print(f"| {cn0:g} | {hits['fast'] / a.trials:.2f} | {hits['hs'] / a.trials:.2f} |", flush=True)
    fa = {"fast": 0, "hs": 0}
    for _ in range(a.noise_trials):
        x = synth(rng, n_samples("hs"), 1, -100.0, 0.0, 0.0)
        for which, fn in (("fast", fast_pass), ("hs", hs_pass)):
            fa[which] += sum(r.detected for r in fn(x[:n_samples(which)], list(range(1, 33))))
    print(f"\nfalse alarms (noise only, 32 PRNs per search, {a.noise_trials} searches per pass): "
          f"fast {fa['fast']} ({fa['fast'] / max(a.noise_trials, 1):.2f} per search), "
          f"high-sensitivity {fa['hs']} ({fa['hs'] / max(a.noise_trials, 1):.2f} per search)")
    print(f"({a.trials} trials per C/N0, seed {a.seed}, {time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
