"""Shared fixtures, and the test-suite conventions.

Every test under ``tests/system/`` (end-to-end runs on recordings) and every test that uses ``tokyo_run`` is marked
``slow``, as are the unit tests that take seconds (``@pytest.mark.slow``): ``make test-fast`` runs the rest
(``-m "not slow"``).

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


def _l5_test_table():
    """The GPS L5 XB-advance table of the test suite (receiver/gnss/l5_codes.py ships none): distinct advances
    of our own choosing, so the simulator and the receiver use one consistent code family (not GPS's codes).
    A user's table in GNSSRX_L5_XB_TABLE is left alone."""
    import os
    import tempfile
    if os.environ.get("GNSSRX_L5_XB_TABLE"):
        return
    # the first 64 advances from 101 in steps of 3 whose codes are balanced within 20 chips, autocorrelation
    # sidelobes < 0.04 and cross-correlation with the ones before < 0.05 (a greedy search of ours)
    adv = (113, 152, 155, 197, 200, 206, 218, 221, 236, 242, 248, 260, 266, 323, 335, 359, 365, 374, 413, 449, 506,
           518, 521, 527, 533, 575, 590, 596, 611, 635, 650, 653, 659, 689, 722, 749, 773, 788, 824, 872, 878, 923,
           926, 950, 962, 977, 983, 989, 992, 1010, 1016, 1019, 1043, 1070, 1088, 1106, 1124, 1175, 1277, 1286,
           1319, 1337, 1382, 1391)
    text = "prn,i5_advance,q5_advance\n" + "".join(f"{p},{adv[2 * p - 2]},{adv[2 * p - 1]}\n" for p in range(1, 33))
    path = Path(tempfile.gettempdir()) / "gnssrx_tests_l5_xb_table.csv"
    if not path.exists() or path.read_text() != text:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    os.environ["GNSSRX_L5_XB_TABLE"] = str(path)


_l5_test_table()

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
    """Slow by convention: the system tests (their folder) and every test that needs the reference run
    (``tokyo_run``, directly or through another fixture: ~20 s of receiver run before its first use), besides
    the unit tests marked one by one."""
    system = ROOT / "tests" / "system"
    for item in items:
        if system in Path(str(item.fspath)).parents or "tokyo_run" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.slow)
