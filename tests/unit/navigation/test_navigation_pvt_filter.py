"""EKF / CKF navigation filters (navigation.filter: ekf | ckf) against the single-epoch WLS.

The synthetic tests use the repository's embedded nominal constellation (data/gps_nominal_constellation.yaml),
so they need no external data: observations of a receiver on a known trajectory with a noisy TCXO-like
clock are fed to NavSolver.fix, and the WLS fixes to the filters.  The last tests run the receiver once
(navigation.filter: ckf) on the first 20 s of the third-party reference recording (skipped when ../shared
is absent).
"""
from types import SimpleNamespace

import numpy as np
import pytest

from receiver.schema import load_receiver_config
from receiver.errors import UserError
from receiver.gnss.geodesy import azel, ecef2lla, lla2ecef
from receiver.gnss.atmosphere import saastamoinen_m
from receiver.gnss.ephemeris import sat_state
from receiver.navigation.pvt import NavSolver, Observation
from receiver.navigation.pvt_filter import PvtFilter, make_pvt_filter
from receiver.gnss.signals import C_LIGHT, LAMBDA_L1, OMEGA_E
from receiver.sim.constellation import nominal_ephemerides

from repo_paths import ROOT
SHARED = ROOT.parent / "shared" / "data"
WEEK, T0 = 2190, 525600.0
RX = lla2ecef(35.68, 139.77, 40.0)
T = 0.1                                     # navigation interval (10 Hz)
NAV_CFG = SimpleNamespace(elevation_mask_deg=10.0, weighting="elevation", troposphere="none",
                          ionosphere="none", residual_threshold_m=30.0)


@pytest.fixture(scope="module")
def ephs():
    e, _ = nominal_ephemerides(ROOT / "data" / "gps_nominal_constellation.yaml", WEEK, T0)
    return e


def _rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.moveaxis(np.array([[c, s, z], [-s, c, z], [z, z, o]]), -1, 0)     # (k, 3, 3)


def _geometry(eph_list, t_true, r, prev=None):
    """Per satellite: travel time, position and velocity in the reception frame, clock bias/drift (s).
    prev: the result of the previous epoch (starting values: two iterations then converge)."""
    if prev is None:
        tau, clk = np.full(len(eph_list), 0.075), np.zeros(len(eph_list))
    else:
        tau, clk = prev[0], prev[3]
    for _ in range(4 if prev is None else 2):
        pos, vel, clk, clk_drift = sat_state(eph_list, t_true - tau + clk)
        rot = _rot_z(OMEGA_E * tau)
        pos_rx = np.einsum("kij,kj->ki", rot, pos)
        tau = np.linalg.norm(pos_rx - r, axis=1) / C_LIGHT
    return tau, pos_rx, np.einsum("kij,kj->ki", rot, vel), clk, clk_drift


