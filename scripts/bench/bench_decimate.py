"""Cost of the decimating input stage (receiver/source/decimate.py) per input sample.

    PYTHONPATH=. python scripts/bench/bench_decimate.py [--seconds 2] [--format packed2_real] [--threads 1,2]

Writes a random file of ``--format`` at 16.368 MS/s (IF 4.1304 MHz, the MAX2769-style front end of
configs/scenarios/static_16mhz_2bit.yaml), then reads it the way a run does (``input.decimate: auto`` ->
4 MS/s; 0.5-s blocks plus the 30-ms overlap of the pipeline) and prints nanoseconds per *input* sample of
process CPU time and of wall time, for SampleReader.read alone (unpacking to complex64: what the stage did
before it unpacked packed real formats itself) and for the whole stage (unpack + mix + filter + resample),
with each thread count of ``--threads``.  The file is in the page cache
and the kernels are compiled before timing; the best of ``--repeat`` passes is printed (the machine may be
shared: CPU time is the figure to compare).
"""
import argparse
import os
import tempfile
import time


import numpy as np  # noqa: E402

from receiver import threads as T  # noqa: E402
from receiver.source.decimate import DecimatingReader, plan  # noqa: E402
from receiver.source.io import SampleReader, bytes_per_sample  # noqa: E402

FS, IF, CHIP = 16.368e6, 4.1304e6, 1.023e6
CHUNK_S, OVERLAP_S = 0.5, 0.03          # receiver/pipeline.py


def passes(reader, fs, repeat):
    chunk, overlap = int(CHUNK_S * fs), int(OVERLAP_S * fs)
    best = (np.inf, np.inf)
    for _ in range(repeat):
        c0, w0 = time.process_time(), time.perf_counter()
        pos = reader.first
        while pos < reader.end:
            reader.read(pos, chunk + overlap)
            pos += chunk
        best = (min(best[0], time.process_time() - c0), min(best[1], time.perf_counter() - w0))
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--format", default="packed2_real")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    n_in = int(a.seconds * FS)
    with tempfile.TemporaryDirectory() as d:
        p = os.path.join(d, "x.bin")
        rng.integers(0, 256, int(n_in * bytes_per_sample(a.format)), dtype=np.uint8).tofile(p)
        raw = SampleReader(p, a.format, FS)
        raw.if_hz = IF
        l, m = plan("auto", FS, CHIP)
        dec = DecimatingReader(raw, l, m, IF, CHIP)
        dec.read(dec.first, 100000)                                  # compile
        raw.read(0, 100000)
        n = raw.n_samples
        print(f"{a.format} {FS / 1e6:g} MS/s IF {IF / 1e6:g} MHz -> {dec.fs / 1e6:g} MS/s (x{dec.resample}), "
              f"{dec.taps} taps per output, {n / 1e6:.1f} M input samples")
        for nt in map(int, a.threads.split(",")):
            T.set_threads(nt)
            cu, wu = passes(raw, FS, a.repeat)
            cs, ws = passes(dec, dec.fs, a.repeat)
            print(f"threads {nt}: SampleReader.read {cu / n * 1e9:5.2f} ns CPU / {wu / n * 1e9:5.2f} ns wall;  "
                  f"whole stage {cs / n * 1e9:5.2f} ns CPU / {ws / n * 1e9:5.2f} ns wall per input sample "
                  f"({n / ws / 1e6:6.1f} MS/s wall)")
        T.set_threads(None)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
