"""Outage metrics (receiver/evaluate/outages.py) on hand-made fix tables and files with known answers."""
import json
import math

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from receiver.batch.metrics import METRIC_KEYS, compute_metrics
from receiver.cli import main
from receiver.evaluate.outages import (OUTAGE_METRIC_KEYS, Fixes, Visibility, batch_metrics, canyon_report,
                                       end_report, loss_report, outage_report, report, total_outages)

OFF = 1e-4            # receiver clock bias: fixes at round GPS times sit 0.1 ms late on the truth axis


def _grid(t0, t1, period=0.1):
    return np.round(np.arange(t0, t1 - 1e-9, period), 6) + OFF


def _outage_fixes():
    """60 s at 10 Hz; outages [10, 11), [20, 23), [30, 38) (see the assertions for what each holds)."""
    t, err, coast = [], [], []

    def add(ts, e, c=False):
        t.extend(ts)
        err.extend(np.broadcast_to(e, len(ts)))
        coast.extend([c] * len(ts))

    add(_grid(0, 10), 2.0)                      # before: good
    add(_grid(11.3, 11.7), 15.0)                # measured but poor (first fix 0.3 s after the return)
    add(_grid(11.7, 20), 3.0)                   # good from 11.7 s
    add(_grid(20, 23.5), 40.0, True)            # coasting through [20, 23) and 0.5 s beyond
    add([21.0 + OFF], 90.0)                     # a measured fix INSIDE the outage (claims what it lacks)
    add([10.2 + OFF], 6.0)                      # a measured fix 0.2 s into outage 1: loss not yet noticed
    add(_grid(23.5, 23.8), 12.0)                # measured, > 10 m
    add(_grid(23.8, 30), 4.0)                   # good from 23.8 s
    # third outage [30, 38): nothing after it (fixes stop)
    return Fixes(np.array(t), np.array(err), np.array(coast))


def test_outage_report_by_hand():
    fx = _outage_fixes()
    rep = outage_report(fx, [(10.0, 11.0), (20.0, 23.0), (30.0, 38.0)], t_end=60.0)
    o1, o2, o3 = rep["outages"]
    assert o1["dur_s"] == 1.0 and o2["dur_s"] == 3.0 and o3["dur_s"] == 8.0
    assert o1["first_fix_s"] == pytest.approx(0.3 + OFF)
    assert o1["ttgf_s"] == pytest.approx(0.7 + OFF)
    assert o1["max_err_m"] == 15.0 and o1["max_err_all_m"] == 15.0 and o1["n_coast"] == 0
    assert o1["n_inside"] == 0
    # outage 2: coast fixes are not the first fix after the return; the measured fix inside the outage
    # (at 21 s) is counted (n_inside) and its error is the window's worst
    assert o2["first_fix_s"] == pytest.approx(0.5 + OFF)
    assert o2["ttgf_s"] == pytest.approx(0.8 + OFF)
    assert o2["max_err_m"] == 90.0 and o2["max_err_all_m"] == 90.0
    assert o2["n_coast"] == 35 and o2["n_inside"] == 1
    assert math.isnan(o3["ttgf_s"]) and math.isnan(o3["first_fix_s"]) and math.isnan(o3["max_err_m"])
    assert rep["fixes_to_end"] is False and rep["end_gap_s"] == pytest.approx(60.0 - 29.9 - OFF)
    assert rep["max_err_m"] == 90.0 and rep["n_coast"] == 35 and rep["n_inside"] == 1
    # without the lying fix the worst measured error is the 15 m of the pull-in
    keep = ~((fx.t > 20.9) & (fx.t < 21.1) & ~fx.coast)
    rep2 = outage_report(Fixes(fx.t[keep], fx.err[keep], fx.coast[keep]), [(10.0, 11.0), (20.0, 23.0)], 30.05)
    assert rep2["max_err_m"] == 15.0 and rep2["max_err_all_m"] == 40.0
    fx.err[3] = 31.0                                             # a bad fix long before any outage counts too
    assert outage_report(fx, [(10.0, 11.0)], 60.0)["max_err_m"] == 90.0
    assert outage_report(Fixes(fx.t[keep], fx.err[keep], fx.coast[keep]), [(10.0, 11.0)], 60.0)["max_err_m"] == 31.0
    assert rep2["outages"][1]["first_fix_s"] == pytest.approx(0.5 + OFF)
    assert rep2["fixes_to_end"] is True


