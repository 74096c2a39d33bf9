"""Print the exit code and stderr of every bad-input case of issue "Hardening" (the acceptance table).

Each case runs the real CLI in a subprocess (so exit codes, stderr and file-size limits are those a user
sees) in a fresh directory, then lists the files left there and checks the input recording's checksum.
tests/system/test_bad_inputs.py asserts the same cases; scripts/bench/signal_trials.py repeats the signal cases.

    PYTHONPATH=$PWD .venv/bin/python scripts/bench/bad_input_matrix.py
"""
from __future__ import annotations

import hashlib
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "configs" / "scenarios" / "static_default.yaml"
FS = 2.0e6
LATIN1 = "# Genève\n".encode("latin-1")


def sha(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def cli(args, cwd, preexec_fn=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "receiver.cli", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, preexec_fn=preexec_fn, timeout=900)


def make_recording(prefix: str) -> Path:
    """A fresh directory with a 3-s simulated recording rec.bin, its RINEX nav rec.nav and rec.yaml (the
    receiver config reading both): the input of the bad-input cases and of scripts/bench/signal_trials.py."""
    from receiver.batch.tasks import write_nav_for_scenario
    from receiver.sim.scenario import load_scenario
    from receiver.sim.simulate import simulate
    base = Path(tempfile.mkdtemp(prefix=prefix))
    ov = [("time.duration_s", 3.0), ("frontend.sample_rate_hz", FS)]
    paths = simulate(SCENARIO, base / "rec.bin", ov, progress=False)
    write_nav_for_scenario(load_scenario(SCENARIO, ov).to_dict(), str(base / "rec.nav"))
    cfg = yaml.safe_load(Path(paths["yaml"]).read_text())
    cfg["input"]["path"] = str(base / "rec.bin")
    cfg["navigation"] = {"ephemeris": str(base / "rec.nav")}
    (base / "rec.yaml").write_text(yaml.safe_dump(cfg))
    return base


def main():
    base = make_recording("bad_inputs_")
    rec_yaml = base / "rec.yaml"
    digest = sha(base / "rec.bin")
    # inputs of the cases
    zeros, const = base / "zeros.bin", base / "const.bin"
    np.zeros(2 * int(FS), np.int8).tofile(zeros)
    c = np.zeros(2 * int(FS), np.int8)
    c[0::2], c[1::2] = 23, -9
    c.tofile(const)
    head = (base / "rec.nav").read_text().split("END OF HEADER")[0] + "END OF HEADER\n"
    (base / "empty.nav").write_text(head)
    (base / "v2body.nav").write_text(head + "12 22  1  1  2  0  0.0" + " 0.100000000000D-03" * 3 + "\n"
                                     + ("   " + " 0.100000000000D+01" * 4 + "\n") * 7)
    (base / "latin1.yaml").write_bytes(LATIN1 + rec_yaml.read_bytes())
    (base / "latin1_sc.yaml").write_bytes(LATIN1 + b"time: {duration_s: 0.05}\n")
    (base / "latin1_batch.yaml").write_bytes(LATIN1 + b"runs: []\n")
    (base / "t.csv").write_bytes(LATIN1 + b"0,4331297,567555,4633133\n10,4331297,567555,4633133\n")
    (base / "csv_sc.yaml").write_text(yaml.safe_dump({"time": {"duration_s": 0.05},
                                                      "receiver": {"trajectory": "csv",
                                                                   "csv": {"path": str(base / "t.csv")}}}))
    (base / "sc.yaml").write_text(SCENARIO.read_text())
    long_name = "r" * 252 + ".h5"
    (base / "adir.h5").mkdir()
    (base / "afile").write_text("x")
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    (base / "locked.h5.lock").write_text(f"{holder.pid}\n")

    def fsize(n):
        return lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (n, n))

    run = ["run", rec_yaml]
    cases = [
        ("output = input", run + ["-o", base / "rec.bin"], None),
        ("output = config", run + ["-o", rec_yaml], None),
        ("output is a directory", run + ["-o", base / "adir.h5"], None),
        ("output dir cannot be made", run + ["-o", base / "afile" / "x" / "r.h5"], None),
        ("255-byte output name", run + ["-o", base / long_name], None),
        ("output locked by a live run", run + ["-o", base / "locked.h5"], None),
        ("output.rinex over the nav input", run + ["-o", base / "rec.h5", "--set", "output.rinex=true"], None),
        ("disk full (RLIMIT_FSIZE 200 kB)", run + ["-o", base / "full.h5", "-q"], fsize(200_000)),
        ("simulate disk full (300 kB)", ["simulate", SCENARIO, "-o", base / "sfull.bin", "-q", "--set",
                                         "time.duration_s=0.5"], fsize(300_000)),
        ("simulate over its scenario", ["simulate", base / "sc.yaml", "-o", base / "sc.bin", "-q"], None),
        ("all-zero input: run", run + ["--input", zeros, "-o", base / "z.h5", "-q"], None),
        ("all-zero input: acquire", ["acquire", rec_yaml, "--input", zeros], None),
        ("constant input: run", run + ["--input", const, "-o", base / "c.h5", "-q"], None),
        ("if_hz beyond fs/2", run + ["-o", base / "i.h5", "--set", "input.if_hz=1.2e6"], None),
        ("real format, if_hz 0", run + ["-o", base / "i.h5", "--set", "input.format=int8_real"], None),
        ("acquisition.prns: []", run + ["-o", base / "i.h5", "--set", "acquisition.prns=[]"], None),
        ("duplicate PRNs", ["acquire", rec_yaml, "--set", "acquisition.prns=[3,3,5]"], None),
        ("RINEX header only", run + ["-o", base / "i.h5", "--set", f"navigation.ephemeris={base / 'empty.nav'}"],
         None),
        ("RINEX v2 body, v3 header", run + ["-o", base / "i.h5", "--set",
                                            f"navigation.ephemeris={base / 'v2body.nav'}"], None),
        ("vector.start_s after the end", run + ["-o", base / "v.h5", "-q", "--set", "vector.enabled=true",
                                                "--set", "vector.start_s=100", "--set", "input.duration_s=1"],
         None),
        ("non-UTF-8 config", ["run", base / "latin1.yaml", "-o", base / "i.h5"], None),
        ("non-UTF-8 scenario", ["simulate", base / "latin1_sc.yaml", "-o", base / "s.bin"], None),
        ("non-UTF-8 batch file", ["batch", base / "latin1_batch.yaml", "--dry-run"], None),
        ("non-UTF-8 trajectory CSV", ["simulate", base / "csv_sc.yaml", "-o", base / "s.bin"], None),
    ]
    before = set(os.listdir(base))
    try:
        for name, args, pre in cases:
            r = cli(args, base, pre)
            lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
            new = sorted(set(os.listdir(base)) - before)
            for n in new:                              # keep the directory as it was for the next case
                p = base / n
                if p.is_file():
                    p.unlink()
            tb = "Traceback" in r.stderr
            print(f"{name:32s} exit {r.returncode:3d}  {len(lines)} line{'s' if len(lines) != 1 else ''}"
                  f"{'  TRACEBACK' if tb else ''}  {' | '.join(lines)[:150]}"
                  + (f"  files: {new}" if new else ""), flush=True)
    finally:
        holder.kill()
        holder.wait()
    print(f"input checksum unchanged: {sha(base / 'rec.bin') == digest}")


if __name__ == "__main__":
    main()
