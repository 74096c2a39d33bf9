"""Doppler positioning drivers (receiver.leo.solvers)."""
import numpy as np
import pytest

from receiver.leo import solvers
from receiver.leo.config import load_scenario
from receiver.leo.constellation import Constellation
from receiver.leo.doppler import simulate


@pytest.fixture(scope="module")
def con():
    return Constellation.from_file()


@pytest.fixture(scope="module")
def clean(con):
    return simulate(load_scenario(None, ["measurement.noise_sigma_hz=0", "receiver.height_m=0"]), con)


@pytest.fixture(scope="module")
def noisy(con):
    return simulate(load_scenario(None, ["measurement.seed=11"]), con)


def test_all_solvers_converge_from_geosot_on_noise_free_data(clean):
    x0, g = solvers.initial_state(clean)
    assert np.linalg.norm(x0[:3] - clean.truth_ecef) < 400
    for m in solvers.METHODS:
        r = solvers.solve(clean, m, x0, dict(sigma_hz=0.5))
        assert not r.failed
        err = np.linalg.norm(r.final[:3] - clean.truth_ecef)
        assert err < (1e-3 if m == "lsm" else 50.0), (m, err)
        assert abs(r.final[3] - 150.0) < 0.5
        # without process noise the filters approach the exact solution closely
        if m != "lsm":
            r0 = solvers.solve(clean, m, x0, dict(sigma_hz=0.5, sigma_d2_m2=0, sf_hz2_per_s=0))
            assert np.linalg.norm(r0.final[:3] - clean.truth_ecef) < 5.0


def test_earth_centre_start_diverges_but_geosot_start_converges(noisy):
    x0, _ = solvers.initial_state(noisy)
    for m in solvers.METHODS:
        bad = solvers.solve(noisy, m, solvers.earth_center_state(),
                            dict(sigma_hz=0.5, init_sigma_m=2.0e6))
        fin = bad.estimates[-1, :3]
        diverged = bad.failed or not np.all(np.isfinite(fin)) or \
            np.linalg.norm(fin - noisy.truth_ecef) > 1.0e6
        assert diverged, m
        good = solvers.solve(noisy, m, x0, dict(sigma_hz=0.5))
        assert np.linalg.norm(good.final[:3] - noisy.truth_ecef) < 300.0, m


def test_ekf_without_process_noise_reproduces_batch_least_squares(noisy):
    x0, _ = solvers.initial_state(noisy)
    ls = solvers.solve(noisy, "lsm", x0, dict(sigma_hz=0.5))
    ekf = solvers.solve(noisy, "ekf", x0, dict(sigma_hz=0.5, sigma_d2_m2=0.0, sf_hz2_per_s=0.0,
                                               init_sigma_m=1e4, init_sigma_fu_hz=1e3))
    assert np.linalg.norm(ekf.final[:3] - ls.final[:3]) < 5.0
    assert abs(ekf.final[3] - ls.final[3]) < 0.1


def test_sqrt_ckf_equals_ckf_on_the_doppler_problem(noisy):
    x0, _ = solvers.initial_state(noisy)
    a = solvers.solve(noisy, "ckf", x0, dict(sigma_hz=0.5))
    b = solvers.solve(noisy, "sqrt_ckf", x0, dict(sigma_hz=0.5))
    assert np.max(np.abs(a.estimates - b.estimates)) < 1e-6
    assert np.max(np.abs(a.covariances - b.covariances)) < 1e-4


def test_lsm_holds_the_initial_value_until_determined(noisy):
    x0, _ = solvers.initial_state(noisy)
    r = solvers.solve(noisy, "lsm", x0, dict(sigma_hz=0.5, lsm_min_observations=10,
                                             lsm_hold_until_better=False))
    # two satellites per epoch: fewer than 10 observations during the first 4 epochs
    assert (noisy.observed.sum(axis=1) == 2).all()
    assert np.allclose(r.estimates[:4], x0)
    assert not np.allclose(r.estimates[4], x0)
    w = solvers.solve(noisy, "lsm", x0, dict(sigma_hz=0.5, lsm_window_epochs=6,
                                             lsm_hold_until_better=False))
    assert np.all(np.isfinite(w.estimates))
    assert not np.allclose(w.final, r.final)              # a sliding window is a different batch


def test_filter_failure_is_reported_not_raised(noisy):
    # 1e-12 Hz measurement noise (a 1e-24 Hz^2 R against kHz-level innovations): round-off in
    # P - W Pzz W^T makes P indefinite after some updates; the Cholesky CKF reports the failure and
    # the square-root CKF keeps going
    x0, _ = solvers.initial_state(noisy)
    st = dict(sigma_hz=1e-12, init_sigma_m=1e3, init_sigma_fu_hz=1e3, sigma_d2_m2=0.0,
              sf_hz2_per_s=0.0)
    r = solvers.solve(noisy, "ckf", x0, st)
    assert r.failed and "Cholesky" in r.message
    k = int(r.message.split("epoch ")[1].split(":")[0])
    assert np.all(np.isfinite(r.estimates[:k])) and np.isnan(r.estimates[k:]).all()
    s = solvers.solve(noisy, "sqrt_ckf", x0, st)
    assert not s.failed and np.all(np.isfinite(s.estimates))
