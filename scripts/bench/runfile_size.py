"""Run-file size and write cost on the reference recording (issue 18: compact run files).

Runs ``configs/gpssim_static_tokyo.yaml`` on ``../shared/data/gpssim_static_tokyo.bin`` (assisted with
brdc0010.22n, as tests/conftest.py does) with the default output settings (or ``--set key=value``
overrides), and prints the file size, the stored bytes per group and per channel column, the run's CPU time
and the CPU time spent inside the run-file writer (``RunWriter`` methods, thread CPU time of the calling
thread, so a loaded machine inflates it less than wall time).

``--rewrite FILE``: instead of running the receiver, write FILE's /channels, /navigation and /observables
again through today's ``RunWriter`` (same chunking as a run: 0.5-s blocks per channel) and report size
and writer CPU time; repeat ``--repeat`` times and report the minimum.  That isolates the writing part.

    PYTHONPATH=. python scripts/bench/runfile_size.py [--out out/tokyo_size.h5] [--set output.compression=gzip]
    PYTHONPATH=. python scripts/bench/runfile_size.py --rewrite out/tokyo_size.h5 --repeat 3
"""
from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "data"


def _instrument(acc: dict):
    """Wrap the RunWriter methods so the thread CPU time spent inside them adds up in acc['cpu']."""
    from receiver.runfile import writer as W
    for name in ("append_channel", "_flush_channel", "_write_stats", "_append_table", "write_acquisition",
                 "write_ephemerides", "write_iono_utc", "set_attrs", "close", "__init__"):
        orig = getattr(W.RunWriter, name)

        def wrap(orig=orig):
            @functools.wraps(orig)
            def f(*a, **k):
                if acc["depth"]:
                    return orig(*a, **k)
                acc["depth"] += 1
                t0 = time.thread_time()
                try:
                    return orig(*a, **k)
                finally:
                    acc["cpu"] += time.thread_time() - t0
                    acc["depth"] -= 1
            return f
        setattr(W.RunWriter, name, wrap())


def sizes(path) -> dict:
    """Stored (compressed) bytes per top-level group and per /channels column (summed over channels)."""
    groups, cols = {}, {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                n = obj.id.get_storage_size()
                top = name.split("/")[0]
                groups[top] = groups.get(top, 0) + n
                if top == "channels":
                    c = name.split("/")[-1]
                    cols[c] = cols.get(c, 0) + n
        f.visititems(visit)
    return {"groups": groups, "columns": cols}


def report(path, extra=""):
    s = sizes(path)
    mb = os.path.getsize(path) / 1e6
    print(f"file {path}: {mb:.2f} MB{extra}")
    for g, n in sorted(s["groups"].items(), key=lambda kv: -kv[1]):
        print(f"  /{g:<14} {n / 1e6:8.3f} MB")
    print("  /channels columns (all channels):")
    for c, n in sorted(s["columns"].items(), key=lambda kv: -kv[1]):
        print(f"    {c:<22} {n / 1e6:8.3f} MB")
    return mb


def run_reference(out, overrides):
    from receiver.schema import load_receiver_config
    from receiver.pipeline import run
    acc = {"cpu": 0.0, "depth": 0}
    _instrument(acc)
    cfg = load_receiver_config(ROOT / "configs" / "gpssim_static_tokyo.yaml",
                               [("input.path", str(SHARED / "gpssim_static_tokyo.bin")),
                                ("output.path", str(out)),
                                ("navigation.ephemeris", str(SHARED / "brdc0010.22n")),
                                ("navigation.weighting", "rtklib"), *overrides])
    c0, w0 = time.process_time(), time.perf_counter()
    run(cfg, quiet=True)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    report(out, f"; run CPU {cpu:.2f} s, wall {wall:.2f} s, writer CPU {acc['cpu']:.3f} s")


def rewrite(src, repeat, compression):
    from receiver.runfile.record import EPOCH_DTYPE, FIX_DTYPE, OBS_DTYPE
    from receiver.runfile.writer import RunWriter
    with h5py.File(src, "r") as f:
        chans = {}
        for name, g in f["channels"].items():
            n = g["time_s"].shape[0]
            r = np.zeros(n, EPOCH_DTYPE)
            for c in EPOCH_DTYPE.names:
                if c in g:
                    r[c] = g[c][:]
            chans[int(g.attrs["prn"])] = r
        fixes = np.zeros(f["navigation/time_s"].shape[0], FIX_DTYPE)
        for c in FIX_DTYPE.names:
            if c in f["navigation"]:            # (iono_params: not in older run files)
                fixes[c] = f["navigation"][c][:]
        obs = np.zeros(f["observables/time_s"].shape[0], OBS_DTYPE)
        for c in OBS_DTYPE.names:
            obs[c] = f["observables"][c][:]
    best = None
    with tempfile.TemporaryDirectory() as d:
        for _ in range(repeat):
            out = os.path.join(d, "rw.h5")
            if os.path.exists(out):
                os.remove(out)
            t0 = time.thread_time()
            w = RunWriter(out, "{}", {}, compression=compression)
            # a run hands over 0.5 s of every channel at a time (pipeline CHUNK_S), fixes every chunk
            tmax = max(float(r["time_s"][-1]) for r in chans.values())
            edges = np.arange(0.0, tmax + 0.5, 0.5)
            for a, b in zip(edges[:-1], edges[1:]):
                for prn, r in chans.items():
                    i0, i1 = np.searchsorted(r["time_s"], [a, b])
                    if i1 > i0:
                        w.append_channel(prn, r[i0:i1])
                j0, j1 = np.searchsorted(fixes["time_s"], [a, b])
                w.append_fixes(fixes[j0:j1])
                k0, k1 = np.searchsorted(obs["time_s"], [a, b])
                w.append_observables(obs[k0:k1])
            w.close(True)
            cpu = time.thread_time() - t0
            best = cpu if best is None else min(best, cpu)
            mb = report(out, f"; writer CPU {cpu:.3f} s ({compression})")
    print(f"rewrite: {mb:.2f} MB, writer CPU min of {repeat}: {best:.3f} s")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="run file to write (default: a temporary file)")
    ap.add_argument("--set", action="append", default=[], help="config override key=value")
    ap.add_argument("--rewrite", default=None, help="rewrite this run file's tables instead of running")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--compression", default="gzip", help="for --rewrite (the run default: gzip)")
    a = ap.parse_args(argv)
    if a.rewrite:
        rewrite(a.rewrite, a.repeat, a.compression)
        return 0
    if not (SHARED / "gpssim_static_tokyo.bin").exists():
        print(f"reference recording not found under {SHARED}", file=sys.stderr)
        return 2
    import yaml
    overrides = [(k, yaml.safe_load(v)) for k, v in (s.split("=", 1) for s in a.set)]
    if a.out:
        run_reference(a.out, overrides)
    else:
        with tempfile.TemporaryDirectory() as d:
            run_reference(os.path.join(d, "tokyo.h5"), overrides)
    return 0


if __name__ == "__main__":
    sys.exit(main())
