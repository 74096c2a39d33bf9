#!/usr/bin/env python3
"""`make figures-check`: re-run a cheap subset of the paper figures and compare with the committed reference.

    python scripts/figures/figures_check.py                      # check against configs/figures_reference.json
    python scripts/figures/figures_check.py --set tracking.carrier.ekf.bn_hz=12     # a perturbed loop: must fail
    python scripts/figures/figures_check.py --update             # rewrite the reference (after an intended change)

The subset (every part seeded; the same numbers for any -j):
  * carrier: the strong-moderate scintillation scenario (S4 0.6, sigma_phi 0.5), 3 seeds x 20 s, loops
    cpll_atan / ekf / pli_ekf / pli_ekf_paper (scripts/figures/figures_carrier.py --scenarios 3);
  * LEO: 40 Monte Carlo runs in 2 seed blocks, all four solvers (scripts/figures/figures_leo.py --runs 40 --seeds 2);
  * vector: the acceleration-steps scenario shortened to 30 s, its own seed, CV (sigma_v^2 = 0.1) and the
    polynomial loop (chi-square 25) through receiver/batch (scripts/figures/figures_vector.py --only accel).
--set key=value overrides go to the carrier loops and to the vector receiver runs.

Every compared number has a tolerance (stated in the reference file and printed): a value passes when
|measured - reference| <= max(abs, rel * |reference|).  The tolerances are a few per cent: far above the
round-off differences between machines (the experiments are deterministic for a given seed; the chaotic
runs, e.g. a loop on the edge of divergence, are not in this subset) and below the effect of a loop
parameter change.  Exit status 0: all within tolerance; 1: a mismatch (each one listed); 2: bad usage.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
REFERENCE = os.path.join(ROOT, "configs", "figures_reference.json")

# tolerance classes: (abs, rel)
TOL = {"carrier_std_deg": (0.05, 0.02), "carrier_lol": (0.004, 0.10), "leo_m": (0.5, 0.01),
       "vector_pos_m": (0.2, 0.05), "vector_vel_mps": (0.02, 0.05)}


def run(cmd, log):
    log("  $ " + " ".join(os.path.relpath(c, ROOT) if c.startswith(ROOT) else c for c in cmd))
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                       env={**os.environ, "PYTHONPATH": ROOT + os.pathsep + os.environ.get("PYTHONPATH", "")})
    if p.returncode != 0:
        sys.stderr.write(p.stdout[-3000:])
        raise SystemExit(f"figures-check: {os.path.basename(cmd[1])} failed (exit {p.returncode})")
    log(f"    {time.perf_counter() - t0:.0f} s")


def measure(tmp, sets, jobs, log, parts=("carrier", "leo", "vector"), carrier_engine="compiled"):
    """The subset's numbers: {name: (value, tolerance class)}."""
    py = sys.executable
    out = {}
    if "carrier" in parts:
        _carrier(py, tmp, sets, jobs, log, out, carrier_engine)
    if "leo" in parts:
        _leo(py, tmp, log, out)
    if "vector" in parts:
        _vector(py, tmp, sets, jobs, log, out)
    return out


def _carrier(py, tmp, sets, jobs, log, out, engine="compiled"):
    cj = os.path.join(tmp, "carrier.json")
    run([py, os.path.join(ROOT, "scripts", "figures", "figures_carrier.py"), "--out", os.path.join(tmp, "carrier"),
         "--seeds", "3", "--duration", "20", "--scenarios", "3", "--skip-weak", "--jobs", str(jobs),
         "--json", cj, "--engine", engine] + sum((["--set", s] for s in sets), []), log)
    with open(cj) as fh:
        c = json.load(fh)
    for k, v in c["scint"].items():
        out[f"carrier/{k}/phase_std_deg"] = (v["std_mean"], "carrier_std_deg")
        out[f"carrier/{k}/p_loss_of_lock"] = (v["lol_mean"], "carrier_lol")


def _leo(py, tmp, log, out):
    lj = os.path.join(tmp, "leo.json")
    run([py, os.path.join(ROOT, "scripts", "figures", "figures_leo.py"), "--out", os.path.join(tmp, "leo"),
         "--runs", "40",
         "--seeds", "2", "--sens-runs", "0", "--skip-figures", "--quiet", "--json", lj], log)
    with open(lj) as fh:
        lb = json.load(fh)["blocks"]
    for m in lb[0]:
        for q in ("total", "rmse_mean"):
            out[f"leo/{m}/{q}_m"] = (sum(b[m][q] for b in lb) / len(lb), "leo_m")


