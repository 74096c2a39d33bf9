"""Shared fixtures, and the test-suite conventions.

Every test under ``tests/system/`` (end-to-end runs on recordings) is marked ``slow``, as are the unit tests
that take seconds (``@pytest.mark.slow``): ``make test-fast`` runs the rest (``-m "not slow"``).

``tokyo_run``: the path of the run file of the third-party reference recording
(``../shared/data/gpssim_static_tokyo.bin``, GPS-SDR-SIM, static antenna in Tokyo) processed once per test
session with ``configs/gpssim_static_tokyo.yaml`` (troposphere off, Klobuchar on, default weighting) in
assisted mode (ephemerides from ``../shared/data/brdc0010.22n``; fixes from ~10 s, about 340 fixes at
10 Hz).  It takes about 20 s.  Skips when ../shared is absent.  Under pytest-xdist (``make test`` runs
``-n auto``) the workers share one run: the first to need it runs it under a file lock in the session's
common temporary directory, the others wait and reuse it.  Treat the file as read-only: tests that
write files beside a run file should link or copy it into their own tmp_path first.
"""
import sys
from pathlib import Path

import pytest

# the test helpers (repo_paths, synth) import by name from every test folder
sys.path.insert(0, str(Path(__file__).resolve().parent))

from repo_paths import ROOT, TOKYO_META, TOKYO_NAV, TOKYO_REC  # noqa: E402

import receiver  # noqa: E402

receiver.limit_blas_threads()          # as the command line (before numpy loads)
from receiver.tracking import refresh_compiled_caches  # noqa: E402

refresh_compiled_caches()              # a changed compiled callee: its callers compile again


def _shared_tmp(tmp_path_factory) -> Path:
    """A directory every xdist worker of this session sees (the per-worker base's parent), or the
    session's base directory without xdist."""
    import os
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@pytest.fixture(scope="session")
def tokyo_run(tmp_path_factory):
    if not (TOKYO_REC.exists() and TOKYO_NAV.exists()):
        pytest.skip("../shared/data reference recording (gpssim_static_tokyo.bin, brdc0010.22n) absent")
    import fcntl
    d = _shared_tmp(tmp_path_factory) / "tokyo_run"
    d.mkdir(exist_ok=True)
    out = d / "tokyo.h5"
    with open(d / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)          # released when the file closes
        if not out.exists():
            _run_tokyo(out)
    assert out.exists()
    return out


def _run_tokyo(out: Path) -> None:
    from receiver.schema import load_receiver_config
    from receiver.pipeline import run
    cfg = load_receiver_config(ROOT / "configs" / "gpssim_static_tokyo.yaml",
                               [("input.path", str(TOKYO_REC)), ("output.path", str(out)),
                                ("navigation.ephemeris", str(TOKYO_NAV)),
                                # RTKLIB's error model, so rnx2rtkp on the exported files is judged
                                # against our fixes on equal terms (tests/unit/export/test_export_rinex.py)
                                ("navigation.weighting", "rtklib")])
    run(cfg, quiet=True)


@pytest.fixture(scope="session")
def tokyo_exports(tokyo_run, tmp_path_factory):
    """The reference run linked into its own directory with every standard output written beside it
    (``export_all``): dict kind -> path, plus ``h5`` (the linked run file)."""
    import os
    import shutil

    from receiver.export import export_all
    d = tmp_path_factory.mktemp("tokyo_exports")
    h5 = d / "tokyo.h5"
    try:
        os.symlink(tokyo_run, h5)
    except OSError:
        shutil.copy(tokyo_run, h5)
    written = export_all(h5, {"rinex": True, "nmea": True, "kml": True, "gpx": True, "report": True},
                         truth=str(TOKYO_META))
    written["h5"] = str(h5)
    return written


def pytest_collection_modifyitems(config, items):
    """The system tests are slow by convention (their folder), besides the unit tests marked one by one."""
    system = ROOT / "tests" / "system"
    for item in items:
        if system in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.slow)