def test_batch_metrics_keys_and_values():
    fx = _outage_fixes()
    rep = {"total": outage_report(fx, [(10.0, 11.0), (20.0, 23.0), (30.0, 38.0)], 60.0), "canyon": None,
           **end_report(fx, 60.0)}
    m = batch_metrics(rep)
    assert set(m) == set(OUTAGE_METRIC_KEYS) and set(OUTAGE_METRIC_KEYS) <= set(METRIC_KEYS)
    assert m["outage_n"] == 3.0 and m["outage2_dur_s"] == 3.0
    assert m["outage1_ttgf_s"] == pytest.approx(0.7 + OFF) and m["outage2_max_err_m"] == 90.0
    assert math.isnan(m["outage3_ttgf_s"]) and math.isnan(m["outage4_dur_s"])
    assert m["fixes_to_end"] == 0.0 and m["outage_coast_fixes"] == 35.0 and m["outage_fixes_inside"] == 1.0
    assert math.isnan(m["canyon_availability"])
    assert all(math.isnan(v) for v in batch_metrics({"total": None, "canyon": None}).values())


def test_total_outages_from_the_blockage_table():
    t = np.arange(0, 3000) * 0.01
    n = np.full(t.size, 7)
    n[(t >= 5.0) & (t < 6.0)] = 0                               # e.g. random blockages coinciding
    vis = Visibility(t, n, total_windows=[(20.0, 23.0), (8.0, 9.0), (22.0, 25.0), (29.0, 40.0)])
    out = total_outages(vis)
    assert len(out) == 3 and out[:2] == [(8.0, 9.0), (20.0, 25.0)] and out[2] == pytest.approx((29.0, 30.0))
    # a random-blockage truth: coincidences are not total outages
    assert total_outages(Visibility(t, n, random_window=(4.0, 30.0), total_windows=[])) == []
    # a table of per-satellite outages only (every satellite listed at once, configs/scenarios/
    # fig8_total_outages.yaml): the runs with no satellite visible
    assert total_outages(Visibility(t, n, total_windows=[])) == [pytest.approx((5.0, 6.0))]


def test_total_outages_from_visibility():
    t = np.arange(0, 3000) * 0.01                               # 30 s at 100 Hz
    n = np.full(t.size, 7)
    n[(t >= 5.0) & (t < 6.0)] = 0
    n[(t >= 9.0) & (t < 9.02)] = 0                              # 20 ms: a glitch, not an outage
    n[(t >= 12.0) & (t < 15.0)] = 3                             # partial blockage: not total
    n[t >= 27.0] = 0                                            # until the end
    out = total_outages(Visibility(t, n))
    assert len(out) == 2
    assert out[0] == pytest.approx((5.0, 6.0))
    assert out[1] == pytest.approx((27.0, 30.0))


@pytest.mark.parametrize("offset", [OFF, 0.0499, -0.03])
def test_canyon_availability_by_hand(offset):
    t = np.arange(0, 2500) * 0.01                               # 25 s of truth
    n = np.full(t.size, 6)
    n[(t >= 16.0) & (t < 18.0)] = 3                             # 20 epochs with < 4 visible
    vis = Visibility(t, n, random_window=(10.0, 20.0))
    ft = np.round(np.arange(0, 25, 0.1), 6) + offset
    ft = ft[ft >= 0]
    missing = (ft >= 12.0 + offset - 1e-9) & (ft < 13.0 + offset - 1e-9)    # 10 epochs without a fix
    coast = (ft >= 16.0) & (ft < 18.0)                          # coast fixes while < 4 visible
    err = np.where((ft >= 14.0) & (ft < 15.0), 8.0, 2.0)
    fx = Fixes(ft[~missing], err[~missing], coast[~missing])
    c = canyon_report(fx, vis, rate_hz=10.0)
    assert c["epochs"] in (99, 100)
    assert c["counted"] == c["epochs"] - 20
    assert c["available"] == c["counted"] - 10
    assert c["availability"] == pytest.approx((c["counted"] - 10) / c["counted"])
    # 3D RMS of the measured fixes in the window: 10 at 8 m, the rest at 2 m
    n_meas = c["epochs"] - 20 - 10
    assert c["rms_3d_m"] == pytest.approx(math.sqrt((10 * 64 + (n_meas - 10) * 4) / n_meas), rel=0.02)
    assert c["max_err_m"] == 8.0
    # coast fixes are not availability
    fx2 = Fixes(fx.t, fx.err, np.ones(fx.t.size, bool))
    assert canyon_report(fx2, vis, 10.0)["availability"] == 0.0
    assert canyon_report(fx, Visibility(t, n), 10.0) is None


