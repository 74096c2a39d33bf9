"""scripts/tools/outage_table.py: acceptance verdicts of issue 14 from batch summary rows."""
import importlib.util
import math

import pytest

from repo_paths import SCRIPTS
SCRIPT = SCRIPTS / "tools" / "outage_table.py"
spec = importlib.util.spec_from_file_location("outage_table", SCRIPT)
ot = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ot)

NAN = math.nan


def _row(vector, ttgf, max_meas, max_all, to_end=1.0, avail=NAN, rms=NAN):
    r = {"config_yaml": f"vector:\n  enabled: {str(vector).lower()}\n", "outage_n": 4.0,
         "outage_max_err_m": max_meas, "outage_max_err_all_m": max_all, "outage_coast_fixes": 0.0,
         "fixes_to_end": to_end, "outage_fixes_inside": 0.0, "canyon_availability": avail, "canyon_rms_3d_m": rms,
         "canyon_max_err_m": rms, "canyon_epochs": 700.0}
    for k, (d, t) in enumerate(zip((1.0, 3.0, 8.0, 30.0), ttgf), start=1):
        r[f"outage{k}_dur_s"], r[f"outage{k}_ttgf_s"], r[f"outage{k}_max_err_m"] = d, t, max_meas
    return r


def _verdict(lines):
    return [line.rsplit("|", 2)[-2].strip() for line in lines[4:]]


def test_scalar_limits_per_outage_length():
    ok = _row(False, (1.9, 2.0, 3.9, 9.9), 12.0, 12.0)
    assert _verdict(ot.total_table("x", {"scalar": [ok, ok]})) == ["met"]
    slow8 = _row(False, (1.0, 1.0, 4.5, 5.0), 12.0, 12.0)
    assert _verdict(ot.total_table("x", {"scalar": [ok, slow8]})) == ["NOT met: 8 s > 4 s"]
    never = _row(False, (1.0, 1.0, 1.0, NAN), 12.0, 12.0, to_end=0.0)
    assert _verdict(ot.total_table("x", {"scalar": [never]})) == ["NOT met: 30 s > 10 s, fixes stop"]
    far = _row(False, (1.0, 1.0, 1.0, 1.0), 12.0, 31.0)          # scalar: any fix > 30 m fails
    assert _verdict(ot.total_table("x", {"scalar": [far]})) == ["NOT met: error > 30 m"]


def test_vector_limits_ignore_coast_errors_and_the_30s_outage():
    v = _row(True, (1.5, 1.5, 2.0, 25.0), 29.0, 120.0)            # coast fixes may be far off
    lines = ot.total_table("x", {"cv": [v]})
    assert _verdict(lines) == ["met"] and "cv (vector)" in lines[4]
    assert "1.50 (1.50)" in lines[4] and "25.00 (25.00)" in lines[4]
    liar = dict(v, outage_fixes_inside=12.0)                     # coasting not flagged
    assert _verdict(ot.total_table("x", {"cv": [v, liar]})) == ["NOT met: unflagged fixes in outages"]
    slow = _row(True, (1.5, 2.5, 2.0, 5.0), 29.0, 29.0)
    assert _verdict(ot.total_table("x", {"cv": [slow]})) == ["NOT met: 3 s > 2 s"]


def test_ttgf_cell_and_canyon_verdict():
    assert ot.ttgf_cell([1.0, 3.0, NAN]) == "2.00 (3.00), never 1/3"
    assert ot.ttgf_cell([NAN]) == "never (1/1)"
    good = _row(False, (NAN,) * 4, NAN, NAN, avail=0.96, rms=4.0)
    bad = _row(False, (NAN,) * 4, NAN, NAN, avail=0.94, rms=4.0)
    assert _verdict(ot.canyon_table("y", {"scalar": [good, good]})) == ["met"]
    assert _verdict(ot.canyon_table("y", {"scalar": [good, bad]})) == ["NOT met"]
    assert _verdict(ot.canyon_table("y", {"cv": [_row(True, (NAN,) * 4, NAN, NAN, avail=0.5, rms=9.0)]})) \
        == ["(reported)"]


@pytest.mark.parametrize("dur, vector, lim", [(1, False, 2), (3, False, 2), (8, False, 4), (30, False, 10),
                                              (8, True, 2), (30, True, None)])
def test_limits(dur, vector, lim):
    assert ot.ttgf_limit(dur, vector) == lim
