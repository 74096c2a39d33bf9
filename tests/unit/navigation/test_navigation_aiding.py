"""Clock/height-aided fixes (navigation.aiding): synthetic measurements from real broadcast orbits."""
from itertools import combinations

import numpy as np
import pytest

from receiver.gnss.geodesy import ecef2lla, lla2ecef
from receiver.navigation.pvt import Aiding, NavSolver
from test_navigation_pvt import RX_LLA, WEEK, brdc, cfg, simulate  # noqa: F401  (brdc: fixture)

BIAS = 12345.0
DRIFT = 150.0


@pytest.fixture(scope="module")
def rx():
    return lla2ecef(*RX_LLA)


@pytest.fixture(scope="module")
def exact(brdc, rx):
    ephs, iono = brdc
    return simulate(ephs, iono, rx, bias_m=BIAS, drift_mps=DRIFT)


def _aid(clock_err=0.0, height_err=0.0, **kw):
    return Aiding(clock_m=BIAS + clock_err, clock_sigma_m=1.0, height_m=RX_LLA[2] + height_err,
                  height_sigma_m=2.0, drift_mps=DRIFT, drift_sigma_mps=0.2, **kw)


def test_three_satellites_with_clock_and_height_recover_truth(brdc, rx, exact):
    ephs, iono = brdc
    rx_tow, obs = exact
    solver = NavSolver(cfg())
    x0 = rx + np.array([30.0, -20.0, 10.0])            # the previous fix, 40 m away
    n_ok = 0
    for sub in combinations(obs, 3):
        sub = list(sub)
        assert solver.fix(WEEK, rx_tow, sub, ephs, iono, x0=x0) is None      # unaided: impossible
        f = solver.fix(WEEK, rx_tow, sub, ephs, iono, x0=x0, aid=_aid())
        if f is None:                      # a degenerate triple (PDOP above max_pdop even with the constraints)
            continue
        n_ok += 1
        assert f.n_sats == 3 and f.aiding == ("clock", "height")
        assert np.linalg.norm(f.ecef - rx) < 0.2 and f.clock_bias_m == pytest.approx(BIAS, abs=0.2)
        # velocity from 3 Dopplers and the drift constraint (receiver at rest)
        assert np.linalg.norm(f.velocity_ecef) < 0.05 and f.clock_drift_mps == pytest.approx(DRIFT, abs=0.05)
    assert n_ok >= 10


def test_clock_only_aiding_with_three_satellites(brdc, rx, exact):
    """A clock constraint alone makes 3 satellites a determined system: exact ranges give the truth, a clock
    error of 2 m gives a position error of the order of the geometry times 2 m."""
    ephs, iono = brdc
    rx_tow, obs = exact
    solver = NavSolver(cfg(max_pdop=1e9))
    sub = obs[:3]
    a = Aiding(clock_m=BIAS, clock_sigma_m=1.0)
    f = solver.fix(WEEK, rx_tow, sub, ephs, iono, x0=rx + 50.0, aid=a)
    assert f is not None and f.aiding == ("clock",) and np.linalg.norm(f.ecef - rx) < 0.05
    g = solver.fix(WEEK, rx_tow, sub, ephs, iono, x0=rx + 50.0, aid=Aiding(clock_m=BIAS + 2.0, clock_sigma_m=1.0))
    err = np.linalg.norm(g.ecef - rx)
    assert 0.5 < err < 2.0 * g.pdop


