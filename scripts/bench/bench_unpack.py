"""Unpacking speed of the packed formats (receiver/source/io.py), one thread.

    .venv/bin/python scripts/bench/bench_unpack.py [--mb 64]

Writes a random file of each packed format in a temporary directory, then times SampleReader.read over it
in 1 M-sample blocks (memory-mapped file already in the page cache, numba kernel compiled beforehand).
Prints MS/s of wall time and of process CPU time (the machine may be shared).
"""
import argparse
import os
import tempfile
import time

import numpy as np

from receiver.source.io import FORMATS, SampleReader, bits_per_sample


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mb", type=float, default=32.0, help="file size per format (MB)")
    ap.add_argument("--formats", default="packed2_real,packed2_iq,packed4_real,packed4_iq,int4_iq,int8_iq")
    a = ap.parse_args()
    try:
        import numba
        numba.set_num_threads(1)
    except Exception:
        pass
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as d:
        for name in a.formats.split(","):
            f = FORMATS[name]
            p = os.path.join(d, name)
            rng.integers(0, 256, int(a.mb * 1e6), dtype=np.uint8).tofile(p)
            r = SampleReader(p, name, 1e6)
            r.read(0, 1000)                                       # compile
            for _ in r.chunks(1 << 20):                           # page cache
                pass
            w0, c0 = time.perf_counter(), time.process_time()
            n = 0
            for _, b in r.chunks(1 << 20):
                n += b.size
            w, c = time.perf_counter() - w0, time.process_time() - c0
            print(f"{name:14s} {bits_per_sample(f):2d} bit/sample  {n / 1e6:7.1f} MS  "
                  f"{n / w / 1e6:8.1f} MS/s wall  {n / max(c, 1e-9) / 1e6:8.1f} MS/s CPU")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
