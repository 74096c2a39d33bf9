"""Navigation solution on synthetic measurements built from real broadcast orbits."""
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from receiver.gnss.geodesy import azel, lla2ecef
from receiver.gnss.atmosphere import klobuchar_delay_s, saastamoinen_m
from receiver.gnss.ephemeris import sat_state, select
from receiver.navigation.pvt import Fix, NavSolver, Observation
from receiver.gnss.rinex import read_rinex_nav
from receiver.gnss.signals import C_LIGHT, LAMBDA_L1, OMEGA_E

from repo_paths import SHARED_DATA as DATA
BRDC = DATA / "brdc0010.22n"

WEEK = 2190
T_TRUE = 518400.0 + 3 * 3600 + 17.0          # 2022-01-01 03:00:17 GPS
RX_LLA = (35.6812, 139.7671, 40.0)            # Tokyo


def cfg(**kw):
    base = dict(elevation_mask_deg=5.0, weighting="elevation", troposphere="saastamoinen",
                ionosphere="klobuchar", residual_threshold_m=30.0)
    base.update(kw)
    return SimpleNamespace(**base)


@pytest.fixture(scope="module")
def brdc():
    if not BRDC.exists():
        pytest.skip(f"shared test data absent: {BRDC}")
    ephs, iono = read_rinex_nav(BRDC)
    chosen = {prn: select(lst, T_TRUE) for prn, lst in ephs.items()}
    return {p: e for p, e in chosen.items() if e is not None}, iono


def _rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def simulate(ephs, iono, rx, bias_m=12345.0, drift_mps=150.0, vel=np.zeros(3), sigma_m=0.0,
             sigma_hz=0.0, atmosphere=True, mask_deg=5.0, seed=0, extra_m=None, t_true=T_TRUE):
    """Observations of a receiver at ECEF rx (true time t_true) with clock bias/drift."""
    rng = np.random.default_rng(seed)
    rx_tow = (t_true + bias_m / C_LIGHT) % 604800.0
    lat, lon = np.radians(RX_LLA[0]), np.radians(RX_LLA[1])
    obs = []
    for prn, eph in sorted(ephs.items()):
        tau = 0.07
        for _ in range(8):                           # light time with Earth rotation
            t_tx = t_true - tau
            t_sv = t_tx
            for _ in range(4):                       # satellite clock reading at t_tx
                t_sv = t_tx + sat_state(eph, t_sv)[2]
            pos, v_sat, clk, clk_drift = sat_state(eph, t_sv)
            pos_rx = _rot_z(OMEGA_E * tau) @ pos
            tau = np.linalg.norm(pos_rx - rx) / C_LIGHT
        az, el = azel(rx, pos_rx)
        if np.degrees(el) < mask_deg:
            continue
        delay = 0.0
        if atmosphere:
            delay = C_LIGHT * klobuchar_delay_s(iono, lat, lon, az, el, rx_tow) + saastamoinen_m(lat, RX_LLA[2], el)
        rho = C_LIGHT * tau + bias_m - C_LIGHT * clk + delay + sigma_m * rng.standard_normal()
        if extra_m and prn in extra_m:
            rho += extra_m[prn]
        los = (pos_rx - rx) / np.linalg.norm(pos_rx - rx)
        v_sat_rx = _rot_z(OMEGA_E * tau) @ v_sat
        rate = los @ (v_sat_rx - vel) + drift_mps - C_LIGHT * clk_drift
        doppler = -rate / LAMBDA_L1 + sigma_hz * rng.standard_normal()
        obs.append(Observation(prn=prn, tx_tow=(rx_tow - rho / C_LIGHT) % 604800.0, doppler_hz=doppler,
                               cn0_dbhz=45.0 + 5 * np.sin(el)))
    return rx_tow, obs


@pytest.fixture(scope="module")
def rx():
    return lla2ecef(*RX_LLA)