def test_aiding_improves_weak_four_satellite_geometry(brdc, rx):
    """Over every 4-satellite subset with noisy ranges, the aided fixes' 3D RMS is smaller than the unaided
    ones', most of all for the weak geometries (PDOP > 10)."""
    ephs, iono = brdc
    open_solver = NavSolver(cfg(max_pdop=1e9))
    e_un, e_aid, weak_un, weak_aid = [], [], [], []
    for seed in range(1):
        rx_tow, obs = simulate(ephs, iono, rx, bias_m=BIAS, drift_mps=DRIFT, sigma_m=2.0, seed=seed)
        rng = np.random.default_rng(seed)
        for sub in combinations(obs, 4):
            f = open_solver.fix(WEEK, rx_tow, list(sub), ephs, iono, x0=rx)
            aid = _aid(clock_err=rng.normal(0, 1.0), height_err=rng.normal(0, 2.0), code_sigma_m=2.0,
                       residual_threshold_m=1e9)
            g = open_solver.fix(WEEK, rx_tow, list(sub), ephs, iono, x0=rx, aid=aid)
            if f is None or g is None:
                continue
            eu, ea = np.linalg.norm(f.ecef - rx), np.linalg.norm(g.ecef - rx)
            e_un.append(eu)
            e_aid.append(ea)
            if f.pdop > 10:
                weak_un.append(eu)
                weak_aid.append(ea)
            assert g.pdop <= f.pdop + 1e-9      # the constraints only add information
    rms = lambda e: float(np.sqrt(np.mean(np.square(e))))   # noqa: E731
    assert len(weak_un) >= 5
    assert rms(e_aid) < 0.5 * rms(e_un)
    assert rms(weak_aid) < 0.2 * rms(weak_un)


def test_aided_fix_rejects_a_bad_range(brdc, rx):
    """4 satellites, one with a 60-m error: unaided, the error goes into the position unseen (no redundancy);
    aided (clock + height: redundancy 2) the bad satellite is dropped and the fix is good."""
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx, bias_m=BIAS, drift_mps=DRIFT, sigma_m=0.5, seed=5)
    solver = NavSolver(cfg(max_pdop=1e9))
    sub = None
    for cand in combinations(obs, 4):
        f = solver.fix(WEEK, rx_tow, list(cand), ephs, iono, x0=rx)
        if f is not None and f.pdop < 4:
            sub = list(cand)
            break
    assert sub is not None
    bad = sub[1].prn
    rx_tow, obs_bad = simulate(ephs, iono, rx, bias_m=BIAS, drift_mps=DRIFT, sigma_m=0.5, seed=5,
                               extra_m={bad: 60.0})
    sub_bad = [o for o in obs_bad if o.prn in {s.prn for s in sub}]
    f = solver.fix(WEEK, rx_tow, sub_bad, ephs, iono, x0=rx)
    assert np.linalg.norm(f.ecef - rx) > 30.0 and np.max(np.abs(f.residuals_m)) < 1e-3
    g = solver.fix(WEEK, rx_tow, sub_bad, ephs, iono, x0=rx, aid=_aid())
    assert g is not None and g.rejected_prns == [bad] and bad not in g.prns and g.n_sats == 3
    assert np.linalg.norm(g.ecef - rx) < 5.0
    # a wrong constraint (clock 40 m off) is not taken either: the fix is refused or keeps its satellites
    k = solver.fix(WEEK, rx_tow, sub, ephs, iono, x0=rx, aid=_aid(clock_err=40.0))
    assert k is None or np.linalg.norm(k.ecef - rx) < 10.0


def test_height_constraint_is_ellipsoidal(brdc, rx, exact):
    ephs, iono = brdc
    rx_tow, obs = exact
    solver = NavSolver(cfg(max_pdop=1e9))
    a = Aiding(height_m=RX_LLA[2] + 5.0, height_sigma_m=0.01, clock_m=BIAS, clock_sigma_m=100.0,
               residual_threshold_m=1e9)
    f = solver.fix(WEEK, rx_tow, obs[:3], ephs, iono, x0=rx, aid=a)
    assert f is not None
    assert ecef2lla(f.ecef)[2] == pytest.approx(RX_LLA[2] + 5.0, abs=0.05)