def _vector(py, tmp, sets, jobs, log, out):
    """Through the batch machinery; runs cached by content hash (code + config) under out/figures_check."""
    vout = os.path.join(tmp, "vector")
    cmd = [py, os.path.join(ROOT, "scripts", "figures", "figures_vector.py"), "--out", vout,
           "--data", os.path.join(ROOT, "out", "figures_check"), "--only", "accel", "--duration", "30",
           "--seeds", "1", "--variants", "cv_0.1,poly_25", "-j", str(jobs)]
    cmd += sum((["--set", s] for s in sets), [])
    run(cmd, log)
    with open(os.path.join(vout, "vector_results.json")) as fh:
        rows = json.load(fh)["accel"]["rows"]
    for r in rows:
        out[f"vector/accel/{r['run']}/pos_rms_m"] = (r["pos_rms"], "vector_pos_m")
        out[f"vector/accel/{r['run']}/vel_rms_mps"] = (r["vel_rms"], "vector_vel_mps")


def compare(measured, ref, parts=None):
    bad, lines = [], []
    for name, r in sorted(ref["values"].items()):
        if parts is not None and name.split("/")[0] not in parts:
            continue
        a, rel = r["tol_abs"], r["tol_rel"]
        if name not in measured:
            bad.append(name)
            lines.append(f"MISSING  {name}")
            continue
        v = measured[name][0]
        tol = max(a, rel * abs(r["value"]))
        ok = v is not None and math.isfinite(v) and abs(v - r["value"]) <= tol
        if not ok:
            bad.append(name)
        lines.append(f"{'ok      ' if ok else 'MISMATCH'} {name}: {v:.4g} (reference {r['value']:.4g}, "
                     f"tolerance ±{tol:.3g})")
    for name in sorted(set(measured) - set(ref["values"])):
        lines.append(f"new      {name}: {measured[name][0]:.4g} (not in the reference)")
    return bad, lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reference", default=REFERENCE)
    ap.add_argument("--update", action="store_true", help="write the measured numbers as the new reference")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                    help="receiver override for the carrier loops and the vector runs (perturbation demo)")
    ap.add_argument("--jobs", "-j", type=int, default=2)
    ap.add_argument("--only", default=None, help="comma-separated parts to run: carrier, leo, vector (default: all)")
    ap.add_argument("--carrier-engine", choices=("compiled", "python"), default="compiled",
                    help="corrsim path of the carrier part (figures_carrier.py --engine; python = the reference)")
    args = ap.parse_args(argv)
    parts = tuple(args.only.split(",")) if args.only else ("carrier", "leo", "vector")
    if set(parts) - {"carrier", "leo", "vector"}:
        ap.error(f"--only: unknown part in {args.only!r} (carrier, leo, vector)")
    if args.update and args.only:
        ap.error("--update needs every part")
    if args.update and args.sets:
        ap.error("--update with --set would make a perturbed reference")
    if not args.update and not os.path.exists(args.reference):
        sys.stderr.write(f"figures-check: no reference file {args.reference} (run with --update)\n")
        return 2
    log = lambda m: print(m, flush=True)      # noqa: E731
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="figures_check_") as tmp:
        measured = measure(tmp, args.sets, args.jobs, log, parts, args.carrier_engine)
    wall = time.perf_counter() - t0
    if args.update:
        doc = {"about": "reference numbers of `make figures-check` (scripts/figures/figures_check.py): value "
                        "and tolerance |measured - value| <= max(tol_abs, tol_rel * |value|)",
               "tolerance_classes": {k: {"abs": a, "rel": r} for k, (a, r) in TOL.items()},
               "values": {k: {"value": v, "tol_abs": TOL[c][0], "tol_rel": TOL[c][1], "class": c}
                          for k, (v, c) in sorted(measured.items())}}
        with open(args.reference, "w") as fh:
            json.dump(doc, fh, indent=1)
            fh.write("\n")
        log(f"wrote {os.path.relpath(args.reference, ROOT)} ({len(measured)} values, {wall:.0f} s)")
        return 0
    with open(args.reference) as fh:
        ref = json.load(fh)
    bad, lines = compare(measured, ref, parts)
    n = sum(1 for k in ref["values"] if k.split("/")[0] in parts)
    log("\n".join(lines))
    if bad:
        log(f"figures-check FAILED: {len(bad)} of {n} values outside their tolerance "
            f"({wall:.0f} s){' with --set ' + ' '.join(args.sets) if args.sets else ''}")
        return 1
    log(f"figures-check passed: {n} values within tolerance ({wall:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
