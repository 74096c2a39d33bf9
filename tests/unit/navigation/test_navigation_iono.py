"""Which Klobuchar set the fixes use (navigation.klobuchar_fallback, FIX_DTYPE iono_params): the built-in
fallback set while no broadcast set is known, the broadcast set from the moment a channel decodes subframe 4
page 18.  Measurements: synthetic pseudoranges from the real broadcast orbits of brdc0010.22n, delayed by an
ionosphere that is NOT the fallback set's (the nominal constellation's Klobuchar set, another day's)."""

import numpy as np
import pytest

from receiver.schema import load_receiver_config
from receiver.gnss.lnav import encode_frames
from receiver.navigation.engine import NavigationEngine
from receiver.runfile.record import FIX_DTYPE, IONO_BROADCAST, IONO_FALLBACK, IONO_NONE
from receiver.sim.constellation import nominal_ephemerides, quantize_ephemeris, quantize_iono
from test_navigation_bits import FS, _merge_bits, _records
from test_navigation_pvt import BRDC, WEEK, brdc, rx, simulate  # noqa: F401  (brdc, rx: fixtures)

from repo_paths import ROOT


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


# ---- end to end: the navigation engine on the reference recording's stored tracking output, started late
TOKYO_TRUTH = np.array([-3959617.482, 3350136.615, 3699531.459])


def _replay(run_h5, start_s, end_s, *overrides):
    """Fixes of a standalone NavigationEngine fed the run file's channel records from start_s on (as if the
    recording had started there: no subframe 4 page 18 until 30 s later).  The bit offset of each channel is
    the code period (mod 20) at which its prompt changes sign."""
    from receiver.runfile.reader import RunFile
    from receiver.runfile.record import EPOCH_DTYPE, STATE_BIT_SYNC
    cfg = load_receiver_config(ROOT / "configs" / "gpssim_static_tokyo.yaml", list(overrides)).navigation
    recs = {}
    with RunFile(run_h5) as rf:
        fs = float(rf.attrs["sample_rate_hz"])
        for name in rf.channel_names():
            c = rf.channel(name)
            r = np.zeros(len(c["time_s"]), EPOCH_DTYPE)
            for k in EPOCH_DTYPE.names:
                r[k] = c[k]
            b = r[r["state"] == STATE_BIT_SYNC]
            flip = np.flatnonzero(np.sign(b["prompt_i"][1:]) != np.sign(b["prompt_i"][:-1])) + 1
            recs[rf.channel_prn(name)] = (r, int(np.bincount(b["code_period"][flip] % 20, minlength=20).argmax()))
    eng = NavigationEngine(cfg, fs, 0.0, int(start_s * fs), week_hint=2190)
    out, step = [], int(0.5 * fs)
    for a in range(int(start_s * fs), int(end_s * fs), step):
        for prn, (r, bit_offset) in recs.items():
            m = (r["sample_index"] >= a) & (r["sample_index"] < a + step)
            eng.add_records(prn, r[m], bit_offset if (r["state"][m] == STATE_BIT_SYNC).any() else -1)
        out.append(eng.update(a + step)[0])
    f = np.concatenate(out)
    return f, np.linalg.norm(f["ecef"] - TOKYO_TRUTH, axis=1)


@pytest.mark.slow
def test_reference_recording_started_late_uses_the_fallback_until_page18(tokyo_run):
    """The reference recording from 9.7 s on (scripts/tools/derived_recordings.py late_9.7): fixes from 33.7 s,
    page 18 decoded at 39.7 s.  With the fallback set the fixes before page 18 are as good as after it
    (the recording's ionosphere is the fallback set's day); without it they carry the whole delay (6-7 m)."""
    f, e = _replay(tokyo_run, 9.7, 41.0)
    fb, bc = f["iono_params"] == IONO_FALLBACK, f["iono_params"] == IONO_BROADCAST
    assert fb.sum() >= 50 and bc.sum() >= 10 and fb.sum() + bc.sum() == len(f)
    assert f["time_s"][fb].max() < f["time_s"][bc].min()                   # fallback first, then broadcast
    assert np.sqrt(np.mean(e[fb] ** 2)) < 0.5 and np.sqrt(np.mean(e[bc] ** 2)) < 0.5
    g, e_off = _replay(tokyo_run, 9.7, 41.0, ("navigation.klobuchar_fallback", False))
    none = g["iono_params"] == IONO_NONE
    assert np.array_equal(none, fb) and np.all(g["iono_params"][~none] == IONO_BROADCAST)
    assert np.sqrt(np.mean(e_off[none] ** 2)) > 4.0
    print(f"\nlate start: before page 18 {np.sqrt(np.mean(e[fb] ** 2)):.3f} m (fallback) vs "
          f"{np.sqrt(np.mean(e_off[none] ** 2)):.3f} m (none), after {np.sqrt(np.mean(e[bc] ** 2)):.3f} m")