def test_engine_predicts_the_clock_and_height_from_unaided_fixes(rx):
    """NavigationEngine: the constraints are the recent unaided fixes extrapolated with their drift / vertical
    speed; their sigma grows with the age of the latest unaided fix; aided fixes never feed the prediction;
    no aiding past max_age_s or with navigation.aiding.enabled false."""
    from receiver.schema import load_receiver_config
    from receiver.navigation.engine import NavigationEngine
    from receiver.navigation.pvt import Fix

    cfg = load_receiver_config(None, [("navigation.aiding.max_age_s", 5.0)])
    eng = NavigationEngine(cfg.navigation, 2.6e6, 0.0, 0)

    def fix(t, aiding=()):
        up = rx / np.linalg.norm(rx)
        return Fix(gps_week=WEEK, gps_tow=t, ecef=rx + up * 0.3 * t, velocity_ecef=up * 0.3,
                   clock_bias_m=BIAS + DRIFT * t, clock_drift_mps=DRIFT, n_sats=6, prns=[], pdop=2.0, hdop=1.0,
                   vdop=1.7, gdop=2.3, residuals_m=np.zeros(0), elevations_deg=np.zeros(0),
                   azimuths_deg=np.zeros(0), pseudoranges_m=np.zeros(0), pseudorange_rates_mps=np.zeros(0),
                   aiding=aiding)
    for k in range(20):
        eng._remember(10.0 + 0.1 * k, fix(10.0 + 0.1 * k))
    eng._remember(12.5, fix(12.5, aiding=("clock", "height")))         # ignored: aided
    h0 = ecef2lla(rx)[2]
    a = eng._aiding(13.9)
    assert a.clock_m == pytest.approx(BIAS + DRIFT * 13.9, abs=1e-6)
    assert a.height_m == pytest.approx(h0 + 0.3 * 13.9, abs=0.01)
    assert a.drift_mps == pytest.approx(DRIFT)
    age = 13.9 - 11.9
    assert a.clock_sigma_m == pytest.approx(np.hypot(1.0, 0.3 * age ** 1.5))
    assert a.height_sigma_m == pytest.approx(np.hypot(2.0, 0.5 * age))
    assert eng._aiding(12.0).clock_sigma_m < a.clock_sigma_m
    assert eng._aiding(11.9 + 5.1) is None                              # older than max_age_s
    off = NavigationEngine(load_receiver_config(None, [("navigation.aiding.enabled", False)]).navigation,
                           2.6e6, 0.0, 0)
    off._remember(10.0, fix(10.0))
    assert off._aiding(10.5) is None


@pytest.mark.slow
def test_aided_pdop_limit_refuses_the_weak_triples_only(brdc, rx):
    """3 satellites with noisy ranges and noisy clock / height predictions: the aided fix's error grows with
    its PDOP (constraints included).  Aiding.max_pdop (navigation.aiding.max_pdop) refuses exactly the fixes
    above it - their errors are much larger than those of the fixes kept - and leaves the others unchanged."""
    ephs, iono = brdc
    solver = NavSolver(cfg())
    kept, refused = [], []
    for seed in range(3):
        rx_tow, obs = simulate(ephs, iono, rx, bias_m=BIAS, drift_mps=DRIFT, sigma_m=2.0, seed=seed)
        rng = np.random.default_rng(seed)
        for sub in combinations(obs, 3):
            kw = dict(clock_err=rng.normal(0, 1.0), height_err=rng.normal(0, 2.0), code_sigma_m=2.0)
            f = solver.fix(WEEK, rx_tow, list(sub), ephs, iono, x0=rx + 30.0, aid=_aid(**kw))
            g = solver.fix(WEEK, rx_tow, list(sub), ephs, iono, x0=rx + 30.0, aid=_aid(max_pdop=5.0, **kw))
            if f is None:
                assert g is None
                continue
            err = float(np.linalg.norm(f.ecef - rx))
            if f.pdop > 5.0:
                assert g is None
                refused.append(err)
            else:
                assert g is not None and np.array_equal(g.ecef, f.ecef)
                kept.append(err)
    rms = lambda e: float(np.sqrt(np.mean(np.square(e))))   # noqa: E731
    assert len(refused) >= 5 and len(kept) >= 100
    assert rms(refused) > 1.8 * rms(kept), (rms(refused), rms(kept))