# ------------------------------------------------------------------------------------------ files + CLI
def _files(tmp_path, outage=True):
    """Truth: static point, 40 s at 100 Hz, 5 satellites, total outage [10, 13) (if outage) and a random
    window [20, 40) with 3 satellites at 30-32 s; run: 10 Hz fixes, 3 m east, none during [10, 14)."""
    from receiver.gnss.geodesy import enu_matrix, lla2ecef
    lat, lon, h, week, t0 = 35.68, 139.77, 40.0, 2300, 345598.0
    ref = np.asarray(lla2ecef(lat, lon, h), float).reshape(3)
    t = np.arange(0, 4000) * 0.01
    truth, run = tmp_path / "x.truth.h5", tmp_path / "x.h5"
    with h5py.File(truth, "w") as f:
        f.attrs["gps_week"] = week
        g = f.create_group("receiver")
        g["time_s"], g["gps_tow"] = t, t0 + t
        g["ecef"], g["velocity_ecef"] = np.tile(ref, (t.size, 1)), np.zeros((t.size, 3))
        g["clock_bias_m"], g["clock_drift_mps"] = np.zeros(t.size), np.zeros(t.size)
        for i, p in enumerate((1, 7, 11, 14, 15)):
            v = np.ones(t.size, bool)
            if outage:
                v[(t >= 10.0) & (t < 13.0)] = False
            if i < 2:
                v[(t >= 30.0) & (t < 32.0)] = False
            v[(t >= 24.0) & (t < 24.5)] = False
            s = f.create_group(f"satellites/G{p:02d}")
            s["time_s"], s["visible"] = t, v
        b = f.create_group("blockage")
        b.attrs["random_start_s"], b.attrs["random_end_s"] = 20.0, 40.0
        rows = [(0, 10.0, 13.0, 1)] if outage else []
        rows += [(p, 24.0, 24.5, 2) for p in (1, 7, 11, 14, 15)]       # a coinciding random blockage
        b["prn"] = np.array([r[0] for r in rows], np.int32)
        b["start_s"] = np.array([r[1] for r in rows], float)
        b["end_s"] = np.array([r[2] for r in rows], float)
        b["kind"] = np.array([r[3] for r in rows], np.uint8)
    tf = np.round(np.arange(1.0, 40.0, 0.1), 6)
    tf = tf[(tf < 10.0) | (tf >= 14.0)]
    e = np.array([3.0, 0.0, 0.0]) @ enu_matrix(lat, lon)
    with h5py.File(run, "w") as f:
        f.attrs["config"] = "navigation:\n  rate_hz: 10.0\n"
        f.attrs["sample_rate_hz"], f.attrs["n_samples"] = 1.0e6, int(40e6)
        n = f.create_group("navigation")
        n["time_s"], n["gps_week"], n["gps_tow"] = tf, np.full(tf.size, week, np.int32), t0 + tf
        n["ecef"] = np.tile(ref + e, (tf.size, 1))
        n["velocity_ecef"] = np.zeros((tf.size, 3))
        n["mode"] = np.zeros(tf.size, np.uint8)
    return run, truth