def test_exact_measurements_recover_truth(brdc, rx):
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx)
    assert len(obs) >= 7
    f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
    assert isinstance(f, Fix)
    assert np.linalg.norm(f.ecef - rx) < 0.05
    assert f.clock_bias_m == pytest.approx(12345.0, abs=0.05)
    assert f.gps_tow == pytest.approx(T_TRUE, abs=1e-9) and f.gps_week == WEEK
    assert np.max(np.abs(f.residuals_m)) < 0.05
    assert f.n_sats == len(obs) and sorted(f.prns) == sorted(o.prn for o in obs)
    assert np.all(f.elevations_deg >= 5.0) and np.all((f.azimuths_deg >= 0) & (f.azimuths_deg < 360))
    assert f.pdop ** 2 == pytest.approx(f.hdop ** 2 + f.vdop ** 2)
    assert 1.0 < f.pdop < 10 and f.gdop > f.pdop
    assert np.all(f.tropo_m > 2.3) and np.all(f.iono_m > 1.0)
    # corrected pseudorange - clock - residual is the geometric range to the satellite
    geo = f.pseudoranges_m - f.clock_bias_m - f.residuals_m
    assert np.all((geo > 19.5e6) & (geo < 26e6))
    assert np.all(f.raw_pseudoranges_m - f.pseudoranges_m
                  == pytest.approx(f.raw_pseudoranges_m - f.pseudoranges_m))
    lat, lon, h = f.lla
    assert lat == pytest.approx(RX_LLA[0], abs=1e-7) and h == pytest.approx(RX_LLA[2], abs=0.05)


@pytest.mark.slow
def test_noisy_wls_accuracy(brdc, rx):
    ephs, iono = brdc
    errs = []
    for seed in range(10):
        rx_tow, obs = simulate(ephs, iono, rx, sigma_m=2.0, seed=seed)
        f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
        errs.append(np.linalg.norm(f.ecef - rx))
        # the errors expected from the geometry: ~ PDOP x sigma (weighted, low sats noisier)
        assert errs[-1] < 6 * 2.0 * f.pdop
        assert abs(f.clock_bias_m - 12345.0) < 6 * 2.0 * f.gdop
    assert 0.5 < np.sqrt(np.mean(np.square(errs))) < 15


def test_models_matter(brdc, rx):
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx)
    f_none = NavSolver(cfg(troposphere="none", ionosphere="none")).fix(WEEK, rx_tow, obs, ephs, iono)
    f_ok = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
    assert np.linalg.norm(f_none.ecef - rx) > 5.0 > 100 * np.linalg.norm(f_ok.ecef - rx)
    # without the ionosphere parameters the solver still works (tropo only)
    rx_tow, obs = simulate(ephs, iono, rx, atmosphere=False)
    f = NavSolver(cfg(ionosphere="klobuchar", troposphere="none")).fix(WEEK, rx_tow, obs, ephs, None)
    assert np.linalg.norm(f.ecef - rx) < 0.05


@pytest.mark.slow
def test_residual_check_drops_faulty_satellite(brdc, rx):
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx, sigma_m=1.0, seed=3)
    prns = [o.prn for o in obs]
    bad = prns[len(prns) // 2]
    rx_tow, obs = simulate(ephs, iono, rx, sigma_m=1.0, seed=3, extra_m={bad: 200.0})
    f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
    assert bad not in f.prns and f.rejected_prns == [bad]
    assert np.linalg.norm(f.ecef - rx) < 10.0
    # without the check (huge threshold) the error leaks into the position
    g = NavSolver(cfg(residual_threshold_m=1e9)).fix(WEEK, rx_tow, obs, ephs, iono)
    assert bad in g.prns and np.linalg.norm(g.ecef - rx) > np.linalg.norm(f.ecef - rx)


@pytest.mark.slow
def test_velocity_and_drift_from_doppler(brdc, rx):
    ephs, iono = brdc
    v_true = np.array([12.0, -7.5, 3.0])
    rx_tow, obs = simulate(ephs, iono, rx, vel=v_true, drift_mps=-420.0, sigma_hz=0.05, seed=9)
    f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
    assert np.linalg.norm(f.velocity_ecef - v_true) < 0.1
    assert f.clock_drift_mps == pytest.approx(-420.0, abs=0.1)
    assert np.all(np.abs(f.velocity_residuals_mps) < 0.2)
    # static receiver, no noise: exact
    rx_tow, obs = simulate(ephs, iono, rx, drift_mps=150.0)
    f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
    assert np.linalg.norm(f.velocity_ecef) < 2e-3 and f.clock_drift_mps == pytest.approx(150.0, abs=2e-3)
    # missing Doppler: position still solved, velocity NaN
    obs = [replace(o, doppler_hz=float("nan")) for o in obs]
    f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
    assert np.all(np.isnan(f.velocity_ecef)) and np.linalg.norm(f.ecef - rx) < 0.05


def test_mask_weights_and_start_point(brdc, rx):
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx, sigma_m=1.0, seed=4)
    high = NavSolver(cfg(elevation_mask_deg=30.0)).fix(WEEK, rx_tow, obs, ephs, iono)
    low = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
    assert high.n_sats < low.n_sats and np.all(high.elevations_deg >= 30.0)
    for w in ("cn0", "none"):
        f = NavSolver(cfg(weighting=w)).fix(WEEK, rx_tow, obs, ephs, iono)
        assert np.linalg.norm(f.ecef - rx) < 15
    warm = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono, x0=low.ecef + 500.0)
    assert np.allclose(warm.ecef, low.ecef, atol=1e-3)
    # per-prn lists of ephemerides are accepted too
    lists = {p: [e] for p, e in ephs.items()}
    f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, lists, iono)
    assert np.allclose(f.ecef, low.ecef, atol=1e-6)


