"""Outage scores of a receiver run against simulator truth (total-outage scenarios).

    python scripts/score_outages.py RUN.h5 TRUTH.h5 [--from-s 40] [--good-m 10]

Outages are the spans where fewer than four satellites carry a signal (truth /satellites/*/visible).  For
each outage: its length, the time from the signal's return to the first fix within --good-m of the truth
(fixes with mode 2 = coast never count as good), the largest error of the non-coast fixes in the 10 s after
the return.  Over the whole run (from --from-s): the largest error of the non-coast fixes, the count of coast
fixes and the time of the last fix.  Prints one table; --json writes the numbers.
"""
from __future__ import annotations

import argparse
import json
import sys

import h5py
import numpy as np


def outages(truth):
    sats = truth["satellites"]
    t = None
    cnt = None
    for name in sats:
        g = sats[name]
        tt = g["time_s"][:]
        v = g["visible"][:].astype(int)
        if t is None:
            t, cnt = tt, v.copy()
        else:
            cnt += np.interp(t, tt, v).round().astype(int)
    low = cnt < 4
    spans = []
    i = 0
    while i < len(t):
        if low[i]:
            j = i
            while j + 1 < len(t) and low[j + 1]:
                j += 1
            spans.append((float(t[i]), float(t[j]) + (t[1] - t[0])))
            i = j + 1
        else:
            i += 1
    return spans


def score(run_path, truth_path, from_s=0.0, good_m=10.0):
    with h5py.File(truth_path, "r") as tr, h5py.File(run_path, "r") as rn:
        spans = outages(tr)
        r = tr["receiver"]
        tt, te = r["time_s"][:], r["ecef"][:]
        nav = rn["navigation"]
        tow = nav["gps_tow"][:]
        ecef = nav["ecef"][:]
        mode = nav["mode"][:] if "mode" in nav else np.zeros(len(tow), int)
        nsat = nav["n_sats"][:]
        gtow = r["gps_tow"][:]
    # fixes are time-tagged in GPS time: truth position at that GPS time
    truth_pos = np.stack([np.interp(tow, gtow, te[:, k]) for k in range(3)], axis=1)
    t = np.interp(tow, gtow, tt)                    # seconds since the first sample (true time)
    err = np.linalg.norm(ecef - truth_pos, axis=1)
    sel = t >= from_s
    coast = mode == 2
    out = {"n_fixes": int(sel.sum()), "n_coast": int((sel & coast).sum()),
           "max_err_m": float(np.nanmax(err[sel & ~coast])) if (sel & ~coast).any() else float("nan"),
           "last_fix_s": float(t[sel].max()) if sel.any() else float("nan"),
           "coast_nsats_max": int(nsat[sel & coast].max()) if (sel & coast).any() else 0,
           "outages": []}
    for a, b in spans:
        if b < from_s:
            continue
        after = (t >= b) & ~coast
        good = after & (err <= good_m)
        first_good = float(t[good].min() - b) if good.any() else float("nan")
        win = after & (t <= b + 10.0)
        out["outages"].append({"start_s": a, "end_s": b, "length_s": round(b - a, 2),
                               "first_good_s": first_good,
                               "max_err_10s_m": float(err[win].max()) if win.any() else float("nan"),
                               "max_err_during_m": float(err[(t >= a) & (t < b) & ~coast].max())
                               if ((t >= a) & (t < b) & ~coast).any() else float("nan")})
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run")
    ap.add_argument("truth")
    ap.add_argument("--from-s", type=float, default=0.0)
    ap.add_argument("--good-m", type=float, default=10.0)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    s = score(a.run, a.truth, a.from_s, a.good_m)
    print(f"{a.run}: fixes {s['n_fixes']} (coast {s['n_coast']}, coast n_sats max {s['coast_nsats_max']}), "
          f"max error (non-coast) {s['max_err_m']:.1f} m, last fix {s['last_fix_s']:.1f} s")
    for o in s["outages"]:
        print(f"  outage {o['start_s']:6.1f}-{o['end_s']:6.1f} s ({o['length_s']:4.1f} s): first good fix "
              f"{o['first_good_s']:5.2f} s after, max error 10 s after {o['max_err_10s_m']:.1f} m, "
              f"during {o['max_err_during_m']:.1f} m")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(s, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