def test_report_from_files_cli_and_batch_metrics(tmp_path):
    run, truth = _files(tmp_path)
    rep = report(run, truth)
    (o,) = rep["total"]["outages"]
    assert (o["start_s"], o["end_s"]) == pytest.approx((10.0, 13.0))
    assert o["ttgf_s"] == pytest.approx(1.0) and o["max_err_m"] == pytest.approx(3.0)
    assert rep["total"]["fixes_to_end"] is True
    c = rep["canyon"]
    # 2 s with 3 visible, 0.5 s with none: 25 epochs with < 4; the truth ends at 39.99 s
    assert c["epochs"] == 199 and c["counted"] == 199 - 25 and c["availability"] == 1.0
    assert c["rms_3d_m"] == pytest.approx(3.0)
    m = compute_metrics(run, truth)
    assert m["outage_n"] == 1.0 and m["outage1_ttgf_s"] == pytest.approx(1.0)
    assert m["canyon_availability"] == 1.0 and m["fixes_to_end"] == 1.0
    res = CliRunner().invoke(main, ["eval", str(run), str(truth), "--outages"])
    assert res.exit_code == 0, res.output
    assert "total outages" in res.output and "10.00-13.00" in res.output and "availability" in res.output
    res = CliRunner().invoke(main, ["eval", str(run), str(truth), "--json"])
    assert json.loads(res.output)["outages"]["total"]["outages"][0]["ttgf_s"] == pytest.approx(1.0)


def test_eval_outages_without_outages_is_a_user_error(tmp_path):
    run, truth = _files(tmp_path, outage=False)
    assert report(run, truth)["total"] is None             # the coinciding random blockage is no outage
    with h5py.File(truth, "a") as f:
        del f["blockage"]
        for g in f["satellites"].values():                   # no table, no dark spell: nothing to score
            v = g["visible"][:]
            v[(f["receiver/time_s"][:] >= 24.0) & (f["receiver/time_s"][:] < 24.5)] = True
            g["visible"][...] = v
    res = CliRunner().invoke(main, ["eval", str(run), str(truth), "--outages"])
    assert res.exit_code == 2
    assert "no total outage" in res.output and "Traceback" not in res.output
    res = CliRunner().invoke(main, ["eval", str(run), str(truth)])       # plain eval: no outage section
    assert res.exit_code == 0 and "total outages" not in res.output


def test_loss_report_latencies():
    """Blockages of >= 0.5 s of a satellite in lock: time to the first unlocked record and to the end of the
    track; a short blockage, one of a satellite not in lock and a track that never ends (vector) are handled."""
    tt = np.round(np.arange(0.0, 20.0, 0.01), 6)                 # truth at 100 Hz
    vis = {1: np.ones(tt.size, bool), 2: np.ones(tt.size, bool), 3: np.ones(tt.size, bool)}
    vis[1][(tt >= 5.0) & (tt < 7.0)] = False                    # G1: lock gone 0.04 s, track ends 0.10 s later
    vis[1][(tt >= 12.0) & (tt < 12.3)] = False                  # too short: not scored
    vis[2][(tt >= 8.0) & (tt < 9.0)] = False                    # G2: never loses its track (vector): lock 0.06 s
    vis[3][(tt >= 3.0) & (tt < 4.0)] = False                    # G3: not in lock before: not scored
    t = np.round(np.arange(0.0, 20.0, 0.02), 6)
    ok1 = ~((t >= 5.04) & (t < 7.2))
    keep1 = ~((t > 5.10) & (t < 7.2))
    ok2 = ~((t >= 8.06) & (t < 9.1))
    tracks = {1: (t[keep1], ok1[keep1]), 2: (t, ok2), 3: (t, np.zeros(t.size, bool))}
    r = loss_report(tracks, vis, tt)
    assert r["n"] == 2 and r["n_lost"] == 1
    assert r["lock_lag_mean_s"] == pytest.approx(0.05, abs=1e-6)
    assert r["lock_lag_max_s"] == pytest.approx(0.06, abs=1e-6)
    assert r["lost_lag_mean_s"] == pytest.approx(0.10, abs=1e-6)
    assert loss_report({}, vis, tt) is None
