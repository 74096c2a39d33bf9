"""Shared fixtures.

``tokyo_run``: the path of the run file of the third-party reference recording
(``../shared/data/gpssim_static_tokyo.bin``, GPS-SDR-SIM, static antenna in Tokyo) processed once per test
session with ``configs/gpssim_static_tokyo.yaml`` (troposphere off, Klobuchar on, default weighting) in
assisted mode (ephemerides from ``../shared/data/brdc0010.22n``; fixes from ~10 s, about 340 fixes at
10 Hz).  It takes about 20 s.  Skips when ../shared is absent.  Treat the file as read-only: tests that
write files beside a run file should link or copy it into their own tmp_path first.
"""
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
TOKYO_REC = SHARED / "gpssim_static_tokyo.bin"
TOKYO_NAV = SHARED / "brdc0010.22n"
TOKYO_META = SHARED / "gpssim_static_tokyo.yaml"


@pytest.fixture(scope="session")
def tokyo_run(tmp_path_factory):
    if not (TOKYO_REC.exists() and TOKYO_NAV.exists()):
        pytest.skip("../shared/data reference recording (gpssim_static_tokyo.bin, brdc0010.22n) absent")
    from receiver.config import load_receiver_config
    from receiver.pipeline import run
    out = tmp_path_factory.mktemp("tokyo_run") / "tokyo.h5"
    cfg = load_receiver_config(ROOT / "configs" / "gpssim_static_tokyo.yaml",
                               [("input.path", str(TOKYO_REC)), ("output.path", str(out)),
                                ("navigation.ephemeris", str(TOKYO_NAV)),
                                # RTKLIB's error model, so rnx2rtkp on the exported files is judged
                                # against our fixes on equal terms (tests/test_export_rinex.py)
                                ("navigation.weighting", "rtklib")])
    run(cfg, quiet=True)
    assert out.exists()
    return out


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