def scene(ephs, traj, n_epochs=200, sigma_m=3.0, sigma_mps=0.05, averaged=False, code_carrier=0.0,
          clock_noise=True, seed=0, jump=None, troposphere=False, mask_deg=12.0):
    """WLS fixes and truth of a receiver on traj(t) -> (r, v) (t: s since T0).

    Clock: code bias b(t) = 3e4 m + (d + code_carrier) t, carrier drift d = 150 m/s plus TCXO-like noise.
    averaged: pseudorange rates are carrier delta ranges over the last interval (as the receiver's engine
    makes them) instead of instantaneous ones.  jump: (epoch, metres) added to the code clock from then on.
    troposphere: Saastamoinen delay on code and carrier (and corrected by the WLS).
    Returns a list of (receiver time, Fix), true positions, true velocities.
    """
    rng = np.random.default_rng(seed)
    everyone = sorted(ephs)
    el = azel(RX, _geometry([ephs[p] for p in everyone], T0, RX)[1])[1]
    prns = [p for p, e in zip(everyone, np.degrees(el)) if e > mask_deg]
    eph_list = [ephs[p] for p in prns]
    geo = None
    b_car, d = 3.0e4, 150.0
    out, truth_r, truth_v, prev_car = [], [], [], None
    for k in range(n_epochs + 1):                       # epoch 0 only feeds the first delta range
        t = k * T
        if k and clock_noise:                           # TCXO: S_b = 9e-3 m^2/s, S_d = 3.55e-2 m^2/s^3
            d += np.sqrt(3.55e-2 * T) * rng.standard_normal()
            b_car += d * T + np.sqrt(9e-3 * T) * rng.standard_normal()
        elif k:
            b_car += d * T
        b_code = b_car + code_carrier * t + (jump[1] if jump and k >= jump[0] else 0.0)
        r, v = traj(t)
        geo = _geometry(eph_list, T0 + t, r, geo)
        tau, p, vs, clk, clk_drift = geo
        tropo = 0.0
        if troposphere:
            lat, _, h = ecef2lla(r)
            tropo = saastamoinen_m(np.radians(lat), h, azel(r, p)[1])
        carrier_range = C_LIGHT * tau + b_car - C_LIGHT * clk + tropo
        rho = C_LIGHT * tau + b_code - C_LIGHT * clk + tropo + sigma_m * rng.standard_normal(len(prns))
        if averaged:
            rate = (carrier_range - prev_car) / T if prev_car is not None else None
        else:
            los = (p - r) / np.linalg.norm(p - r, axis=1)[:, None]
            rate = np.sum(los * (vs - v), axis=1) + d - C_LIGHT * clk_drift
        prev_car = carrier_range
        if k == 0:
            continue
        rate = rate + sigma_mps * rng.standard_normal(len(prns))
        rx_tow = T0 + t + b_code / C_LIGHT
        obs = [Observation(prn=prn, tx_tow=rx_tow - rho[i] / C_LIGHT, doppler_hz=-rate[i] / LAMBDA_L1,
                           cn0_dbhz=45.0) for i, prn in enumerate(prns)]
        nav_cfg = SimpleNamespace(**{**vars(NAV_CFG), "elevation_mask_deg": mask_deg - 2.0,
                                     "troposphere": "saastamoinen" if troposphere else "none"})
        fix = NavSolver(nav_cfg).fix(WEEK, rx_tow, obs, ephs, None, x0=RX)
        assert fix is not None
        out.append((rx_tow - T0, fix))
        truth_r.append(r)
        truth_v.append(v)
    return out, np.array(truth_r), np.array(truth_v)


def static(t):
    return RX, np.zeros(3)


def constant_velocity(t, v=np.array([12.0, -8.0, 1.0])):
    return RX + v * t, v


