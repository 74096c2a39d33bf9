"""Installable package (issue 18): the wheel built from this tree, installed non-editable into a
separate directory, runs `gnssrx simulate` and `gnssrx run` in an empty directory with the shipped
configs/ and data/ (package data found through importlib.resources).

Cheap by construction: the wheel is built without build isolation and without dependencies, installed
with ``pip install --no-deps --target``, and its ``gnssrx`` script runs on this interpreter (which has the
dependencies); the recording is 0.3 s with one satellite.  Most of its time is numba compiling the
installed copy's kernels (the cache is per source path): ~20 s CPU.  Marked slow."""
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


@pytest.mark.slow
def test_wheel_installs_and_runs_in_an_empty_directory(tmp_path):
    whl = _build_wheel(tmp_path)
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
    site = tmp_path / "site"
    r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-compile", "--target",
                        str(site), str(whl)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    gnssrx = site / "bin" / "gnssrx"
    assert gnssrx.exists()
    work = tmp_path / "empty"
    work.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site)}
    env.pop("PYTHONSAFEPATH", None)
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