def test_too_few_satellites(brdc, rx):
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx)
    solver = NavSolver(cfg())
    assert solver.fix(WEEK, rx_tow, obs[:3], ephs, iono) is None
    assert solver.fix(WEEK, rx_tow, [], ephs, iono) is None
    assert solver.fix(WEEK, rx_tow, obs, {}, iono) is None
    # four satellites still give a fix
    f = solver.fix(WEEK, rx_tow, obs[:4], ephs, iono)
    assert f is not None and np.linalg.norm(f.ecef - rx) < 0.1
    # unhealthy ephemeris is not used
    sick = dict(ephs)
    sick[obs[0].prn] = replace(ephs[obs[0].prn], health=1)
    assert solver.fix(WEEK, rx_tow, obs[:4], sick, iono) is None


def test_large_clock_bias(brdc, rx):
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx, bias_m=-3.0e5)     # receiver clock 1 ms early
    f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, ephs, iono)
    assert f.gps_tow == pytest.approx(T_TRUE, abs=1e-9)
    assert np.linalg.norm(f.ecef - rx) < 0.05


def test_week_rollover(brdc, rx):
    if not BRDC.exists():
        pytest.skip(f"shared test data absent: {BRDC}")
    allephs, iono = read_rinex_nav(BRDC)
    t_true = 604800.0 - 0.005                                 # 5 ms before the end of week 2190
    ephs = {p: select(lst, t_true, week=WEEK) for p, lst in allephs.items()}
    ephs = {p: e for p, e in ephs.items() if e is not None}
    # receiver clock 10 ms late: its time of week already wrapped into week 2191
    rx_tow, obs = simulate(ephs, iono, rx, bias_m=3.0e6, t_true=t_true)
    assert rx_tow < 10.0 and any(o.tx_tow > 600000 for o in obs)
    f = NavSolver(cfg()).fix(WEEK + 1, rx_tow, obs, ephs, iono)
    assert (f.gps_week, f.gps_tow) == (WEEK, pytest.approx(t_true, abs=1e-9))
    assert np.linalg.norm(f.ecef - rx) < 0.05


def test_pdop_mask_refuses_weak_geometry(brdc, rx):
    """navigation.max_pdop: a 4-satellite subset with a weak geometry gives no fix (its errors would be
    PDOP x the pseudorange noise), the same subset with the mask lifted does, strong subsets always do."""
    from itertools import combinations
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx, sigma_m=2.0, seed=3)
    open_solver = NavSolver(cfg(max_pdop=1e9))
    fixes = [(sub, open_solver.fix(WEEK, rx_tow, list(sub), ephs, iono)) for sub in combinations(obs, 4)]
    fixes = [(sub, f) for sub, f in fixes if f is not None]
    weak = [(sub, f) for sub, f in fixes if f.pdop > 20.0]
    strong = [(sub, f) for sub, f in fixes if f.pdop < 5.0]
    assert weak and strong
    masked = NavSolver(cfg(max_pdop=20.0))
    for sub, f in weak:
        assert masked.fix(WEEK, rx_tow, list(sub), ephs, iono) is None
    assert max(np.linalg.norm(f.ecef - rx) for _, f in weak) > max(np.linalg.norm(f.ecef - rx) for _, f in strong)
    for sub, f in strong:
        g = masked.fix(WEEK, rx_tow, list(sub), ephs, iono)
        assert g is not None and np.allclose(g.ecef, f.ecef)


