"""The example plugin package (docs/examples/gnssrx-fll-pll) installed beside a non-editable gnssrx: its wheel
and gnssrx's (built as tests/system/test_install.py builds it: no build isolation, no network, no
dependencies) installed into a fresh target directory, then `gnssrx plugins` shows it, `gnssrx run` tracks
with it (the run file records its name, version and parameters), `gnssrx batch` runs it against the
built-in PLL on simulated truth and `gnssrx compare` tabulates both; the package's own tests pass against
the installed copies.  Mostly numba compiling the installed copy's kernels: slow."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from repo_paths import ROOT
from test_install import _build_wheel

EXAMPLE = ROOT / "docs" / "examples" / "gnssrx-fll-pll"


def _plugin_wheel(dest: Path) -> Path:
    src = dest / "plugin_src"
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                        str(dest / "plugin_dist"), str(src)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = (dest / "plugin_dist").glob("gnssrx_fll_pll-*.whl")
    return whl


@pytest.mark.slow
def test_example_plugin_installs_and_runs_through_run_batch_and_compare(tmp_path):
    wheels = [_build_wheel(tmp_path), _plugin_wheel(tmp_path)]
    site = tmp_path / "site"
    r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-compile", "--target",
                        str(site), *map(str, wheels)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    gnssrx = site / "bin" / "gnssrx"
    work = tmp_path / "work"
    work.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site)}
    env.pop("PYTHONSAFEPATH", None)

    def cli(*args, check=True):
        res = subprocess.run([str(gnssrx), *args], cwd=work, env=env, capture_output=True, text=True)
        if check:
            assert res.returncode == 0, res.stderr[-3000:]
        return res

    out = cli("plugins").stdout
    line = next(ln for ln in out.splitlines() if ln.split()[:1] == ["fll_pll"])
    assert "plugin" in line and "0.1.0" in line and "entry point gnssrx.carrier_loops of gnssrx-fll-pll" in line
    # a short recording with truth, then a run with the plugin
    cli("simulate", "configs/scenarios/static_default.yaml", "-o", "s.bin", "--set", "time.duration_s=4",
        "--set", "constellation.prns=[6]", "--quiet")
    cli("run", "s.yaml", "-o", "run.h5", "--quiet", "--threads", "1", "--set", "tracking.carrier.variant=fll_pll",
        "--set", "tracking.carrier.fll_pll.fll_bw_hz=3.0", "--set", "navigation.enabled=false")
    with h5py.File(work / "run.h5") as f:
        used = json.loads(f.attrs["plugins"])
        assert used[0]["name"] == "fll_pll" and used[0]["version"] == "0.1.0"
        assert used[0]["params"] == {"pll_bw_hz": 15.0, "fll_bw_hz": 3.0}
        assert str(site) in f.attrs["git_commit"] or f.attrs["git_commit"] == ""   # the installed copy ran
    # batch: the plugin against the built-in PLL on simulated truth, then compare
    (work / "b.yaml").write_text(
        "name: plug\noutput_dir: out/plug\njobs: 1\n"
        "set: {navigation.rate_hz: 2.0, acquisition.prns: [1, 6, 7, 9, 10, 12, 13, 16, 22, 30, 32]}\n"
        "variants:\n  - name: pll\n  - name: fll_pll\n    set: {tracking.carrier.variant: fll_pll}\n"
        "inputs:\n  - name: static\n    scenario: configs/scenarios/static_default.yaml\n"
        "    set: {time.duration_s: 6.0}\n    assisted: true\n")
    cli("batch", "b.yaml", "--quiet")
    summary = work / "out" / "plug" / "summary.h5"
    table = cli("compare", str(summary), "--no-plot").stdout
    lines = table.splitlines()
    header = next(ln for ln in lines if ln.startswith("metric"))
    assert header.split()[1:] == ["pll", "fll_pll"], table             # one column per variant
    runs = next(ln for ln in lines if ln.startswith("runs (ok / all)"))
    assert runs.split()[-6:] == ["1", "/", "1", "1", "/", "1"], table   # both ran and scored on the truth
    rms = next(ln for ln in lines if ln.startswith("pos_3d_rms_m")).split()[1:]
    assert all(float(v) < 15.0 for v in rms), table                     # both give fixes near the truth
    # the package's own tests, against the installed gnssrx and plugin
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(EXAMPLE / "tests"),
                        "--rootdir", str(EXAMPLE)], cwd=work, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-1000:]
