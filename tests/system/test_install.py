"""Installable package (issue 18): the wheel built from this tree, installed non-editable into a
separate directory, runs `gnssrx simulate` and `gnssrx run` in an empty directory with the shipped
configs/ and data/ (package data found through importlib.resources).

Cheap by construction: the wheel is built without build isolation and without dependencies, installed
with ``pip install --no-deps --target``, and its ``gnssrx`` script runs on this interpreter (which has the
dependencies); the recording is 0.3 s with one satellite.

The example plugin package (docs/examples/gnssrx-fll-pll) installed beside the non-editable gnssrx (its wheel
into the same target directory): `gnssrx plugins` shows it, `gnssrx run` tracks with it (the run file records
its name, version and parameters), `gnssrx batch` runs it against the built-in PLL on simulated truth and
`gnssrx compare` tabulates both; the package's own tests pass against the installed copies.

Most of the time is numba compiling the installed copy's kernels (the cache is per source path): both tests
share one installed directory, so they are compiled once.  Marked slow."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from repo_paths import ROOT


def _build_wheel(dest: Path) -> Path:
    try:
        import setuptools
        st_version = tuple(int(x) for x in setuptools.__version__.split(".")[:2])
    except ImportError:
        st_version = (0, 0)
    new_setuptools = st_version >= (70, 1)
    env = dict(os.environ)
    if st_version < (77, 0):        # pyproject's SPDX `license = "MIT"` (PEP 639) needs setuptools >= 77
        tools = dest / "buildtools"
        r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(tools),
                            "setuptools>=77"], capture_output=True, text=True)
        if r.returncode:
            pytest.skip("pyproject.toml's SPDX licence string needs setuptools >= 77 and it could not be "
                        "fetched: " + r.stderr.strip()[-200:])
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(tools), env.get("PYTHONPATH")]))
        new_setuptools = True
    try:
        import wheel  # noqa: F401   (older setuptools build wheels through it)
        have_wheel = True
    except ImportError:
        have_wheel = False
    if not (new_setuptools or have_wheel):      # fetch 'wheel' beside the build (not into this environment)
        tools = dest / "buildtools_wheel"
        r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(tools),
                            "wheel"], capture_output=True, text=True)
        if r.returncode:
            pytest.skip("building the wheel without build isolation needs setuptools >= 70.1 or the 'wheel' "
                        "package, and it could not be fetched: " + r.stderr.strip()[-200:])
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(tools), env.get("PYTHONPATH")]))
    # build from a copy: the build writes build/ and *.egg-info beside the sources
    src = dest / "src"
    shutil.copytree(ROOT, src, symlinks=True,
                    ignore=shutil.ignore_patterns(".git", ".venv", "out", "figures", "site", "build",
                                                  "*.egg-info", "__pycache__", ".pytest_cache", "*.h5", "*.bin"))
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                        "-q", "-w", str(dest / "dist"), str(src)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = (dest / "dist").glob("gnssrx-*.whl")
    return whl


EXAMPLE = ROOT / "docs" / "examples" / "gnssrx-fll-pll"


def _plugin_wheel(dest: Path) -> Path:
    src = dest / "plugin_src"
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                        str(dest / "plugin_dist"), str(src)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = (dest / "plugin_dist").glob("gnssrx_fll_pll-*.whl")
    return whl


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """gnssrx's wheel and the example plugin's, installed into one fresh target directory: (gnssrx wheel,
    target directory, the environment that imports from it)."""
    d = tmp_path_factory.mktemp("install")
    whl = _build_wheel(d)
    site = d / "site"
    r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-compile", "--target",
                        str(site), str(whl), str(_plugin_wheel(d))], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    env = {**os.environ, "PYTHONPATH": str(site)}
    env.pop("PYTHONSAFEPATH", None)
    return whl, site, env


@pytest.mark.slow
def test_wheel_installs_and_runs_in_an_empty_directory(installed, tmp_path):
    whl, site, env = installed
    import zipfile
    names = zipfile.ZipFile(whl).namelist()
    for f in ("receiver/_share/configs/default.yaml", "receiver/_share/configs/scenarios/static_default.yaml",
              "receiver/_share/data/gps_nominal_constellation.yaml", "receiver/_share/data/iridium_synthetic.tle"):
        assert f in names, f
    # the long description is the (short) README: what `pip show -v gnssrx` and a package index show
    meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
    body = zipfile.ZipFile(whl).read(meta).decode().split("\n\n", 1)[1]
    readme = (ROOT / "README.md").read_text()
    assert body.strip() == readme.strip() and len(readme.splitlines()) <= 300
    gnssrx = site / "bin" / "gnssrx"
    assert gnssrx.exists()
    work = tmp_path / "empty"
    work.mkdir()
    # the installed copy is the one that runs (not this checkout)
    r = subprocess.run([str(gnssrx), "--help"], cwd=work, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-c", "import receiver.config as c; print(c.__file__, c.shipped_dir())"],
                       cwd=work, env=env, capture_output=True, text=True)
    assert str(site) in r.stdout.split()[0] and str(site) in r.stdout.split()[1], r.stdout
    r = subprocess.run([str(gnssrx), "simulate", "configs/scenarios/static_default.yaml", "-o", "x.bin",
                        "--set", "time.duration_s=0.3", "--set", "constellation.prns=[6]", "--quiet"],
                       cwd=work, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    r = subprocess.run([str(gnssrx), "run", "configs/default.yaml", "--input", "x.bin", "--quiet",
                        "--set", "acquisition.prns=[6,9]", "--set", "acquisition.coherent_ms=1",
                        "--set", "acquisition.noncoherent=10", "--set", "navigation.enabled=false"],
                       cwd=work, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    with h5py.File(work / "x.h5") as f:                      # found and tracked: PRN 6 only
        assert list(f["channels"]) == ["G06"] and len(f["channels/G06/time_s"]) > 100
        acq = dict(zip(f["acquisition/prn"][:], f["acquisition/detected"][:]))
        assert acq[6] and not acq[9]


@pytest.mark.slow
def test_example_plugin_installs_and_runs_through_run_batch_and_compare(installed, tmp_path):
    _, site, env = installed
    gnssrx = site / "bin" / "gnssrx"
    work = tmp_path / "work"
    work.mkdir()

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