def test_grossly_wrong_satellite_is_left_out_when_the_wls_cannot_converge(brdc, rx):
    """One satellite with a corrupted ephemeris thousands of km off (a set decoded from noise: semi-major axis
    or clock offset wrong) keeps the iteration from converging before the residual test can see it; the
    solver then leaves each satellite out in turn: the fix is computed from the others, the bad one
    rejected (before: no fix at all, for as long as the set stayed in use)."""
    ephs, iono = brdc
    rx_tow, obs = simulate(ephs, iono, rx, sigma_m=1.0, seed=3)
    bad = [o.prn for o in obs][3]
    for wrong in (replace(ephs[bad], sqrt_a=ephs[bad].sqrt_a * 1.8), replace(ephs[bad], af0=0.1)):
        e2 = dict(ephs)
        e2[bad] = wrong
        for x0 in (None, rx + 500.0):
            f = NavSolver(cfg()).fix(WEEK, rx_tow, obs, e2, iono, x0=x0)
            assert f is not None
            assert f.rejected_prns == [bad] and bad not in f.prns and f.n_sats == len(obs) - 1
            assert np.linalg.norm(f.ecef - rx) < 10.0
    # with only 5 satellites a left-out one cannot be checked by the residuals of the other 4: no fix
    few = [o for o in obs if o.prn != bad][:4] + [o for o in obs if o.prn == bad]
    e2 = dict(ephs)
    e2[bad] = replace(ephs[bad], af0=0.1)
    assert NavSolver(cfg()).fix(WEEK, rx_tow, few, e2, iono) is None


def test_cn0_elevation_weighting_is_the_best_linear_estimate_under_its_model(brdc, rx):
    """navigation.weighting cn0_elevation: range variance 10^((cn0_ref - C/N0) / 10) + 1 / sin^2(el) (in units of
    the zenith elevation term).  When the ranges' errors follow that model, with each satellite's C/N0 drawn
    apart from its elevation (a weak high satellite, a strong low one), its fixes are closer to the truth than
    those of sin^2(el) weights (blind to C/N0) and of C/N0 weights (blind to elevation), over many draws."""
    ephs, iono = brdc
    rx_tow, clean = simulate(ephs, iono, rx, seed=0)
    base = NavSolver(cfg()).fix(WEEK, rx_tow, clean, ephs, iono)
    el = dict(zip(base.prns, np.radians(base.elevations_deg)))
    rng = np.random.default_rng(7)
    err = {"cn0_elevation": [], "elevation": [], "cn0": []}
    for _ in range(150):
        cn0 = {o.prn: float(rng.uniform(27.0, 47.0)) for o in clean}
        sd = {p: 0.5 * np.sqrt(10 ** ((45.0 - cn0[p]) / 10) + 1 / np.sin(el.get(p, np.pi / 2)) ** 2) for p in cn0}
        noise = {p: sd[p] * rng.standard_normal() for p in cn0}
        obs = [replace(o, cn0_dbhz=cn0[o.prn], tx_tow=o.tx_tow - noise[o.prn] / C_LIGHT) for o in clean]
        for w in err:
            f = NavSolver(cfg(weighting=w, cn0_ref_dbhz=45.0)).fix(WEEK, rx_tow, obs, ephs, iono, x0=base.ecef)
            err[w].append(np.sum((f.ecef - rx) ** 2))
    rms = {w: float(np.sqrt(np.mean(v))) for w, v in err.items()}
    assert rms["cn0_elevation"] < 0.95 * rms["elevation"] and rms["cn0_elevation"] < 0.95 * rms["cn0"], rms
