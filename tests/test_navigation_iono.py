"""Which Klobuchar set the fixes use (navigation.klobuchar_fallback, FIX_DTYPE iono_params): the built-in
fallback set while no broadcast set is known, the broadcast set from the moment a channel decodes subframe 4
page 18.  Measurements: synthetic pseudoranges from the real broadcast orbits of brdc0010.22n, delayed by an
ionosphere that is NOT the fallback set's (the nominal constellation's Klobuchar set, another day's)."""
from pathlib import Path

import numpy as np
import pytest

from receiver.config import load_receiver_config
from receiver.gnss.lnav import encode_frames
from receiver.navigation.engine import NavigationEngine
from receiver.runfile.record import FIX_DTYPE, IONO_BROADCAST, IONO_FALLBACK, IONO_NONE
from receiver.sim.constellation import nominal_ephemerides, quantize_ephemeris, quantize_iono
from test_navigation_bits import FS, _merge_bits, _records
from test_navigation_pvt import BRDC, WEEK, brdc, rx, simulate  # noqa: F401  (brdc, rx: fixtures)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def page18():
    """(the broadcast set, 20-ms prompt records of one LNAV frame of PRN 5 carrying it in subframe 4)."""
    ephs, iono = nominal_ephemerides(ROOT / "data" / "gps_nominal_constellation.yaml", 2300, 345600.0)
    iono = quantize_iono(iono)
    bits = encode_frames(quantize_ephemeris(ephs[5]), iono, 345600.0, 2300, 1, page18_every_frame=True)
    bits = np.concatenate([bits, np.array([1, 0, 0, 1], np.uint8)])    # a bit is complete when the next starts
    return iono, _merge_bits(_records(bits, 0.0, 0.3))


@pytest.fixture(scope="module")
def measured(brdc, rx, page18):  # noqa: F811
    ephs, _ = brdc
    return simulate(ephs, page18[0], rx)                                # Klobuchar delay of the broadcast set


def _engine(*overrides):
    return NavigationEngine(load_receiver_config(None, list(overrides)).navigation, FS, 0.0, 0)


def _decode(eng, recs):
    ch = eng.channel(5)
    for a in range(0, len(recs), 97):
        ch.add(recs[a:a + 97], 0)
    assert ch.decoder.iono_utc is not None


def _error(eng, brdc, rx, measured):  # noqa: F811
    ephs, _ = brdc
    rx_tow, obs = measured
    f = eng.solver.fix(WEEK, rx_tow, obs, ephs, eng.iono())
    return float(np.linalg.norm(f.ecef - rx))


def test_fallback_set_until_page18_is_decoded_then_the_broadcast_set(brdc, rx, page18, measured):  # noqa: F811
    """Before any page 18: the fallback set (iono_params 2), which removes most of another day's delay;
    once one channel decodes page 18: exactly the broadcast set (iono_params 1), which removes all of it."""
    eng = _engine()
    assert eng.broadcast_iono() is None and eng.iono_params() == IONO_FALLBACK
    uncorrected = float(np.linalg.norm(eng.solver.fix(WEEK, measured[0], measured[1], brdc[0], None).ecef - rx))
    fallback = _error(eng, brdc, rx, measured)
    _decode(eng, page18[1])
    assert eng.iono_params() == IONO_BROADCAST
    assert eng.iono().alpha == page18[0].alpha and eng.iono().beta == page18[0].beta
    decoded = _error(eng, brdc, rx, measured)
    print(f"\n3D error: uncorrected {uncorrected:.2f} m, fallback set {fallback:.2f} m, decoded set {decoded:.4f} m")
    assert uncorrected > 3.0                       # a midday ionosphere in Tokyo
    assert fallback < 0.5 * uncorrected
    # the decoded set is the delay model of the measurements (left: the synthetic measurements' few-cm model
    # mismatch, as in test_navigation_pvt)
    exact = eng.solver.fix(WEEK, measured[0], measured[1], brdc[0], page18[0])
    assert decoded == float(np.linalg.norm(exact.ecef - rx)) < 0.1


def test_fallback_off_is_the_old_behaviour(brdc, rx, page18, measured):  # noqa: F811
    """navigation.klobuchar_fallback false: no correction until page 18 is decoded (iono_params 0)."""
    eng = _engine(("navigation.klobuchar_fallback", False))
    assert eng.iono() is None and eng.iono_params() == IONO_NONE
    ephs, _ = brdc
    f = eng.solver.fix(WEEK, measured[0], measured[1], ephs, None)
    assert _error(eng, brdc, rx, measured) == float(np.linalg.norm(f.ecef - rx)) > 3.0
    _decode(eng, page18[1])
    assert eng.iono_params() == IONO_BROADCAST and _error(eng, brdc, rx, measured) < 0.1


def test_ionosphere_none_uses_no_set():
    eng = _engine(("navigation.ionosphere", "none"))
    assert eng.iono() is None and eng.iono_params() == IONO_NONE


def test_fallback_set_is_the_brdc0010_22n_header():
    """The built-in set is the one the source file's header prints (ION ALPHA / ION BETA)."""
    if not BRDC.exists():
        pytest.skip(f"shared test data absent: {BRDC}")
    from receiver.gnss.atmosphere import FALLBACK_KLOBUCHAR_ALPHA, FALLBACK_KLOBUCHAR_BETA
    from receiver.gnss.rinex import read_rinex_nav
    _, iono = read_rinex_nav(BRDC)
    assert FALLBACK_KLOBUCHAR_ALPHA == iono.alpha and FALLBACK_KLOBUCHAR_BETA == iono.beta


def test_vector_fix_rows_carry_iono_params():
    """The vector tracker's fix rows fit FIX_DTYPE and say which set its satellite polynomials used."""
    from receiver.tracking.vector.tracker import VectorTracker
    eng = _engine()
    tr = VectorTracker.__new__(VectorTracker)
    tr.__dict__.update(nav=eng, week=2190, s_ref=0.0, fs=FS)
    tr._dops = lambda *a: (np.nan,) * 4
    row = np.zeros(1, FIX_DTYPE)
    row[0] = tr._fix_row(1.0, np.array([-3959617.0, 3350136.0, 3699531.0]), np.zeros(3), 0.0, 0.0, 6, 345600.0)
    assert row["iono_params"][0] == IONO_FALLBACK and row["mode"][0] == 1


def test_rinex_header_set_is_broadcast_unless_it_has_no_klobuchar_terms(brdc):  # noqa: F811
    """Assisted mode: the RINEX header's ION ALPHA / BETA are the broadcast set from the start; a header with
    GPS-UTC terms only (alpha, beta read as zeros) leaves the fallback set in use."""
    from receiver.gnss.ephemeris import IonoUtc
    _, header = brdc
    nav = load_receiver_config(None, []).navigation
    eng = NavigationEngine(nav, FS, 0.0, 0, ephemerides={}, iono_utc=header)
    assert eng.iono() is header and eng.iono_params() == IONO_BROADCAST
    utc_only = IonoUtc(a0=header.a0, a1=header.a1, dt_ls=18)
    eng = NavigationEngine(nav, FS, 0.0, 0, ephemerides={}, iono_utc=utc_only)
    assert eng.iono() is eng.iono_fallback and eng.iono_params() == IONO_FALLBACK