def circle(t, radius=100.0, speed=20.0):
    """Horizontal circle (centripetal acceleration 4 m/s^2) in the local East/North plane."""
    lat, lon = np.radians(35.68), np.radians(139.77)
    east = np.array([-np.sin(lon), np.cos(lon), 0.0])
    north = np.array([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
    w = speed / radius
    r = RX + radius * (np.cos(w * t) - 1.0) * east + radius * np.sin(w * t) * north
    v = speed * (-np.sin(w * t) * east + np.cos(w * t) * north)
    return r, v


def filtered(fixes, **kw):
    f = PvtFilter(**kw)
    return [f.step(*item) for item in fixes], f


def rms(fixes, truth, attr="ecef", skip=0):
    e = np.array([getattr(f, attr) for f in fixes])[skip:] - truth[skip:]
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


# ------------------------------------------------------------------------------------------------------
def test_config_keys_and_factory():
    cfg = load_receiver_config(None, ["navigation.filter=ckf", "navigation.filter_accel_psd=0.5",
                                      "navigation.rate_hz=5"])
    assert make_pvt_filter(load_receiver_config(None).navigation) is None          # default: wls
    f = make_pvt_filter(cfg.navigation)
    assert isinstance(f, PvtFilter) and f.kind == "ckf" and f.accel_psd == 0.5
    assert f.rate_interval_s == pytest.approx(0.2) and f.n == 9
    nav = load_receiver_config(None, ["navigation.filter=ekf",
                                      "navigation.filter_code_carrier_drift=false"]).navigation
    assert make_pvt_filter(nav).n == 8
    with pytest.raises(UserError):
        load_receiver_config(None, ["navigation.filter=ukf"])
    with pytest.raises(UserError):
        load_receiver_config(None, ["navigation.filter_clock=quartz"])


def test_fix_carries_the_satellite_geometry(ephs):
    fixes, _, _ = scene(ephs, constant_velocity, n_epochs=1, sigma_m=0.0, sigma_mps=0.0, clock_noise=False)
    f = fixes[0][1]
    assert f.sat_pos_ecef.shape == (f.n_sats, 3) and f.sat_vel_ecef.shape == (f.n_sats, 3)
    rng = np.linalg.norm(f.sat_pos_ecef - f.ecef, axis=1)
    assert np.allclose(f.pseudoranges_m, rng + f.clock_bias_m + f.residuals_m, atol=1e-3)
    los = (f.sat_pos_ecef - f.ecef) / rng[:, None]
    model = np.sum(los * (f.sat_vel_ecef - f.velocity_ecef), axis=1) + f.clock_drift_mps
    assert np.allclose(f.pseudorange_rates_mps, model + f.velocity_residuals_mps, atol=1e-6)
    assert np.max(np.abs(f.velocity_residuals_mps)) < 0.01


@pytest.mark.parametrize("averaged", [False, True])
def test_ekf_and_ckf_agree(ephs, averaged):
    fixes, truth, _ = scene(ephs, constant_velocity, n_epochs=60, sigma_m=0.5, sigma_mps=0.01,
                            averaged=averaged, seed=1)
    kw = dict(code_sigma_m=0.5, rate_sigma_mps=0.01, rate_interval_s=T if averaged else None)
    ekf, fe = filtered(fixes, kind="ekf", **kw)
    ckf, fc = filtered(fixes, kind="ckf", **kw)
    assert fe.n_cloned == fc.n_cloned == (59 if averaged else 0)
    dr = max(np.linalg.norm(a.ecef - b.ecef) for a, b in zip(ekf, ckf))
    dv = max(np.linalg.norm(a.velocity_ecef - b.velocity_ecef) for a, b in zip(ekf, ckf))
    db = max(abs(a.clock_bias_m - b.clock_bias_m) for a, b in zip(ekf, ckf))
    assert dr < 1e-3 and dv < 1e-4 and db < 1e-3
    scale = np.sqrt(np.outer(np.diag(fe.P), np.diag(fe.P)))
    assert np.max(np.abs(fe.P - fc.P) / scale) < 1e-3
    assert rms(ekf, truth) < 0.5


@pytest.mark.slow
@pytest.mark.parametrize("traj", [static, constant_velocity])
def test_filters_beat_single_epoch_wls(ephs, traj):
    fixes, truth, vtruth = scene(ephs, traj, n_epochs=150, sigma_m=3.0, sigma_mps=0.05, seed=2)
    wls = [f for _, f in fixes]
    pos_wls, vel_wls = rms(wls, truth), rms(wls, vtruth, "velocity_ecef")
    for kind in ("ekf", "ckf"):
        out, flt = filtered(fixes, kind=kind, code_sigma_m=3.0, rate_sigma_mps=0.05)
        assert flt.n_resets == 0 and flt.n_updates == len(fixes)
        pos, vel = rms(out, truth), rms(out, vtruth, "velocity_ecef")
        assert pos < 0.4 * pos_wls, (kind, pos, pos_wls)
        assert vel < vel_wls, (kind, vel, vel_wls)
        assert rms(out, truth, skip=75) < 0.25 * pos_wls
        # GPS time follows the filtered clock bias
        f = out[-1]
        assert f.gps_tow == pytest.approx(f.rx_tow - f.clock_bias_m / C_LIGHT, abs=1e-9)


@pytest.mark.slow
def test_delta_range_model_removes_the_acceleration_lag(ephs):
    """Rates averaged over the interval lag a T / 2 (0.2 m/s on a 4 m/s^2 circle); taken as instantaneous
    they bias the position along track, the delta-range (clone) model does not."""
    fixes, truth, vtruth = scene(ephs, circle, n_epochs=150, sigma_m=3.0, sigma_mps=0.03, averaged=True,
                                 seed=3)
    pos_wls = rms([f for _, f in fixes], truth)
    along_track = vtruth / np.linalg.norm(vtruth, axis=1)[:, None]

    def along(out):
        a = np.sum((np.array([f.ecef for f in out]) - truth) * along_track, axis=1)[50:]
        return abs(a.mean()), float(np.sqrt(np.mean(a * a)))

    lagged, _ = filtered(fixes, kind="ekf", code_sigma_m=3.0, rate_sigma_mps=0.03)
    bias_lagged, rms_lagged = along(lagged)
    assert bias_lagged > 0.3
    for kind in ("ekf", "ckf"):
        out, flt = filtered(fixes, kind=kind, code_sigma_m=3.0, rate_sigma_mps=0.03, rate_interval_s=T)
        assert flt.n_cloned == len(fixes) - 1
        bias, rms_along = along(out)
        assert bias < 0.3 * bias_lagged and rms_along < 0.6 * rms_lagged
        assert rms(out, truth, skip=50) < rms(lagged, truth, skip=50)
        assert rms(out, truth) < 0.25 * pos_wls


@pytest.mark.slow
def test_code_carrier_drift_state(ephs):
    """Carrier drift 150 m/s with a constant code clock (the reference recording's front end)."""
    fixes, truth, _ = scene(ephs, static, n_epochs=120, sigma_m=3.0, averaged=True, code_carrier=-150.0,
                            seed=4)
    pos_wls = rms([f for _, f in fixes], truth)
    out, flt = filtered(fixes, kind="ckf", rate_interval_s=T)
    assert flt.x[8] == pytest.approx(-150.0, abs=0.5)
    assert rms(out, truth, skip=20) < 0.4 * pos_wls
    bad, _ = filtered(fixes, kind="ckf", rate_interval_s=T, code_carrier_drift=False)
    assert rms(bad, truth, skip=20) > 2.0 * rms(out, truth, skip=20)


@pytest.mark.slow
def test_rates_are_corrected_for_the_atmosphere_change(ephs):
    """The troposphere delays code and carrier alike: its change (1 m/min on a 7 deg satellite) must come
    out of the carrier delta ranges, else the carrier-propagated position walks away from the code (seen
    here with equal weights; elevation weighting hides most of it)."""
    fixes, truth, _ = scene(ephs, static, n_epochs=200, sigma_m=0.3, sigma_mps=0.01, averaged=True, seed=6,
                            troposphere=True, mask_deg=3.0)
    assert min(fixes[0][1].elevations_deg) < 8.0
    kw = dict(kind="ekf", rate_interval_s=T, weighting="none", code_sigma_m=0.3, rate_sigma_mps=0.01)
    out, _ = filtered(fixes, **kw)

    class NoAtmosphere(PvtFilter):
        def _atmosphere(self, fix):
            return np.zeros(len(fix.prns))

    flt = NoAtmosphere(**kw)
    uncorrected = [flt.step(*item) for item in fixes]
    assert rms(out, truth, skip=100) < 0.5 * rms(uncorrected, truth, skip=100)


def test_unsmoothed_code_offsets(ephs):
    """The engine's unsmoothed - smoothed pseudorange differences are added to the code, unless
    smoothed_code (here a common 50 m offset: it all goes into the clock bias)."""
    fixes, _, _ = scene(ephs, static, n_epochs=3, sigma_m=0.0, sigma_mps=0.0, clock_noise=False)
    offsets = {prn: 50.0 for prn in fixes[0][1].prns}
    for smoothed, shift in ((False, 50.0), (True, 0.0)):
        plain, with_offsets = PvtFilter(smoothed_code=smoothed), PvtFilter(smoothed_code=smoothed)
        for t, fix in fixes:
            a, b = plain.step(t, fix), with_offsets.step(t, fix, offsets)
        assert b.clock_bias_m - a.clock_bias_m == pytest.approx(shift, abs=0.5)     # (the prior holds a bit)
        assert np.linalg.norm(b.ecef - a.ecef) < 0.5


def test_restart_after_a_clock_jump(ephs):
    fixes, truth, _ = scene(ephs, static, n_epochs=100, sigma_m=2.0, seed=5, jump=(50, 3.0e5))
    out, flt = filtered(fixes, kind="ekf")
    assert flt.n_resets == 1
    assert not any(np.linalg.norm(f.ecef - RX) > 30.0 for f in out)
    assert out[-1].clock_bias_m == pytest.approx(fixes[-1][1].clock_bias_m, abs=10.0)
    assert np.linalg.norm(out[-1].ecef - RX) < 5.0


def test_fix_without_satellite_states_is_refused(ephs):
    fixes, _, _ = scene(ephs, static, n_epochs=1)
    from dataclasses import replace
    with pytest.raises(ValueError):
        PvtFilter().step(0.0, replace(fixes[0][1], sat_pos_ecef=np.zeros((0, 3))))


# ------------------------------------------------------------------------------------------------------
REC, NAV = SHARED / "gpssim_static_tokyo.bin", SHARED / "brdc0010.22n"
TRUTH = np.array([-3959617.482, 3350136.615, 3699531.459])


@pytest.fixture(scope="module")
def reference_ckf_run(tmp_path_factory):
    """The receiver with navigation.filter: ckf on the first 20 s of the reference recording (assisted);
    the (time, WLS fix, code offsets) handed to the filter are recorded on the way."""
    if not (REC.exists() and NAV.exists()):
        pytest.skip("../shared/data reference recording absent")
    from receiver.navigation import pvt_filter
    from receiver.pipeline import run
    captured = []
    step = pvt_filter.PvtFilter.step

    def spy(self, t, fix, code_offsets=None):
        captured.append((t, fix, code_offsets))
        return step(self, t, fix, code_offsets)

    out = tmp_path_factory.mktemp("pvt_filter") / "ckf.h5"
    cfg = load_receiver_config(ROOT / "configs" / "gpssim_static_tokyo.yaml",
                               [("input.path", str(REC)), ("output.path", str(out)),
                                ("navigation.ephemeris", str(NAV)), ("navigation.filter", "ckf"),
                                ("input.duration_s", 20.0)])
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pvt_filter.PvtFilter, "step", spy)
        run(cfg, quiet=True)
    import h5py
    with h5py.File(out) as f:
        rows = {k: f["navigation"][k][:]
                for k in ("ecef", "velocity_ecef", "n_sats", "gps_tow", "clock_bias_m")}
    return out, cfg, rows, captured


@pytest.mark.slow
def test_engine_writes_the_filtered_solution(reference_ckf_run):
    """The /navigation rows are the CKF over the WLS fixes (with the engine's unsmoothed code), with the
    WLS's satellite count and DOPs, and their GPS time follows the filtered clock bias."""
    _, cfg, rows, captured = reference_ckf_run
    assert len(rows["ecef"]) == len(captured) > 150
    ckf, flt = filtered(captured, kind="ckf", rate_interval_s=1.0 / cfg.navigation.rate_hz)
    assert flt.n_resets == 0 and flt.n_cloned == len(captured) - 1
    assert np.max(np.linalg.norm(np.array([f.ecef for f in ckf]) - rows["ecef"], axis=1)) < 1e-6
    dv = np.array([f.velocity_ecef for f in ckf]) - rows["velocity_ecef"]
    assert np.max(np.linalg.norm(dv, axis=1)) < 1e-6
    wls = [fx for _, fx, _ in captured]
    assert np.array_equal(rows["n_sats"], [f.n_sats for f in wls])
    assert np.max(np.linalg.norm(np.array([f.ecef for f in wls]) - rows["ecef"], axis=1)) > 0.1
    rx_tow = np.array([f.rx_tow for f in wls])
    assert np.allclose(rows["gps_tow"], rx_tow - rows["clock_bias_m"] / C_LIGHT, rtol=0, atol=1e-9)
    # the engine hands over unsmoothed code (carrier smoothing is on by default)
    assert max(abs(v) for _, _, offs in captured[50:] for v in offs.values()) > 0.1


@pytest.mark.slow
def test_filters_on_the_reference_recording(reference_ckf_run):
    """EKF and CKF agree and reach the truth with 3D and velocity RMS at or below the WLS's."""
    _, cfg, rows, captured = reference_ckf_run
    wls = [fx for _, fx, _ in captured]
    ekf, _ = filtered(captured, kind="ekf", rate_interval_s=1.0 / cfg.navigation.rate_hz)
    assert np.max(np.linalg.norm(np.array([f.ecef for f in ekf]) - rows["ecef"], axis=1)) < 0.01
    err = lambda e: float(np.sqrt(np.mean(np.sum((np.asarray(e) - TRUTH) ** 2, axis=1))))   # noqa: E731
    pos_wls, pos_ckf, pos_ekf = err([f.ecef for f in wls]), err(rows["ecef"]), err([f.ecef for f in ekf])
    assert pos_ckf <= pos_wls and pos_ekf <= pos_wls and pos_ckf < 2.0, (pos_ckf, pos_ekf, pos_wls)
    vel = lambda v: float(np.sqrt(np.mean(np.sum(np.asarray(v) ** 2, axis=1))))             # noqa: E731
    assert vel(rows["velocity_ecef"]) <= vel([f.velocity_ecef for f in wls])


@pytest.mark.slow
def test_replay_recomputes_the_wls_fixes(reference_ckf_run):
    """replay_run re-solves the run's WLS fixes from its /observables (and filters them)."""
    from receiver.navigation.pvt_filter import replay_run
    from receiver.gnss.rinex import read_rinex_nav
    out, cfg, rows, captured = reference_ckf_run
    ephs, iono = read_rinex_nav(NAV)
    rep = replay_run(out, ephs, iono, cfg.navigation, kinds=("ekf",))
    assert len(rep["wls"]) == len(captured)
    d = [np.linalg.norm(a.ecef - b.ecef) for a, (_, b, _) in zip(rep["wls"], captured)]
    assert max(d) < 1e-3
    e = np.array([f.ecef for f in rep["ekf"]]) - TRUTH
    assert np.sqrt(np.mean(np.sum(e * e, axis=1))) < 3.0
