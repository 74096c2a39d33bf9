"""receiver.batch.metrics / compare on hand-made run and truth files with known errors."""
import math

import h5py
import numpy as np
import pytest

from receiver.batch.compare import comparison_plot, comparison_table, group_stats, interval
from receiver.batch.metrics import METRIC_KEYS, carrier_phase_errors, compute_metrics
from receiver.gnss.geodesy import enu_matrix, lla2ecef

FS, IF = 1.0e6, 1000.0
LAT, LON, H = 46.5, 6.6, 400.0
T0 = 345600.0


def _true_phase(t):
    """A carrier phase with Doppler -1200 Hz and a 3 Hz/s Doppler rate (cycles), and its derivative."""
    return -1200.0 * t + 1.5 * t ** 2, -1200.0 + 3.0 * t


def _make(tmp_path, noise=0.02, seed=0):
    rng = np.random.default_rng(seed)
    ref = np.asarray(lla2ecef(LAT, LON, H), float).reshape(3)
    truth = tmp_path / "t.truth.h5"
    tt = np.arange(0, 601) * 0.01                       # 6 s of truth at 100 Hz
    with h5py.File(truth, "w") as f:
        f.attrs["gps_week"] = 2300
        f.attrs["start_gps_tow_s"] = T0
        g = f.create_group("receiver")
        g["time_s"] = tt
        g["gps_tow"] = T0 + tt
        g["ecef"] = np.tile(ref, (tt.size, 1))
        g["velocity_ecef"] = np.zeros((tt.size, 3))
        g["clock_bias_m"] = np.zeros(tt.size)
        g["clock_drift_mps"] = np.zeros(tt.size)
        s = f.create_group("satellites").create_group("G01")
        ph, dop = _true_phase(tt)
        s["time_s"] = tt
        s["carrier_phase_cycles"] = ph
        s["doppler_hz"] = dop
        s["visible"] = np.ones(tt.size, bool)
    run = tmp_path / "run.h5"
    k = np.arange(6000)                                 # 1 ms epochs
    t = k * 1e-3
    lock = ((t >= 0.3) & ~((t >= 3.0) & (t < 3.1))).astype(np.uint8)   # one loss of lock at 3.0 s
    state = np.where(t < 0.3, 0, 2).astype(np.uint8)
    err = rng.normal(0.0, noise, t.size)
    ph, _ = _true_phase(t)
    nco = ph + IF * t + 3.5 + err                       # half-cycle + integer ambiguity + NCO offset
    enu_err = np.array([3.0, 4.0, -2.0])
    with h5py.File(run, "w") as f:
        a = f.attrs
        a["sample_rate_hz"], a["if_hz"], a["first_sample"], a["n_samples"] = FS, IF, 0, int(6 * FS)
        a["wall_time_s"], a["realtime_factor"] = 2.0, 3.0
        c = f.create_group("channels").create_group("G01")
        c["time_s"], c["sample_index"] = t, (k * 1000).astype(np.int64)
        c["carrier_phase_cycles"], c["pll_lock"], c["state"] = nco, lock, state
        c["cn0_dbhz"] = np.where(lock > 0, 40.0, 20.0).astype(np.float32)
        c["carrier_err_cycles"] = err.astype(np.float32)
        bad = f["channels"].create_group("G05")             # a false acquisition: never locks, then lost
        bad["time_s"], bad["sample_index"] = t[:500], (k[:500] * 1000).astype(np.int64)
        bad["carrier_phase_cycles"] = np.zeros(500)
        bad["pll_lock"] = np.zeros(500, np.uint8)
        bad["state"] = np.where(np.arange(500) < 499, 0, 3).astype(np.uint8)
        bad["cn0_dbhz"] = np.zeros(500, np.float32)
        n = f.create_group("navigation")
        tf = np.arange(1.5, 6.0, 0.5)
        n["time_s"] = tf
        n["gps_week"] = np.full(tf.size, 2300, np.int32)
        n["gps_tow"] = T0 + tf
        n["ecef"] = np.tile(ref + enu_err @ enu_matrix(LAT, LON), (tf.size, 1))
        n["velocity_ecef"] = np.tile([0.0, 0.1, 0.0], (tf.size, 1))
        n["clock_bias_m"] = np.zeros(tf.size)
        n["clock_drift_mps"] = np.zeros(tf.size)
        n["n_sats"] = np.full(tf.size, 7, np.int32)
        n["pdop"] = np.full(tf.size, 1.5)
        n["mode"] = (tf >= 4.0).astype(np.uint8)
    return run, truth


