"""Doppler measurement model and simulator (receiver.leo.doppler)."""
import numpy as np
import pytest

from receiver.errors import UserError
from receiver.gnss.geodesy import lla2ecef
from receiver.leo import doppler as D
from receiver.leo.config import load_scenario
from receiver.leo.constellation import Constellation
from receiver.gnss.signals import C_LIGHT

F0 = D.IRIDIUM_CARRIER_HZ


@pytest.fixture(scope="module")
def con():
    return Constellation.from_file()


def test_doppler_model_equals_numerical_derivative_of_range(con):
    rx = lla2ecef(39.9042, 116.4074, 60.0)
    t = np.datetime64("2022-04-05T12:02:30", "us")
    h = np.timedelta64(50_000, "us")                       # 0.05 s
    r, v, _ = con.propagate_ecef([t - h, t, t + h])
    rho = np.linalg.norm(r - rx, axis=2)                   # (3, N)
    rho_dot_num = (rho[2] - rho[0]) / 0.1
    fu = 123.0
    model = D.doppler_model(np.r_[rx, fu], r[1], v[1], F0)[0]
    expected = -(F0 / C_LIGHT) * rho_dot_num + fu
    # 1 cm/s of range rate is 0.054 Hz; SGP4 velocity vs position consistency is at that level
    assert np.max(np.abs(model - expected)) < 0.2
    assert np.max(np.abs(model - fu)) > 1e4                 # LEO Doppler is tens of kHz


def test_jacobian_equals_finite_differences(con):
    rx = lla2ecef(39.9, 116.4, 50.0)
    r, v, _ = con.propagate_ecef(["2022-04-05T12:02:00"])
    x = np.r_[rx, 10.0]
    J = D.doppler_jacobian(x, r[0], v[0], F0)
    Jn = np.zeros_like(J)
    for i, step in enumerate((1.0, 1.0, 1.0, 0.1)):
        dx = np.zeros(4)
        dx[i] = step
        Jn[:, i] = (D.doppler_model(x + dx, r[0], v[0], F0)[0] -
                    D.doppler_model(x - dx, r[0], v[0], F0)[0]) / (2 * step)
    assert np.allclose(J, Jn, rtol=1e-6, atol=1e-9)


def test_simulation_visibility_noise_and_reproducibility(con):
    cfg = load_scenario(None, ["time.start_utc=2022-04-05T11:45:00",
                               "time.stop_utc=2022-04-05T12:15:00", "time.step_s=10",
                               "measurement.noise_sigma_hz=2.0", "measurement.seed=5",
                               "receiver.freq_drift_hz_per_s=0.1"])
    d = D.simulate(cfg, con)
    el = d.elevation_deg
    assert np.array_equal(d.observed, el >= 10.0)
    assert d.observed.any(axis=1).all()                    # always something in view
    noise = (d.doppler_hz - d.truth_doppler_hz)[d.observed]
    assert abs(noise.std() - 2.0) < 0.25 and abs(noise.mean()) < 0.3
    assert np.allclose(d.truth_freq_offset_hz, 150.0 + 0.1 * d.t_s)
    d2 = D.simulate(cfg, con)
    assert np.array_equal(d.doppler_hz, d2.doppler_hz, equal_nan=True)
    # truth Doppler equals the model at the true state
    k = np.nonzero(d.observed.any(axis=1))[0][3]
    pos, vel, _ = d.epoch(k)
    m = D.doppler_model(np.r_[d.truth_ecef, d.truth_freq_offset_hz[k]], pos, vel, F0)[0]
    assert np.allclose(m, d.truth_doppler_hz[k, d.observed[k]])


def test_measurement_file_round_trip(tmp_path, con):
    d = D.simulate(load_scenario(None, []), con)
    p = tmp_path / "m.h5"
    D.save_measurements(p, d)
    e = D.load_measurements(p)
    assert np.array_equal(e.doppler_hz, d.doppler_hz, equal_nan=True)
    assert np.array_equal(e.time_utc, d.time_utc)
    assert np.allclose(e.sat_pos, d.sat_pos) and e.carrier_hz == d.carrier_hz
    assert np.allclose(e.truth_ecef, d.truth_ecef)
    assert e.sat_names == d.sat_names
    w = e.window("2022-04-05T12:02:00", "2022-04-05T12:03:00", 10.0)
    assert w.n_epochs == 7 and w.t_s[0] == 0.0 and np.allclose(np.diff(w.t_s), 10.0)


def test_bad_files_and_values_raise_user_error(tmp_path):
    p = tmp_path / "x.h5"
    p.write_text("not hdf5")
    with pytest.raises(UserError, match="not an HDF5"):
        D.load_measurements(p)
    with pytest.raises(UserError, match="not found"):
        D.load_measurements(tmp_path / "nope.h5")
    with pytest.raises(UserError, match="measurement.noise_sigma_hz"):
        load_scenario(None, ["measurement.noise_sigma_hz=-1"])
    with pytest.raises(UserError, match="time.start_utc"):
        load_scenario(None, ["time.start_utc=yesterday"])
    with pytest.raises(UserError, match="unknown config key 'receiver.latitude'"):
        load_scenario(None, ["receiver.latitude=3"])
