"""Warm batch workers (receiver/batch/warm.py): the compiled kernels are loaded from numba's cache, not
compiled, and a warm pool's run files are those of separate ``gnssrx run`` processes."""
import json
import os
import subprocess
import sys

import pytest
import yaml

from repo_paths import ROOT

# a fresh interpreter: call one cached kernel (compiles and saves it when the cache lacks it)
FILL = r"""
import numpy as np
from receiver.acquisition.code_search import _mul_rows
spec = np.ones((2, 8), np.float32); out = np.empty((2, 8), np.float32)
_mul_rows(spec, np.zeros(2, np.int64), spec.copy(), out)
"""

# another fresh interpreter: warm, then report what the kernel holds and whether anything was compiled
PROBE = r"""
import json
from numba.core.dispatcher import Dispatcher
from receiver.batch.warm import load_cached_kernels, warm
rec = warm()
import receiver.acquisition.code_search as cs
import sys
misses = sum(sum(o.stats.cache_misses.values()) for m in list(sys.modules.values()) if m and
             m.__name__.startswith("receiver.") for o in list(vars(m).values()) if isinstance(o, Dispatcher))
print(json.dumps({"kernels": rec["kernels"], "mul_rows": len(cs._mul_rows.signatures),
                  "hits": sum(cs._mul_rows.stats.cache_hits.values()), "misses": misses,
                  "again": load_cached_kernels(), "second": warm() is rec}))
"""


def _py(code):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    return p.stdout


@pytest.mark.slow
def test_warm_loads_the_cached_kernels_without_compiling():
    _py(FILL)
    d = json.loads(_py(PROBE).strip().splitlines()[-1])
    assert d["kernels"] >= 1 and d["mul_rows"] >= 1 and d["hits"] >= 1     # loaded before its first call
    assert d["misses"] == 0                                                 # nothing was compiled
    assert d["again"] == 0 and d["second"]                                  # once per process


@pytest.mark.slow
def test_a_warm_pool_gives_the_run_files_of_separate_runs(tmp_path):
    """Two short runs of a simulated recording through the warm local pool (jobs 2) against ``gnssrx run``
    of the same configurations, each in its own process: the same run files bit for bit."""
    from receiver.batch.runner import run_batch
    from receiver.runfile.compare import compare_h5
    batch = {"name": "warm", "output_dir": str(tmp_path / "out"), "recordings_dir": str(tmp_path / "rec"),
             "set": {"acquisition.prns": [1, 6, 7, 9, 10, 12], "navigation.rate_hz": 2.0},
             "sweep": {"tracking.pll_bw_hz": [15.0, 25.0]},
             "inputs": [{"name": "static", "scenario": str(ROOT / "configs/scenarios/static_default.yaml"),
                         "set": {"time.duration_s": 3.0}}]}
    res = run_batch(batch, jobs=2)
    assert res.executed == 2 and res.failed == 0 and res.executor == "local 2 jobs"
    for row in res.rows:
        h5 = tmp_path / "out" / "runs" / f"{row['run_id']}.h5"
        import h5py
        with h5py.File(h5) as f:
            cfg = yaml.safe_load(f.attrs["config"])
        cfg["output"]["path"] = None
        (tmp_path / "sep").mkdir(exist_ok=True)
        conf = tmp_path / "sep" / f"{row['run_id']}.yaml"
        conf.write_text(yaml.safe_dump(cfg))
        other = tmp_path / "sep" / h5.name
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
        p = subprocess.run([sys.executable, "-m", "receiver.cli", "run", str(conf), "-o", str(other), "-q"],
                           capture_output=True, text=True, env=env)
        assert p.returncode == 0, p.stderr
        out = []
        compare_h5(h5, other, out)
        assert out == [], out[:5]
