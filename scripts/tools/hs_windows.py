"""3D position error of hs runs over time windows (issue 17's scalar-vs-vector table).

    python scripts/tools/hs_windows.py out/hs/fig8_33_s1.truth.h5 out/hs/fig8_33_s1_scalar.h5 out/hs/fig8_33_s1_cv.h5

Per run: first fix, 3D RMS from the first fix to the end, from 5 s after it (the default vector hand-over,
vector.start_s empty) to 40 s, from 40 s to the end, max, mean satellites per fix and 3D velocity RMS.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np


from receiver.estimation.interpolation import interp_columns  # noqa: E402
from receiver.runfile.reader import RunFile  # noqa: E402


def windows(run, truth):
    import h5py
    with h5py.File(truth) as f:
        r = f["receiver"]
        tt, pos, vel = r["gps_tow"][:], r["ecef"][:], r["velocity_ecef"][:]
    with RunFile(run) as rf:
        fx = rf.fixes()
    if not len(fx):
        return None
    t = fx["gps_tow"] - tt[0]
    err = np.linalg.norm(fx["ecef"] - interp_columns(tt, pos, fx["gps_tow"]), axis=1)
    verr = np.linalg.norm(fx["velocity_ecef"] - interp_columns(tt, vel, fx["gps_tow"]), axis=1)
    ff = float(t[0])

    def rms(m):
        return float(np.sqrt(np.mean(err[m] ** 2))) if m.any() else float("nan")
    return {"ttff": ff, "all": rms(t >= ff), "hand_40": rms((t >= ff + 5.0) & (t < 40.0)),
            "40_end": rms(t >= 40.0), "max": float(err.max()), "sats": float(np.mean(fx["n_sats"])),
            "vel": float(np.sqrt(np.nanmean(verr ** 2)))}


def main():
    truth, runs = sys.argv[1], sys.argv[2:]
    print("run | first fix | 3D RMS all | hand-over..40 s | 40 s..end | max | sats/fix | vel RMS")
    for run in runs:
        w = windows(run, truth)
        if w is None:
            print(f"{run} | no fix")
            continue
        print(f"{Path(run).name} | {w['ttff']:.1f} | {w['all']:.2f} | {w['hand_40']:.2f} | {w['40_end']:.2f} | "
              f"{w['max']:.1f} | {w['sats']:.2f} | {w['vel']:.3f}")


if __name__ == "__main__":
    main()
