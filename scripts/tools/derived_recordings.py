#!/usr/bin/env python3
"""The third-party reference recording turned into what other front ends deliver, each run and scored.

The outside recording (../shared/data/gpssim_static_tokyo.bin: GPS-SDR-SIM, int8 I/Q, 2.6 MS/s, static
antenna with a surveyed position) is the only file with truth that our own simulator did not make.  This
script derives front-end variants from it (the same signal and noise, so any change in the result is the
receiver's handling of the format, rate, quantisation or impairment), runs ``gnssrx run`` on each with the
reference config plus the variant's input keys, and prints satellites tracked, first fix, fixes and 3D
RMS / max against the published position:

    original       int8 I/Q 2.6 MS/s, as recorded
    2bit_iq        packed 2-bit I/Q (sign-magnitude, MSB first)
    rtl_2.4        uint8 offset-binary I/Q at 2.4 MS/s (RTL-SDR style; resampled 12/13, band cut to +/-1.2 MHz)
    int16_5.0      int16 I/Q at 5.0 MS/s (resampled 25/13)
    real_if_10.4   int8 real IF at 10.4 MS/s, IF 2.6 MHz (x4 and mixed up; the decimating input stage)
    2bit_real_10.4 packed 2-bit real IF at 10.4 MS/s, IF 2.6 MHz
    lo_+4k         every carrier 4 kHz off (an oscillator 2.5 ppm off), with if_hz left at 0
    late_9.7       the first 9.7 s cut off (the receiver starts mid-subframe; start time moved accordingly)
    dc_spur        a DC offset (0.5 sigma) and a CW tone 250 kHz off the carrier at +15 dB over the noise
    low_gain       int8 I/Q scaled to 0.6 LSB of noise (mostly -1, 0, +1: a front end with its gain set low)

    PYTHONPATH=. python scripts/tools/derived_recordings.py [--out out/derived] [--cases a,b] [--keep]

Derived files are written in ~1-s chunks (resampling by polyphase filtering over overlapping chunks), take
0.2-0.9 GB each and are deleted after their run unless --keep.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from receiver.source.io import NOISE_SIGMA, SampleWriter  # noqa: E402

SHARED = os.path.join(ROOT, "..", "shared", "data")
REF = os.path.join(SHARED, "gpssim_static_tokyo.bin")
CONFIG = os.path.join(ROOT, "configs", "gpssim_static_tokyo.yaml")
FS = 2.6e6
TOW0 = 525584.0
TRUTH = np.array([-3959617.482, 3350136.615, 3699531.459])
CHUNK = 13 * 20000                     # input samples per chunk (0.1 s; a multiple of 13 for the 20/13 ratios)
PAD = 13 * 40                          # overlap on each side (filter transients stay inside it)

# name: (format, up, down, if_hz of the output, extra ops)
CASES = {
    "original": None,
    "2bit_iq": ("packed2_iq", 1, 1, 0.0, {}),
    "rtl_2.4": ("uint8_iq", 12, 13, 0.0, {}),
    "int16_5.0": ("int16_iq", 25, 13, 0.0, {}),
    "real_if_10.4": ("int8_real", 4, 1, 2.6e6, {}),
    "2bit_real_10.4": ("packed2_real", 4, 1, 2.6e6, {}),
    "lo_+4k": ("int8_iq", 1, 1, 0.0, {"shift_hz": 4000.0}),
    "late_9.7": ("int8_iq", 1, 1, 0.0, {"skip_s": 9.7}),
    "dc_spur": ("int8_iq", 1, 1, 0.0, {"dc": 0.5, "tone_hz": 250e3, "tone_db": 15.0}),
    "low_gain": ("int8_iq", 1, 1, 0.0, {"sigma": 0.6}),
}


def _noise_sigma(raw: np.ndarray) -> float:
    return float(np.sqrt(np.mean(raw.astype(np.float64) ** 2)))


def derive(name: str, path: str):
    """Write the derived recording; returns the --set overrides for it."""
    from scipy.signal import resample_poly

    fmt, up, down, if_out, ops = CASES[name]
    total = os.path.getsize(REF) // 2
    skip = int(round(ops.get("skip_s", 0.0) * FS))
    sig_in = _noise_sigma(np.fromfile(REF, np.int8, count=2 * 2_600_000))          # ~ the noise (C/N0 45)
    fs_out = FS * up / down
    real = if_out != 0.0
    sigma_out = ops.get("sigma", NOISE_SIGMA[fmt])
    # complex noise of sigma per component; the real part of (x e^{jwt}) keeps that sigma per sample and the
    # signal-to-noise ratio
    scale = sigma_out / sig_in
    n_out0 = 0
    with SampleWriter(path, fmt, 1.0) as w:
        a = skip
        while a < total:
            b = min(a + CHUNK, total)
            lo, hi = max(a - PAD, skip), min(b + PAD, total)
            raw = np.fromfile(REF, np.int8, count=2 * (hi - lo), offset=2 * lo).astype(np.float64)
            x = raw[0::2] + 1j * raw[1::2]
            if up != 1 or down != 1:
                y = resample_poly(x, up, down)
                k0 = (a - lo) * up // down
                y = y[k0:k0 + (b - a) * up // down]
            else:
                y = x[a - lo:b - lo]
            n = np.arange(n_out0, n_out0 + len(y))
            t = n / fs_out
            if "shift_hz" in ops:
                y = y * np.exp(2j * np.pi * ops["shift_hz"] * t)
            y = y * scale
            if "dc" in ops:
                y = y + ops["dc"] * sigma_out * (1 + 1j)
                amp = sigma_out * np.sqrt(2.0) * 10 ** (ops["tone_db"] / 20.0)
                y = y + amp * np.exp(2j * np.pi * ops["tone_hz"] * t + 0.3)
            if real:
                y = np.real(y * np.exp(2j * np.pi * if_out * t))
            w.write(y)
            n_out0 += len(y)
            a = b
    sets = [f"input.format={fmt}", f"input.sample_rate_hz={fs_out:.1f}", f"input.if_hz={if_out:.1f}",
            f"input.start_gps_tow_s={TOW0 + skip / FS:.9f}"]
    return sets


def score(h5: str):
    import h5py
    with h5py.File(h5, "r") as f:
        g = f["navigation"]
        pos = np.stack([g[k][:] for k in ("x_m", "y_m", "z_m")], 1) if "x_m" in g else g["ecef"][:]
        t = g["time_s"][:]
        nsat = len([k for k in f["channels"].keys()]) if "channels" in f else -1
    ok = np.isfinite(pos).all(1)
    if not ok.any():
        return nsat, float("nan"), 0, float("nan"), float("nan")
    e = np.linalg.norm(pos[ok] - TRUTH, axis=1)
    return nsat, float(t[ok][0]), int(ok.sum()), float(np.sqrt(np.mean(e ** 2))), float(e.max())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "derived"))
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--keep", action="store_true", help="keep the derived recordings")
    args = ap.parse_args(argv)
    if not os.path.exists(REF):
        sys.exit(f"derived_recordings: {REF} not found (../shared is needed)")
    os.makedirs(args.out, exist_ok=True)
    gnssrx = [sys.executable, "-m", "receiver.cli"]
    rows = []
    for name in args.cases.split(","):
        name = name.strip()
        t0 = time.time()
        if CASES[name] is None:
            inp, sets = REF, []
        else:
            inp = os.path.join(args.out, f"{name}.bin")
            sets = derive(name, inp)
        t1 = time.time()
        h5 = os.path.join(args.out, f"{name}.h5")
        cmd = gnssrx + ["run", CONFIG, "--input", inp, "-o", h5, "--quiet"]
        for s in sets:
            cmd += ["--set", s]
        p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True,
                           env={**os.environ, "PYTHONPATH": ROOT})
        t2 = time.time()
        if p.returncode != 0:
            rows.append((name, f"run failed: {p.stderr.strip().splitlines()[-1] if p.stderr else p.returncode}"))
        else:
            rows.append((name, score(h5)))
        if inp != REF and not args.keep:
            os.remove(inp)
        print(f"{name}: derived {t1 - t0:.0f} s, run {t2 - t1:.0f} s: {rows[-1][1]}", flush=True)
    print()
    print("| recording | channels | first fix (s after start) | fixes | 3D RMS (m) | max (m) |")
    print("|---|---|---|---|---|---|")
    for name, r in rows:
        if isinstance(r, str):
            print(f"| {name} | {r} | | | | |")
        else:
            print(f"| {name} | {r[0]} | {r[1]:.2f} | {r[2]} | {r[3]:.3f} | {r[4]:.3f} |")


if __name__ == "__main__":
    main()
