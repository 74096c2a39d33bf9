"""Paths every test may need, stated once: the repository root, its configs and scripts, and the read-only
``../shared`` material beside the checkout (the third-party reference recording, broadcast ephemerides,
real antenna recordings).  Tests that use ``../shared`` skip with a reason when it is absent
(:data:`needs_shared`)."""
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
SCRIPTS = ROOT / "scripts"
SHARED = ROOT.parent / "shared"
SHARED_DATA = SHARED / "data"
REAL_DATA = SHARED_DATA / "real"
TOKYO_REC = SHARED_DATA / "gpssim_static_tokyo.bin"
TOKYO_NAV = SHARED_DATA / "brdc0010.22n"
TOKYO_META = SHARED_DATA / "gpssim_static_tokyo.yaml"

#: skip marker for tests that read ../shared/data
needs_shared = pytest.mark.skipif(not TOKYO_REC.exists(), reason="../shared/data (reference recording) absent")
