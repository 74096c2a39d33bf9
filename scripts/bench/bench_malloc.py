#!/usr/bin/env python3
"""The C allocator's settings against resident memory and CPU: interleaved runs of ``gnssrx run`` on the first
``--seconds`` of a recording with glibc's defaults (``GNSSRX_MALLOC=default``), with gnssrx's settings (2 arenas,
``malloc_trim`` every 2 s of signal; receiver/_malloc.py) and with a fixed 1-MB mapping threshold (every large
array its own mapping), printing wall, user and system CPU, minor page faults and the peak RSS and anonymous
RSS of each (sampled from /proc every 0.5 s).

    python scripts/bench/bench_malloc.py CONFIG [--input FILE] [--seconds 60] [--order default,gnssrx,mmap1m,...]
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

VARIANTS = {"default": {"GNSSRX_MALLOC": "default"}, "gnssrx": {},
            "mmap1m": {"MALLOC_ARENA_MAX": "2", "MALLOC_MMAP_THRESHOLD_": str(1 << 20)}}


def one(cmd: list[str], env: dict) -> dict:
    """Wall, CPU, faults and peaks of one child process."""
    b = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    peak = {"rss": 0, "anon": 0}

    def sample():
        while p.poll() is None:
            try:
                s = Path(f"/proc/{p.pid}/status").read_text()
                peak["rss"] = max(peak["rss"], int(re.search(r"VmRSS:\s+(\d+)", s).group(1)))
                peak["anon"] = max(peak["anon"], int(re.search(r"RssAnon:\s+(\d+)", s).group(1)))
            except (OSError, AttributeError):
                pass
            time.sleep(0.5)

    th = threading.Thread(target=sample)
    th.start()
    p.wait()
    th.join()
    a = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"wall": time.perf_counter() - t0, "user": a.ru_utime - b.ru_utime, "sys": a.ru_stime - b.ru_stime,
            "minflt": a.ru_minflt - b.ru_minflt, "rss": peak["rss"] / 1024, "anon": peak["anon"] / 1024,
            "rc": p.returncode}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("config")
    ap.add_argument("--input")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--order", default="default,gnssrx,mmap1m,default,gnssrx,mmap1m")
    ap.add_argument("--nice", type=int, default=19)
    a = ap.parse_args()
    order = a.order.split(",")
    bad = [v for v in order if v not in VARIANTS]
    if bad:
        print(f"bench_malloc: unknown variant {bad[0]} (one of {', '.join(VARIANTS)})", file=sys.stderr)
        return 2
    base = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "GNSSRX_MALLOC"}
    with tempfile.TemporaryDirectory() as tmp:
        cmd = ["nice", "-n", str(a.nice), sys.executable, "-m", "receiver.cli", "run", a.config, "-o",
               os.path.join(tmp, "run.h5"), "--quiet", "--set", f"input.duration_s={a.seconds:g}"]
        if a.input:
            cmd += ["--input", a.input]
        for name in order:
            r = one(cmd, dict(base, **VARIANTS[name]))
            if r["rc"] != 0:
                print(f"bench_malloc: the {name} run failed (exit {r['rc']})", file=sys.stderr)
                return 1
            print(f"{name:8s} wall {r['wall']:6.1f} s  user {r['user']:6.2f} s  sys {r['sys']:5.2f} s  "
                  f"minor faults {r['minflt']:8d}  peak RSS {r['rss']:4.0f} MB  peak anonymous {r['anon']:4.0f} MB  "
                  f"(load average {os.getloadavg()[0]:.1f})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
