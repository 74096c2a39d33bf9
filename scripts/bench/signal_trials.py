"""SIGINT / SIGTERM trials for ``gnssrx run`` and ``gnssrx simulate`` (issue "Hardening", acceptance).

Each trial starts the CLI in a subprocess, waits until its temporary output file (``.partial``) exists,
waits a random 0-1.5 s more (seeded) and sends the signal.  A trial is clean when the process exits with
128 + the signal number (130 / 143), prints exactly one line on stderr ("gnssrx: interrupted by ...") and
no traceback, leaves no output file (final, ``.partial`` or ``.lock``) and the input recording's checksum
is unchanged.  A trial whose process had already finished when the signal was due is reported as "late"
and not counted as clean.

    PYTHONPATH=$PWD .venv/bin/python scripts/bench/signal_trials.py --trials 20      # 20 per signal and command
"""
from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

from bad_input_matrix import FS, ROOT, SCENARIO, make_recording, sha  # (same folder)


def trial(args, cwd: Path, watch: Path, sig, delay_s: float, timeout: float = 600.0) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "receiver.cli", *map(str, args)], cwd=cwd, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    while not watch.exists() and p.poll() is None and time.monotonic() - t0 < timeout:
        time.sleep(0.01)
    time.sleep(delay_s)
    sent = p.poll() is None
    if sent:
        p.send_signal(sig)
    _, err = p.communicate(timeout=timeout)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    left = sorted(os.listdir(cwd))
    ok = (sent and p.returncode == 128 + sig and len(lines) == 1 and "Traceback" not in err
          and lines[0].startswith(f"gnssrx: interrupted by {signal.Signals(sig).name}") and not left)
    return {"sent": sent, "rc": p.returncode, "stderr": lines, "left": left, "ok": ok}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20, help="trials per signal and command")
    ap.add_argument("--seed", type=int, default=15)
    ap.add_argument("--max-delay", type=float, default=1.5)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    base = make_recording("signal_trials_")      # the bad-input matrix's 3-s recording + nav + config
    digest = sha(base / "rec.bin")
    totals = {}
    for cmd in ("run", "simulate"):
        for sig in (signal.SIGINT, signal.SIGTERM):
            name = signal.Signals(sig).name
            clean = late = 0
            for k in range(a.trials):
                d = base / f"{cmd}_{name}_{k}"
                d.mkdir()
                delay = rng.uniform(0.0, a.max_delay)
                if cmd == "run":
                    r = trial(["run", base / "rec.yaml", "-o", d / "r.h5"], d, d / "r.h5.partial", sig, delay)
                    r["ok"] = r["ok"] and sha(base / "rec.bin") == digest
                else:
                    r = trial(["simulate", SCENARIO, "-o", d / "s.bin", "-q", "--set", "time.duration_s=20",
                               "--set", f"frontend.sample_rate_hz={FS}"], d, d / "s.bin.partial", sig, delay)
                clean += r["ok"]
                late += not r["sent"]
                print(f"{cmd:8s} {name:7s} #{k:02d} delay {delay:4.2f} s  exit {r['rc']:4d}  "
                      f"{'clean' if r['ok'] else 'NOT CLEAN'}  stderr: {' | '.join(r['stderr'])[:90]}"
                      + (f"  left: {r['left']}" if r["left"] else "") + ("  (finished first)" if not r["sent"]
                                                                        else ""), flush=True)
            totals[(cmd, name)] = (clean, late)
    import shutil
    shutil.rmtree(base, ignore_errors=True)
    print()
    for (cmd, name), (clean, late) in totals.items():
        print(f"{cmd:8s} {name:7s} {clean}/{a.trials} clean" + (f" ({late} finished before the signal)"
                                                                 if late else ""))
    sys.exit(0 if all(c == a.trials for c, _ in totals.values()) else 1)


if __name__ == "__main__":
    main()
