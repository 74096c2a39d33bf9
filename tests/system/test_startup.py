"""Start-up of ``gnssrx run`` (issue 19: a 1-s file in <= 2 s with a warm numba cache): the run path does
not import the scipy modules it no longer needs, and numba's BLAS still works after the light first load
(receiver/_numba_start.py)."""
import json
import os
import subprocess
import sys

import numpy as np

from synth import make_signal

from repo_paths import ROOT

SATS = [dict(prn=p, doppler_hz=d, code_phase_chips=c, cn0_dbhz=46.0)
        for p, d, c in ((3, 1200.0, 100.0), (7, -2300.0, 400.0), (11, 3100.0, 800.0), (17, -700.0, 50.0),
                        (22, 2500.0, 600.0), (28, -3600.0, 950.0))]

PROBE = r"""
import json, runpy, sys
sys.argv = ["gnssrx", "run", sys.argv[1], "--input", sys.argv[2], "-o", sys.argv[3], "-q",
            "--set", "input.format=int8_iq", "--set", "input.sample_rate_hz=2600000", "--set", "input.if_hz=0"]
try:
    runpy.run_module("receiver.cli", run_name="__main__")
except SystemExit as exc:
    code = exc.code
scipy_mods = sorted(m for m in sys.modules if m.startswith("scipy."))
import numpy as np
from numba import njit
@njit
def dot(a, b):
    return np.dot(a, b)
a = np.arange(9.0).reshape(3, 3)
print(json.dumps({"code": code, "scipy": scipy_mods, "dot_ok": bool(np.array_equal(dot(a, a), a @ a))}))
"""


def test_run_path_imports_no_heavy_scipy_module(tmp_path):
    x = make_signal(SATS, duration_s=0.5, seed=3) * 20.0
    iq = np.empty(2 * x.size, np.int8)
    iq[0::2] = np.clip(np.rint(x.real), -127, 127)
    iq[1::2] = np.clip(np.rint(x.imag), -127, 127)
    f = tmp_path / "x.bin"
    iq.tofile(f)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    p = subprocess.run([sys.executable, "-c", PROBE, str(ROOT / "configs" / "default.yaml"), str(f),
                        str(tmp_path / "x.h5")], capture_output=True, text=True, env=env, cwd=tmp_path,
                       timeout=300)
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert out["code"] in (0, None), p.stderr
    import h5py
    with h5py.File(tmp_path / "x.h5", "r") as h:
        found = sorted(int(q) for q, d in zip(h["acquisition/prn"][:], h["acquisition/detected"][:]) if d)
    assert found == sorted(s["prn"] for s in SATS)
    heavy = [m for m in out["scipy"] if m.split(".")[1] in ("fft", "special", "stats", "linalg", "signal")]
    assert heavy == [], heavy
    assert out["dot_ok"]                   # numba compiles and runs np.dot (BLAS) after the light start



FAST_EXIT = r"""
import atexit, gc, os, sys
import receiver.cli
from receiver.cli import main
if os.environ.get("GC_PROBE"):     # (not for the error exit: the wrapper would tie __main__ to receiver.cli)
    def _frozen(f=receiver.cli._freeze_gc):
        f()
        print(f"gc frozen {gc.get_freeze_count()} enabled {gc.isenabled()}", file=sys.stderr, flush=True)
    receiver.cli._freeze_gc = _frozen
atexit.register(lambda: print("atexit handler ran", flush=True))
class Teardown:
    def __del__(self):
        print("module teardown", flush=True)
keep = Teardown()                  # deleted only by the interpreter's teardown of __main__
sys.argv = ["gnssrx"] + sys.argv[1:]
print("before", end="")            # unflushed at the exit
main()
"""


def test_a_finished_run_exits_without_teardown_but_with_atexit_and_status(tmp_path):
    """After a completed ``gnssrx run`` the process ends with os._exit once the atexit handlers ran and
    stdout was flushed (receiver/cli.py _exit_now): status 0, pending output kept, the run file in place,
    and the interpreter's teardown of the modules (0.2-0.5 s with numba loaded) skipped.  An error exit
    (status 2) ends as usual."""
    x = make_signal(SATS, duration_s=0.5, seed=4) * 20.0
    iq = np.empty(2 * x.size, np.int8)
    iq[0::2] = np.clip(np.rint(x.real), -127, 127)
    iq[1::2] = np.clip(np.rint(x.imag), -127, 127)
    iq.tofile(tmp_path / "x.bin")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    ok = subprocess.run([sys.executable, "-c", FAST_EXIT, "run", str(ROOT / "configs" / "default.yaml"),
                         "--input", str(tmp_path / "x.bin"), "-o", str(tmp_path / "x.h5"), "-q",
                         "--set", "input.format=int8_iq", "--set", "input.sample_rate_hz=2600000",
                         "--set", "input.if_hz=0", "--set", "acquisition.prns=[3,7,11,17,22,28]"],
                        capture_output=True, text=True, env=dict(env, GC_PROBE="1"), cwd=tmp_path, timeout=300)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.startswith("beforeoutput") and "atexit handler ran" in ok.stdout
    assert "module teardown" not in ok.stdout
    # the objects of the imports were put out of the garbage collector's reach (receiver/cli.py _freeze_gc)
    frozen = [ln.split() for ln in ok.stderr.splitlines() if ln.startswith("gc frozen")]
    assert len(frozen) == 1 and int(frozen[0][2]) > 50000 and frozen[0][4] == "True", ok.stderr
    import h5py
    with h5py.File(tmp_path / "x.h5", "r") as h:
        assert int(h["acquisition/detected"][:].sum()) == 6
    bad = subprocess.run([sys.executable, "-c", FAST_EXIT, "run", str(tmp_path / "none.yaml")],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert bad.returncode == 2 and "config file not found" in bad.stderr and "Traceback" not in bad.stderr
    assert "atexit handler ran" in bad.stdout and "module teardown" in bad.stdout


def test_a_test_runner_keeps_its_garbage_collector(tmp_path):
    """``main`` called by a test runner or a script (not the process's command line) leaves the collector
    alone: nothing frozen, still enabled."""
    import gc
    from click.testing import CliRunner
    from receiver.cli import main
    frozen = gc.get_freeze_count()
    r = CliRunner().invoke(main, ["run", str(tmp_path / "none.yaml")])
    assert r.exit_code == 2 and "config file not found" in r.output
    assert gc.isenabled() and gc.get_freeze_count() == frozen
