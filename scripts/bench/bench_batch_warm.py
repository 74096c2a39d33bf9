#!/usr/bin/env python3
"""Warm batch workers against separate processes: N one-second runs as one ``gnssrx batch`` (a local pool whose
workers pay the imports and the loading of the compiled kernels once, receiver/batch/warm.py) and as N separate
``gnssrx run`` processes one after the other (what a shell loop does), measured interleaved (batch, separate,
batch, separate, ...) in one invocation, with the load average beside every measurement.

The N runs are the 1-s slices starting at 0, 1, ..., N-1 s of the reference recording
(../shared/data/gpssim_static_tokyo.bin, 10 satellites, 32 PRNs searched): each is a cold start with its own
acquisition.  The batch also scores every run (its summary row); the separate runs print their summaries.
At the end the batch's run files are compared with the separate runs' (receiver.runfile.compare): they must
be the same bit for bit.

    python scripts/bench/bench_batch_warm.py [--runs 20] [--jobs 2] [--repeat 1] [--separate-jobs 1]

``--separate-jobs 2`` runs the separate processes two at a time (the batch's parallelism) instead.
Wall times on a shared machine mean little: the CPU seconds (of the separate processes, from
RUSAGE_CHILDREN; of the batch's runs, the sum of its ``job_cpu_s`` column, which leaves out each worker's
one-time warm-up) are printed beside them.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import csv
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
RECORDING = REPO.parent / "shared" / "data" / "gpssim_static_tokyo.bin"
CONFIG = REPO / "configs" / "gpssim_static_tokyo.yaml"
TOKYO_LLH = [35.681298, 139.766247, 10.0]


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def write_batch(path: Path, runs: int, out: Path) -> None:
    """The batch file: the reference recording, 1 s from each start 0..runs-1 s."""
    skips = ", ".join(str(i) for i in range(runs))
    path.write_text(f"name: warm{runs}\noutput_dir: {out}\nset: {{input.duration_s: 1.0}}\n"
                    f"sweep: {{input.skip_s: [{skips}]}}\n"
                    f"inputs:\n  - name: tokyo\n    recording: {RECORDING}\n    config: {CONFIG}\n"
                    f"    reference_llh: {TOKYO_LLH}\n")


def run_batch(batch: Path, out: Path, jobs: int) -> tuple[float, float, dict]:
    """(wall s, sum of the runs' CPU s, {skip_s: run file}) of one ``gnssrx batch``."""
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "receiver.cli", "batch", str(batch), "-j", str(jobs),
                        "--out", str(out)], capture_output=True, text=True, env=_env())
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        sys.exit(f"bench_batch_warm: the batch failed: {p.stderr.strip().splitlines()[-3:]}")
    rows = list(csv.DictReader(open(out / "summary.csv")))
    cpu = sum(float(r["job_cpu_s"]) for r in rows)
    files = {float(r["input.skip_s"]): out / "runs" / f"{r['run_id']}.h5" for r in rows}
    return wall, cpu, files


def run_separate(runs: int, out: Path, jobs: int, names: dict) -> tuple[float, float, dict]:
    """(wall s, CPU s of the children, {skip_s: run file}) of ``runs`` separate ``gnssrx run`` processes (run
    file names: ``names`` {skip_s: name}, the batch's, so that the configurations stored match)."""
    out.mkdir(parents=True, exist_ok=True)

    def one(i):
        h5 = out / names[float(i)]
        p = subprocess.run([sys.executable, "-m", "receiver.cli", "run", str(CONFIG), "--input",
                            str(RECORDING),
                            "--set", "input.duration_s=1", "--set", f"input.skip_s={i}", "-o", str(h5), "--quiet"],
                           capture_output=True, text=True, env=_env())
        if p.returncode != 0:
            sys.exit(f"bench_batch_warm: a run failed: {p.stderr.strip().splitlines()[-1:]}")
        return float(i), h5

    c0, t0 = _cpu_children(), time.perf_counter()
    with cf.ThreadPoolExecutor(max_workers=jobs) as pool:
        files = dict(pool.map(one, range(runs)))
    return time.perf_counter() - t0, _cpu_children() - c0, files


def _identical(a: dict, b: dict) -> tuple[int, list]:
    from receiver.runfile.compare import compare_h5
    diffs = []
    for k in sorted(a):
        out: list[str] = []
        compare_h5(a[k], b[k], out)
        diffs += [f"skip {k:g} s: {d}" for d in out]
    return len(a), diffs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2, help="batch pool workers")
    ap.add_argument("--separate-jobs", type=int, default=1, help="separate processes at a time")
    ap.add_argument("--repeat", type=int, default=1, help="pairs (batch, separate) measured")
    a = ap.parse_args()
    if not RECORDING.exists():
        print(f"bench_batch_warm: {RECORDING} not found (../shared beside the checkout)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="bench_batch_warm_") as tmp:
        tmp = Path(tmp)
        batch = tmp / "batch.yaml"
        A, B = [], []
        for r in range(a.repeat):
            out = tmp / f"batch{r}"
            write_batch(batch, a.runs, out)
            A.append(run_batch(batch, out, a.jobs))
            print(f"pair {r + 1}: batch -j {a.jobs}: {A[-1][0]:6.1f} s wall, runs' CPU {A[-1][1]:6.1f} s  "
                  f"(load average {os.getloadavg()[0]:.1f})", flush=True)
            names = {k: v.name for k, v in A[-1][2].items()}
            B.append(run_separate(a.runs, tmp / f"separate{r}", a.separate_jobs, names))
            print(f"pair {r + 1}: {a.runs} x gnssrx run ({a.separate_jobs} at a time): {B[-1][0]:6.1f} s wall, "
                  f"CPU {B[-1][1]:6.1f} s  (load average {os.getloadavg()[0]:.1f})", flush=True)
        n, diffs = _identical(A[0][2], B[0][2])
    wa, wb = statistics.median(x[0] for x in A), statistics.median(x[0] for x in B)
    ca, cb = statistics.median(x[1] for x in A), statistics.median(x[1] for x in B)
    print(f"\n{a.runs} one-second runs: batch {wa:.1f} s wall vs separate {wb:.1f} s: {wb / wa:.2f}x faster "
          f"(median of {a.repeat}; per-run CPU {ca / a.runs:.2f} s in the batch vs {cb / a.runs:.2f} s, "
          f"{cb / ca:.2f}x)")
    print(f"run files: {n - len({d.split(':')[0] for d in diffs})} of {n} identical" +
          ("" if not diffs else "\n  " + "\n  ".join(diffs[:10])))
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
