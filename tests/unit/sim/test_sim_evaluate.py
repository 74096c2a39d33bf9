"""receiver.evaluate against a hand-made run file (fixes with known errors)."""
import h5py
import numpy as np
import pytest

from receiver.errors import UserError
from receiver.evaluate import evaluate, format_table
from receiver.gnss.geodesy import enu_matrix, lla2ecef


def _truth(path, t0=1000.0, n=1001, vel=(1.0, 0.0, 0.0)):
    t = t0 + np.arange(n) * 0.01
    ref = lla2ecef(45.0, 7.0, 300.0)
    v = np.asarray(vel) @ enu_matrix(45.0, 7.0)
    with h5py.File(path, "w") as f:
        f.attrs["gps_week"] = 2300
        f.attrs["start_gps_tow_s"] = t0
        g = f.create_group("receiver")
        g["time_s"] = t - t0
        g["gps_tow"] = t
        g["ecef"] = ref + (t - t0)[:, None] * v
        g["velocity_ecef"] = np.tile(v, (n, 1))
        g["clock_bias_m"] = 300.0 + 150.0 * (t - t0)
        g["clock_drift_mps"] = np.full(n, 150.0)
    return ref, v


def _run(path, tow, ecef, vel, cb, cd, week=2300):
    n = len(tow)
    with h5py.File(path, "w") as f:
        g = f.create_group("navigation")
        g["gps_week"] = np.full(n, week, np.int32)
        g["gps_tow"] = np.asarray(tow, float)
        g["ecef"] = np.asarray(ecef, float)
        g["velocity_ecef"] = np.asarray(vel, float)
        g["clock_bias_m"] = np.asarray(cb, float)
        g["clock_drift_mps"] = np.asarray(cd, float)
        g["n_sats"] = np.full(n, 7, np.int32)
        g["pdop"] = np.full(n, 1.8)
        g["mode"] = np.zeros(n, np.uint8)


def test_known_errors(tmp_path):
    truth = tmp_path / "t.truth.h5"
    ref, v = _truth(truth)
    rot = enu_matrix(45.0, 7.0)
    tow = 1000.0 + np.arange(2.005, 9.0, 0.1)             # between truth samples: interpolation
    true_pos = ref + (tow - 1000.0)[:, None] * v
    enu_err = np.tile([3.0, -4.0, 2.0], (tow.size, 1))
    enu_err[::2] *= -1.0                                   # alternating: mean 0 when even count
    enu_err[-1] = [0.0, 0.0, 12.0]                         # one large vertical error
    ecef = true_pos + enu_err @ rot
    vel = np.tile(v + np.array([0.1, 0.0, 0.0]), (tow.size, 1))
    cb = 300.0 + 150.0 * (tow - 1000.0) + 5.0
    cd = np.full(tow.size, 150.5)
    run = tmp_path / "run.h5"
    _run(run, tow, ecef, vel, cb, cd)
    s = evaluate(run, truth)
    d3 = np.linalg.norm(enu_err, axis=1)
    assert s["n_fixes"] == s["n_scored"] == tow.size
    assert s["ttff_s"] == pytest.approx(2.005)
    assert s["pos_3d_rms_m"] == pytest.approx(np.sqrt(np.mean(d3 ** 2)), rel=1e-6)
    assert s["pos_h_rms_m"] == pytest.approx(np.sqrt(np.mean(enu_err[:, 0] ** 2 + enu_err[:, 1] ** 2)),
                                             rel=1e-6)
    assert s["pos_v_rms_m"] == pytest.approx(np.sqrt(np.mean(enu_err[:, 2] ** 2)), rel=1e-6)
    assert s["pos_3d_max_m"] == pytest.approx(12.0, rel=1e-6)
    assert s["pos_mean_u_m"] == pytest.approx(np.mean(enu_err[:, 2]), abs=1e-6)
    assert s["vel_3d_rms_mps"] == pytest.approx(0.1, rel=1e-6)
    assert s["clock_bias_err_mean_m"] == pytest.approx(5.0, abs=1e-6)
    assert s["clock_bias_err_std_m"] == pytest.approx(0.0, abs=1e-6)
    assert s["clock_drift_err_rms_mps"] == pytest.approx(0.5, abs=1e-9)
    text = format_table(s)
    assert "position 3D RMS" in text and "time to first fix" in text


def test_week_alignment_and_out_of_span(tmp_path):
    truth = tmp_path / "t.truth.h5"
    ref, v = _truth(truth, t0=604790.0, n=2001)
    # fixes in the next week (tow wrapped) and one outside the truth span
    tow = np.array([604795.0, 2.0, 5.0, 50.0])
    week = np.array([2300, 2301, 2301, 2301])
    t_abs = np.array([604795.0, 604802.0, 604805.0, 604850.0])
    true_pos = ref + (t_abs - 604790.0)[:, None] * v
    run = tmp_path / "run.h5"
    _run(run, tow, true_pos, np.tile(v, (4, 1)), np.zeros(4), np.zeros(4))
    with h5py.File(run, "a") as f:
        del f["navigation/gps_week"]
        f["navigation/gps_week"] = week.astype(np.int32)
    s = evaluate(run, truth)
    assert s["n_fixes"] == 4 and s["n_scored"] == 3
    assert s["pos_3d_max_m"] < 1e-6


def test_no_fixes_and_bad_files(tmp_path):
    truth = tmp_path / "t.truth.h5"
    _truth(truth)
    run = tmp_path / "empty.h5"
    with h5py.File(run, "w") as f:
        f.create_group("navigation")
    s = evaluate(run, truth)
    assert s["n_fixes"] == 0 and np.isnan(s["pos_3d_rms_m"])
    assert "n/a" in format_table(s)
    with pytest.raises(UserError, match="not found"):
        evaluate(tmp_path / "missing.h5", truth)
    with pytest.raises(UserError, match="no /receiver"):
        evaluate(run, run)
