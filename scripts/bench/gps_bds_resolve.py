"""GPS only / BeiDou only / GPS + BeiDou fixes solved again from one combined run's observables (the PVT alone:
receiver.evaluate.systems.resolve_fixes, NavSolver on the same pseudoranges, ephemerides and Klobuchar set),
scored against the truth over their common epochs: 3D RMS, mean east/north/up error, satellites, PDOP.
Seconds instead of three tracking runs, so a change of the solver is measured at once;
scripts/bench/accuracy_gps_bds.py runs the receiver itself.

    PYTHONPATH=. python scripts/bench/gps_bds_resolve.py RUN.h5 REC.bin [--iono run|fallback|none]
        [--every N] [--from-s S] [-o KEY=VALUE ...]     (KEY: a navigation setting, e.g. weighting=none)
        [--systems GE,G,E] [--code-var E=2.0 ...]

``--systems``: the system sets to solve (RINEX letters, default GC,G,C; e.g. GE,G,E for a GPS + Galileo run,
GEC,G,E,C for three systems); ``--code-var L=V``: system L's range variance relative to L1 C/A for this solve
(receiver.navigation.pvt.CODE_VAR_REL_CA, e.g. E=1 to compare with the shipped 2).
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from receiver.config import read_yaml
from receiver.errors import UserError
from receiver.evaluate.systems import common_epochs, nav_settings, resolve_fixes, score_enu
from receiver.navigation.config import default
from receiver.runfile.reader import load_run


def truth_ecef(recording) -> np.ndarray:
    """The truth position of a recording: REC.truth.h5 (gnssrx simulate) or REC.truth.yaml (SignalSim maker)."""
    stem = recording[:-4] if recording.endswith(".bin") else recording
    if os.path.exists(stem + ".truth.h5"):
        import h5py
        with h5py.File(stem + ".truth.h5", "r") as t:
            return np.asarray(t["receiver"]["ecef"][0], float)
    return np.asarray(read_yaml(stem + ".truth.yaml")["truth"]["ecef_m"], float)


def table(fixes: dict, x_true) -> str:
    """Markdown table of {name: fixes} over their common epochs."""
    common = common_epochs(*fixes.values())
    out = [f"{len(common)} common epochs",
           "| case | fixes | 3D RMS m | mean E m | mean N m | mean U m | sats | PDOP |",
           "|---|---|---|---|---|---|---|---|"]
    for name, fx in fixes.items():
        s = score_enu(fx, x_true, common)
        e, n, u = s["enu"]
        out.append(f"| {name} | {s['n']} | {s['rms']:.3f} | {e:+.3f} | {n:+.3f} | {u:+.3f} | {s['sats']:.1f} "
                   f"| {s['pdop']:.2f} |")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("recording")
    ap.add_argument("--iono", default="run", choices=("run", "fallback", "none"))
    ap.add_argument("--every", type=int, default=1, help="use every N-th epoch")
    ap.add_argument("--from-s", type=float, default=0.0, help="only epochs from this time in the file (s)")
    ap.add_argument("-o", dest="overrides", action="append", default=[], help="navigation KEY=VALUE")
    ap.add_argument("--systems", default="GC,G,C", help="comma-separated system sets, e.g. GE,G,E")
    ap.add_argument("--code-var", action="append", default=[], help="L=V: system L's variance vs L1 C/A")
    a = ap.parse_args(argv)
    from receiver.navigation.pvt import CODE_VAR_REL_CA
    for item in a.code_var:
        k, v = item.split("=", 1)
        CODE_VAR_REL_CA[k] = float(v)
    run = load_run(a.run)
    run.obs = run.obs[run.obs["time_s"] >= a.from_s]
    changes = {}
    for ov in a.overrides:
        k, v = ov.split("=", 1)
        changes[k] = type(default(k))(v)
    nav = nav_settings(run, **changes)
    iono = "run"
    if a.iono == "fallback":
        from receiver.gnss.atmosphere import FALLBACK_KLOBUCHAR_ALPHA, FALLBACK_KLOBUCHAR_BETA
        from receiver.gnss.ephemeris import IonoUtc
        iono = IonoUtc(alpha=FALLBACK_KLOBUCHAR_ALPHA, beta=FALLBACK_KLOBUCHAR_BETA)
    elif a.iono == "none":
        iono = None
    names = {"G": "GPS", "C": "BeiDou", "E": "Galileo", "J": "QZSS"}
    fixes = {(" + ".join(names.get(c, c) for c in sy) + (" only" if len(sy) == 1 else "")):
             resolve_fixes(run, sy, iono, nav, a.every) for sy in a.systems.split(",")}
    print(table(fixes, truth_ecef(a.recording)))


if __name__ == "__main__":
    try:
        main()
    except (UserError, FileNotFoundError) as exc:     # a missing run file or truth: one line, exit 2
        print(f"gps_bds_resolve: {exc}", file=sys.stderr)
        sys.exit(2)
