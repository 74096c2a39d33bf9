#!/usr/bin/env python3
"""Start-up cost: a short slice of a recording run end to end, as a user runs it (not part of CI).

Issue 19 asks that a 1-s file runs in <= 2 s wall with a warm numba cache.  This runs ``gnssrx run`` on the
first ``--seconds`` of the reference recording (../shared/data/gpssim_static_tokyo.bin, 8-bit I/Q at
2.6 MS/s, 10 satellites) ``--repeat`` times as separate processes (one untimed run first warms numba's
cache and the page cache), and prints for each run the wall time and CPU time of the process and its
``--timings`` stage table, then the median per stage.  Byte-compile the package first when it was edited
with PYTHONDONTWRITEBYTECODE set (``python -m compileall receiver``): stale .pyc files cost ~0.05 s of
source compilation per run.  The machine should be otherwise idle.

    python scripts/bench/bench_startup.py [--seconds 1] [--repeat 5] [--input FILE --config CONFIG]
"""
from __future__ import annotations

import argparse
import os
import re
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


def one(cmd: list[str]) -> tuple[float, float, dict]:
    """(wall s, CPU s of the child, {stage: (wall, cpu)}) of one run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        sys.exit(f"bench_startup: the run failed: {p.stderr.strip().splitlines()[-1:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    stages = {}
    for line in p.stderr.splitlines():
        m = re.match(r"^(\S.*?)\s{2,}([0-9.]+)\s+([0-9.]+)(\s+\d+)?\s*$", line)
        if m:
            stages[m.group(1).strip()] = (float(m.group(2)), float(m.group(3)))
    return wall, cpu, stages


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=1.0, help="seconds of the recording processed")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--input", default=str(RECORDING))
    ap.add_argument("--config", default=str(CONFIG))
    a = ap.parse_args()
    if not Path(a.input).exists():
        print(f"bench_startup: {a.input} not found (../shared beside the checkout)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "run.h5")
        cmd = [sys.executable, "-m", "receiver.cli", "run", a.config, "--input", a.input,
               "--set", f"input.duration_s={a.seconds:g}", "-o", out, "--quiet", "--timings"]
        one(cmd)                                              # warm numba's cache and the page cache
        runs = []
        for i in range(a.repeat):
            wall, cpu, st = one(cmd)
            runs.append((wall, cpu, st))
            print(f"run {i + 1}: wall {wall:.2f} s  CPU {cpu:.2f} s  (load average {os.getloadavg()[0]:.1f})",
                  flush=True)
    names = [n for n in runs[0][2] if n not in ("stage",)]
    print(f"\nmedian of {a.repeat} runs of a {a.seconds:g}-s slice:")
    print(f"  {'stage':24s} {'wall s':>7s} {'CPU s':>7s}")
    for n in names:
        w = statistics.median(r[2].get(n, (0.0, 0.0))[0] for r in runs)
        c = statistics.median(r[2].get(n, (0.0, 0.0))[1] for r in runs)
        print(f"  {n:24s} {w:7.3f} {c:7.3f}")
    wall = statistics.median(r[0] for r in runs)
    print(f"  {'process (measured here)':24s} {wall:7.3f} {statistics.median(r[1] for r in runs):7.3f}")
    print(f"\nwall time {wall:.2f} s median (min {min(r[0] for r in runs):.2f}, max {max(r[0] for r in runs):.2f}); "
          f"issue 19's target for a 1-s file: <= 2 s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
