#!/usr/bin/env python3
"""Peak resident memory of `gnssrx run` against file length: the input reader releases the mapped pages
behind its read position, so a long file should cost what a short one does.

    python scripts/bench/bench_memory.py [--seconds 15,120] [--dir /tmp/gnssrx_mem]

Writes int8 I/Q noise files at 2.6 MS/s of each length (reused when present), runs the receiver on each
(2 PRNs searched, navigation off: the whole file is streamed through the input stages and two channels) as
a child process and prints its peak RSS (ru_maxrss of the child).
"""
import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
FS = 2.6e6


def _noise_file(path: Path, seconds: int):
    size = int(2 * FS * seconds)
    if path.exists() and path.stat().st_size == size:
        return
    rng = np.random.default_rng(1)
    with open(path, "wb") as f:
        for _ in range(seconds):
            f.write(rng.integers(-20, 20, int(2 * FS), dtype=np.int8).tobytes())


def peak_rss_mb(path: Path) -> float:
    cmd = [sys.executable, "-m", "receiver.cli", "run", str(ROOT / "configs" / "default.yaml"), "--input",
           str(path), "-o", str(path) + ".h5", "-q", "--set", "input.format=int8_iq",
           "--set", "input.sample_rate_hz=2600000", "--set", "input.if_hz=0",
           "--set", "acquisition.prns=[1, 2]", "--set", "navigation.enabled=false"]
    # a fresh interpreter per measurement: ru_maxrss of RUSAGE_CHILDREN is the largest child so far
    probe = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True); "
             "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    out = subprocess.run([sys.executable, "-c", probe, *cmd], capture_output=True, text=True, check=True)
    return int(out.stdout.strip().splitlines()[-1]) / 1024.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", default="15,120", help="file lengths (s), comma-separated")
    ap.add_argument("--dir", default="/tmp/gnssrx_mem", help="where the noise files go")
    a = ap.parse_args()
    d = Path(a.dir)
    d.mkdir(parents=True, exist_ok=True)
    for s in (int(x) for x in a.seconds.split(",")):
        p = d / f"noise_{s}s.bin"
        _noise_file(p, s)
        print(f"{s:5d} s file ({p.stat().st_size / 1e6:.0f} MB): peak RSS {peak_rss_mb(p):.0f} MB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
