#!/usr/bin/env python3
"""`gnssrx probe` on front-end variants of the reference recording and on the real recordings.

From 1.5 s of ../shared/data/gpssim_static_tokyo.bin (int8 I/Q, 2.6 MS/s; from 1 s in) it writes 18
variants -- other sample formats, packings, bit orders, encodings, rates, a real IF, swapped I/Q, an
inverted spectrum, an oscillator offset, low gain, DC + a CW tone -- into --out, then runs the probe on
each and on every recording of ../shared/data/real/, and prints whether format, rate, IF and (where the
truth is known) the spectrum's sign were named right, the satellites found and the probe's time:

    PYTHONPATH=. python scripts/bench/probe_acceptance.py [--shared DIR] [--out /tmp/probe_variants] [--keep]

Truth of the real recordings: ../shared/data/real/README.md (the table below copies format, rate, IF).
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)

from receiver.source.io import NOISE_SIGMA, quantize  # noqa: E402

SHARED = os.path.join(ROOT, "..", "shared", "data")
FS = 2.6e6

#: real recordings: file -> (format, rate, IF, iq_swap or None when the README does not say)
REAL = {
    "pocketsdr_L1_20211202_084700_4MHz_IQ.bin": ("int8_iq", 4e6, 0.0, True),
    "pocketsdr_L1_20211125_004000_12MHz_I.bin": ("int8_real", 12e6, 3.0e6, None),
    "pocketsdr_L1_20211201_054600_24MHz_I.bin": ("int8_real", 24e6, 6.0e6, None),
    "pysdr_GPS_L1_recording_10ms_4MHz_cf32.iq": ("complex64", 4e6, 0.0, None),
    "peregrine_test_samples.dat": ("int8_real", 16.368e6, 4.092e6, None),
    "gnsssdr_GSoC_CTTC_capture_2012_07_26_4Msps_4ms.dat": ("complex64", 4e6, 0.0, None),
}


def _write(path, y, fmt, **kw):
    if fmt.endswith(("_iq", "complex64")):
        scale = NOISE_SIGMA[fmt] / np.sqrt(np.mean(np.abs(y) ** 2) / 2)
    else:
        scale = NOISE_SIGMA[fmt] / np.std(np.real(y))
    quantize(y, fmt, scale, **kw).tofile(path)


def variants(ref: str, out: str, dur: float = 1.5) -> dict:
    """Write the variants; name -> (path, format, rate, IF, iq_swap, bit_order or None, encoding or None)."""
    from scipy.signal import resample_poly
    raw = np.fromfile(ref, np.int8, count=int(2 * FS * dur), offset=int(2 * FS))
    x = (raw[0::2] + 1j * raw[1::2]).astype(np.complex128)
    sig = np.sqrt(np.mean(np.abs(x) ** 2) / 2)
    n = np.arange(len(x))
    up4 = resample_poly(x, 4, 1)
    real104 = np.real(up4 * np.exp(2j * np.pi * 0.25 * np.arange(len(up4))))       # IF 2.6 MHz at 10.4 MS/s
    y8 = resample_poly(x, 40, 13)
    inv8 = np.real(np.conj(y8) * np.exp(2j * np.pi * 0.25 * np.arange(len(y8))))   # inverted, IF 2 MHz at 8
    cases = {
        "int8_iq": (x, "int8_iq", FS, 0.0, False, {}),
        "int16_iq": (x, "int16_iq", FS, 0.0, False, {}),
        "uint8_iq": (x, "uint8_iq", FS, 0.0, False, {}),
        "packed2_iq": (x, "packed2_iq", FS, 0.0, False, {}),
        "complex64": (x, "complex64", FS, 0.0, False, {}),
        "swapped_iq": (x.imag + 1j * x.real, "int8_iq", FS, 0.0, True, {}),
        "uint8_2.4": (resample_poly(x, 12, 13), "uint8_iq", 2.4e6, 0.0, False, {}),
        "int16_5.0": (resample_poly(x, 25, 13), "int16_iq", 5.0e6, 0.0, False, {}),
        "int8_real_10.4": (real104, "int8_real", 10.4e6, 2.6e6, False, {}),
        "packed2_real_10.4": (real104, "packed2_real", 10.4e6, 2.6e6, False, {}),
        "float32_real_10.4": (real104, "float32_real", 10.4e6, 2.6e6, False, {}),
        "packed2_iq_lsb_twos": (x, "packed2_iq", FS, 0.0, False,
                                {"bit_order": "lsb_first", "encoding": "twos_complement"}),
        "int8_4.0": (resample_poly(x, 20, 13), "int8_iq", 4.0e6, 0.0, False, {}),
        "lo_+4k": (x * np.exp(2j * np.pi * 4000 / FS * n), "int8_iq", FS, 0.0, False, {}),
        "low_gain": (x / sig * 0.6, None, FS, 0.0, False, {}),
        "dc_spur": (x / sig + 0.5 * (1 + 1j) / np.sqrt(2) + 10 ** (15 / 20) * np.exp(2j * np.pi * 250e3 / FS * n),
                    "int8_iq", FS, 0.0, False, {}),
        "packed2_real_lsb_twos": (real104, "packed2_real", 10.4e6, 2.6e6, False,
                                  {"bit_order": "lsb_first", "encoding": "twos_complement"}),
        "int16_real_inverted_8": (inv8, "int16_real", 8.0e6, 2.0e6, True, {}),
    }
    os.makedirs(out, exist_ok=True)
    out_cases = {}
    for name, (y, fmt, fs, if_hz, swap, kw) in cases.items():
        path = os.path.join(out, f"{name}.bin")
        if fmt is None:                              # low gain: 0.6 LSB of noise, int8
            quantize(y, "int8_iq", 1.0).tofile(path)
            fmt = "int8_iq"
        else:
            _write(path, y, fmt, **kw)
        out_cases[name] = (path, fmt, fs, if_hz, swap, kw.get("bit_order"), kw.get("encoding"))
    return out_cases


def check(path, fmt, fs, if_hz, swap, bit_order=None, encoding=None) -> tuple[str, str, float]:
    from receiver.probe.search import probe
    t0 = time.perf_counter()
    r = probe(path)
    dt = time.perf_counter() - t0
    if r.best is None:
        return "nothing found", "", dt
    c = r.config()
    got_if = c["if_hz"] if not c.get("iq_swap") or fmt.endswith(("_iq", "complex64")) else fs / 2 - c["if_hz"]
    ok = c["format"] == fmt and abs(c["sample_rate_hz"] - fs) < 1.0 and abs(got_if - if_hz) < 1.0
    ok = ok and (bit_order is None or c.get("bit_order") == bit_order) and \
        (encoding is None or c.get("encoding") == encoding)
    sign = "" if swap is None else ("sign ok" if bool(c.get("iq_swap")) == swap else
                                    ("sign ?" if r.iq_swap is None else "SIGN WRONG"))
    what = f"{c['format']} {c['sample_rate_hz'] / 1e6:g} MS/s IF {got_if / 1e6:g} MHz"
    return ("ok   " if ok else "WRONG") + f" {what} {sign}", " ".join(str(s.prn) for s in r.best.found), dt


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--shared", default=SHARED, help="the shared data directory (default: ../shared/data)")
    ap.add_argument("--out", default="/tmp/probe_variants")
    ap.add_argument("--keep", action="store_true", help="keep the variant files")
    a = ap.parse_args()
    ref = os.path.join(a.shared, "gpssim_static_tokyo.bin")
    if not os.path.exists(ref):
        sys.exit(f"{ref} absent")
    rows = []
    for name, args in variants(ref, a.out).items():
        rows.append((name,) + check(*args))
    for name, (fmt, fs, if_hz, swap) in REAL.items():
        p = os.path.join(a.shared, "real", name)
        if os.path.exists(p):
            rows.append((name[:40],) + check(p, fmt, fs, if_hz, swap))
    for name, verdict, sats, dt in rows:
        print(f"{name:42s} {dt:5.1f} s  {verdict:55s} {sats}")
    n_ok = sum(r[1].startswith("ok") for r in rows)
    print(f"{n_ok} of {len(rows)} named right")
    if not a.keep:
        shutil.rmtree(a.out, ignore_errors=True)


if __name__ == "__main__":
    main()
