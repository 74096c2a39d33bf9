#!/usr/bin/env python3
"""Compare two run files (or two output directories) exactly: every group, dataset (dtype, shape, values,
NaNs in the same places) and attribute, bit for bit.  Used to show that a refactoring leaves the outputs
unchanged.

    python scripts/tools/compare_runs.py A.h5 B.h5
    python scripts/tools/compare_runs.py DIR_A DIR_B        # every file in both trees: .h5 as above, others byte-wise

Ignored: attributes that depend on the wall clock or on the invocation (``command``, ``created_utc``,
``wall_time_s``, ``realtime_factor``).  In string attributes and text files the directory of each side is
replaced by a placeholder first, so ``-o /tmp/a/run.h5`` and ``-o /tmp/b/run.h5`` compare equal, and a
string attribute naming an existing file is compared as its real path (the same input reached through a
symlink).
Prints each difference on one line; exit 1 on any difference, 2 on bad arguments, 0 when identical.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from receiver.runfile.compare import compare_files


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a")
    ap.add_argument("b")
    args = ap.parse_args(argv)
    a, b = Path(args.a), Path(args.b)
    if not a.exists() or not b.exists():
        print(f"compare_runs: {a if not a.exists() else b} does not exist", file=sys.stderr)
        return 2
    out: list[str] = []
    n = 0
    if a.is_dir() and b.is_dir():
        fa = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
        fb = {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
        for rel in sorted(fa ^ fb):
            out.append(f"{rel}: only in {'A' if rel in fa else 'B'}")
        for rel in sorted(fa & fb):
            compare_files(a / rel, b / rel, out, f"{rel}:")
            n += 1
    elif a.is_file() and b.is_file():
        compare_files(a, b, out)
        n = 1
    else:
        print("compare_runs: give two files or two directories", file=sys.stderr)
        return 2
    for line in out:
        print(line)
    print(f"compare_runs: {n} file(s) compared, {len(out)} difference(s)")
    return 1 if out else 0


if __name__ == "__main__":
    sys.exit(main())
