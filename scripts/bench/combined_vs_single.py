"""Combined fixes against the best single system over many runs (issue 33): one row per run, then how often
and by how much the combination is worse, with a bootstrap interval over the runs.

Each run's systems are solved again from its observables (receiver.evaluate.systems, as
scripts/bench/gps_bds_resolve.py does for one run), scored against the truth over their common epochs; the
truth is found beside the run file (RUN.truth.h5 from ``gnssrx simulate``, RUN.truth.yaml from
scripts/tools/signalsim_gps_bds.py), or beside ``--recording`` names given in the same order.

    PYTHONPATH=. python scripts/bench/combined_vs_single.py RUN.h5 [RUN.h5 ...] [--systems GEC,G,E,C]
        [-o KEY=VALUE ...] [--from-s S] [--seed N]

``--from-s``: only fixes from S seconds after each run's first re-solved fix; ``-o``: a navigation setting for
every solve (e.g. weighting=cn0).  A single run's error is mostly a few satellites' slowly varying smoothed
code errors, so one run says little: report the count and the interval over several places, times and seeds.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from receiver.errors import UserError
from receiver.evaluate.systems import common_epochs, nav_settings, resolve_fixes, score_enu
from receiver.navigation.config import default
from receiver.runfile.reader import load_run

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gps_bds_resolve import truth_ecef  # noqa: E402


def compare(run_path, truth_stem, systems, changes, from_s):
    """(combined rms, {system set: rms}, common epochs) of one run."""
    run = load_run(run_path)
    x_true = truth_ecef(truth_stem)
    nav = nav_settings(run, **changes)
    fixes = {s: resolve_fixes(run, s, "run", nav) for s in systems}
    starts = [f["gps_tow"].min() for f in fixes.values() if len(f)]
    if not starts:
        raise UserError(f"{run_path}: no fixes re-solved")
    t0 = min(starts)
    fixes = {s: f[f["gps_tow"] >= t0 + from_s] for s, f in fixes.items()}
    common = common_epochs(*fixes.values())
    if len(common) == 0:
        raise UserError(f"{run_path}: no common epochs of {', '.join(systems)}")
    rms = {s: score_enu(f, x_true, common)["rms"] for s, f in fixes.items()}
    return rms, len(common)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--recording", action="append", default=[], help="the recording of each run, in order "
                    "(default: the truth beside the run file)")
    ap.add_argument("--systems", default="GEC,G,E,C", help="the combination first, then the single systems")
    ap.add_argument("-o", dest="overrides", action="append", default=[], help="navigation KEY=VALUE")
    ap.add_argument("--from-s", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1, help="bootstrap seed")
    a = ap.parse_args(argv)
    systems = a.systems.split(",")
    if len(systems) < 3:
        raise UserError("--systems: a combination and at least two single systems, e.g. GC,G,C")
    if a.recording and len(a.recording) != len(a.runs):
        raise UserError("--recording: one per run")
    changes = {}
    for ov in a.overrides:
        k, v = ov.split("=", 1)
        changes[k] = type(default(k))(v)
    ratios = []
    rows = [f"| run | epochs | {systems[0]} 3D RMS m | best single m | ratio |", "|---|---|---|---|---|"]
    for i, path in enumerate(a.runs):         # (all runs scored before anything is printed)
        stem = a.recording[i] if a.recording else path[:-3] if path.endswith(".h5") else path
        rms, n = compare(path, stem, systems, changes, a.from_s)
        best = min(systems[1:], key=lambda s: rms[s])
        r = rms[systems[0]] / rms[best]
        ratios.append(r)
        rows.append(f"| {path} | {n} | {rms[systems[0]]:.3f} | {rms[best]:.3f} ({best}) | {r:.2f}"
                    f"{' worse' if r > 1 else ''} |")
    print("\n".join(rows))
    lr = np.log(np.array(ratios))
    rng = np.random.default_rng(a.seed)
    boot = np.exp(rng.choice(lr, size=(2000, len(lr))).mean(axis=1))
    lo, hi = np.percentile(boot, [2.5, 97.5])
    print(f"\ncombined worse than the best single system in {int(np.sum(lr > 0))} of {len(lr)} runs; ratio "
          f"geometric mean {np.exp(lr.mean()):.3f} (95 % bootstrap interval {lo:.3f}-{hi:.3f}), "
          f"max {np.exp(lr.max()):.3f}")


if __name__ == "__main__":
    try:
        main()
    except (UserError, FileNotFoundError) as exc:
        print(f"combined_vs_single: {exc}", file=sys.stderr)
        sys.exit(2)
