"""scripts/bench/bench_scaling.py's sampler: /proc samples of a child's memory and CPU, and the processed
signal seconds read from the progress bar it draws on a pseudo-terminal."""
import importlib.util
import sys

import pytest

from repo_paths import ROOT, TOKYO_REC

SCRIPT = ROOT / "scripts" / "bench" / "bench_scaling.py"
spec = importlib.util.spec_from_file_location("bench_scaling", SCRIPT)
bs = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bs)

# a child that holds 200 MB of touched anonymous memory for a while, then burns some CPU
HOLD = "import time; b = bytearray(200 * 2**20); time.sleep(1.0); sum(range(3 * 10**6)); time.sleep(0.3)"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_the_sampler_sees_the_childs_memory_and_cpu():
    r = bs.run_sampled([sys.executable, "-c", HOLD], interval=0.05)
    assert r["returncode"] == 0
    s = r["samples"]
    assert len(s) >= 10
    assert max(x["anon_mb"] for x in s) >= 195            # the bytearray is anonymous memory
    assert r["peak_rss_mb"] >= max(x["rss_mb"] for x in s) >= 200
    cpu = [x["cpu_s"] for x in s]
    assert cpu == sorted(cpu) and cpu[-1] > cpu[0]
    assert [x["t_s"] for x in s] == sorted(x["t_s"] for x in s)
    assert bs.proc_sample(2**22 + 12345) is None           # no such process


def test_progress_is_the_last_bar_update():
    text = ("\rtracking |#   | 0.0/3600.0 s [00:00<?]\rtracking |##  | 12.5/3600.0 s [00:10<40:00]"
            "\rtracking |### | 13.0/3600.0 s [00:11<39:59]")
    assert bs.last_progress(text) == 13.0
    assert bs.last_progress("output   run.h5\nsignal   1.0 s processed") is None


@pytest.mark.slow
@pytest.mark.skipif(not TOKYO_REC.exists(), reason="../shared/data reference recording absent")
def test_a_real_run_reports_its_progress(tmp_path):
    cmd = bs._run_cmd(TOKYO_REC, ROOT / "configs" / "gpssim_static_tokyo.yaml", 2.0, tmp_path / "run.h5")
    r = bs.run_sampled(cmd, interval=0.2, env=bs._env())
    assert r["returncode"] == 0, r["stderr"][-500:]
    assert bs.last_progress(r["stderr"]) == 2.0            # the bar's last update: the whole 2 s
    assert "signal          2.0 s processed" in r["stdout"]