def test_metrics_against_truth(tmp_path):
    run, truth = _make(tmp_path)
    m = compute_metrics(run, truth, carrier_settle_s=1.0)
    assert set(m) == set(METRIC_KEYS)
    assert m["ttff_s"] == pytest.approx(1.5)
    assert m["n_fixes"] == m["n_scored"] == 9
    assert m["pos_3d_rms_m"] == pytest.approx(math.sqrt(29.0), rel=1e-6)
    assert m["pos_h_rms_m"] == pytest.approx(5.0, rel=1e-6)
    assert m["pos_h_max_m"] == pytest.approx(5.0, rel=1e-6)
    assert m["pos_v_max_m"] == pytest.approx(2.0, rel=1e-6)
    assert m["vel_3d_rms_mps"] == pytest.approx(0.1, rel=1e-6)
    assert m["loss_of_lock"] == 1 and m["n_channels_locked"] == 1 and m["channels_dropped"] == 0
    assert m["cn0_mean_dbhz"] == pytest.approx(40.0)
    # 1.3 s .. 6 s minus the 0.1 s outage: the ambiguity (3.5 cycles) and the IF term are removed
    assert m["carrier_phase_epochs"] == pytest.approx(4700 - 100, abs=2)
    assert m["carrier_phase_err_std_cyc"] == pytest.approx(0.02, rel=0.05)
    assert m["carrier_disc_std_cyc"] == pytest.approx(0.02, rel=0.05)
    assert m["vector_fix_fraction"] == pytest.approx(4 / 9)
    assert m["run_wall_s"] == 2.0 and m["realtime_factor"] == 3.0 and m["signal_s"] == pytest.approx(6.0)


def test_carrier_error_wraps_half_cycles(tmp_path):
    """Half-cycle jumps (data-bit ambiguity) do not count as phase error."""
    run, truth = _make(tmp_path, noise=0.01)
    with h5py.File(run, "a") as f:
        ph = f["channels/G01/carrier_phase_cycles"]
        v = ph[:]
        v[4000:] += 0.5
        ph[...] = v
    m = compute_metrics(run, truth)
    assert m["carrier_phase_err_std_cyc"] == pytest.approx(0.01, rel=0.06)


def test_carrier_phase_errors_near_the_wrap_edge():
    """A constant offset near +-0.25 cycles is centred by the circular mean, not split by the wrap."""
    t = np.arange(3000) * 1e-3
    ph, _ = _true_phase(t)
    rng = np.random.default_rng(3)
    ch = {"time_s": t, "sample_index": (t * FS).astype(np.int64), "pll_lock": np.ones(t.size, np.uint8),
          "state": np.full(t.size, 2, np.uint8),
          "carrier_phase_cycles": ph + IF * t + 0.249 + rng.normal(0, 0.01, t.size)}
    tt = np.arange(0, 301) * 0.01
    pt, dt = _true_phase(tt)
    e = carrier_phase_errors(ch, {"time_s": tt, "carrier_phase_cycles": pt, "doppler_hz": dt}, IF, 0.5)
    assert e.size == 2500
    assert abs(np.mean(e)) < 1e-3 and np.std(e) == pytest.approx(0.01, rel=0.06)


def test_metrics_static_reference_without_truth(tmp_path):
    run, _truth = _make(tmp_path)
    m = compute_metrics(run, None, reference_llh=[LAT, LON, H])
    assert m["pos_3d_rms_m"] == pytest.approx(math.sqrt(29.0), rel=1e-6)
    assert m["vel_3d_rms_mps"] == pytest.approx(0.1, rel=1e-6)
    assert math.isnan(m["carrier_phase_err_std_cyc"])          # no truth: no carrier metric
    assert m["carrier_disc_std_cyc"] == pytest.approx(0.02, rel=0.05)
    m2 = compute_metrics(run)                                   # no truth, no reference
    assert math.isnan(m2["pos_3d_rms_m"]) and m2["ttff_s"] == pytest.approx(1.5)


def test_interval_and_groups(tmp_path):
    n, mean, lo, hi = interval([1.0, 2.0, 3.0, float("nan")], 0.95)
    assert n == 3 and mean == 2.0
    assert hi - mean == pytest.approx(4.302653 * 1.0 / math.sqrt(3), rel=1e-5)   # t(0.975, 2) s / sqrt(n)
    n1, mean1, lo1, hi1 = interval([5.0])
    assert (n1, mean1) == (1, 5.0) and math.isnan(lo1) and math.isnan(hi1)
    rows = [{"variant": "a", "status": "ok", "x": 1.0}, {"variant": "a", "status": "ok", "x": 3.0},
            {"variant": "b", "status": "ok", "x": 10.0}, {"variant": "b", "status": "failed", "x": math.nan}]
    g = group_stats(rows, "variant", ["x"])
    assert [x["variant"] for x in g] == ["a", "b"]
    assert g[0]["x_mean"] == 2.0 and g[1]["n_runs"] == 2 and g[1]["n_ok"] == 1 and g[1]["x_mean"] == 10.0
    text = comparison_table(g, ["variant"], ["x"], 0.95)
    assert "2 ± " in text and "1 / 2" in text
    png = tmp_path / "c.png"
    comparison_plot(g, ["variant"], ["x"], str(png))
    assert png.stat().st_size > 1000
