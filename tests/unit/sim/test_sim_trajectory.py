"""Trajectories: velocity = d position / dt, acceleration = d velocity / dt, for every kind."""
import numpy as np
import pytest

from receiver.config import build
from receiver.errors import UserError
from receiver.gnss.geodesy import ecef2enu, lla2ecef
from receiver.sim.scenario import SCENARIO_SCHEMA
from receiver.sim.trajectory import make_trajectory


def _traj(rx, tmp_path=None):
    sc = build(SCENARIO_SCHEMA, {"receiver": rx})
    return make_trajectory(sc.receiver, lambda p: p)


def _check_derivatives(traj, t0=0.3, t1=119.7, h=1e-3, tol_v=1e-6, tol_a=1e-5):
    t = np.linspace(t0, t1, 397)
    p, v, a = traj.state(t)
    pp, vp, _ = traj.state(t + h)
    pm, vm, _ = traj.state(t - h)
    scale_v = max(1.0, float(np.max(np.abs(v))))
    scale_a = max(1.0, float(np.max(np.abs(a))))
    assert np.max(np.abs((pp - pm) / (2 * h) - v)) < tol_v * scale_v * 1e3
    assert np.max(np.abs((vp - vm) / (2 * h) - a)) < tol_a * scale_a * 1e3
    return p, v, a


def test_static():
    tr = _traj({"trajectory": "static", "lat_deg": 10.0, "lon_deg": 20.0, "height_m": 30.0})
    p, v, a = _check_derivatives(tr)
    assert np.allclose(p, lla2ecef(10.0, 20.0, 30.0)) and not v.any() and not a.any()


def test_constant_velocity():
    tr = _traj({"trajectory": "constant_velocity", "velocity_enu_mps": [3.0, -4.0, 0.5]})
    p, v, a = _check_derivatives(tr)
    enu = ecef2enu(p[-1], p[0])
    assert np.allclose(np.linalg.norm(v, axis=1), np.sqrt(9 + 16 + 0.25))
    assert np.allclose(enu / np.linalg.norm(enu), np.array([3, -4, 0.5]) / np.sqrt(25.25), atol=1e-9)


def test_segments_with_jerk():
    segs = [{"duration_s": 10.0, "accel_enu_mps2": [1.0, 0.0, 0.0]},
            {"duration_s": 5.0, "jerk_enu_mps3": [0.0, 0.4, 0.0]},
            {"duration_s": 20.0, "accel_enu_mps2": [-0.5, 0.0, 0.1], "jerk_enu_mps3": [0.0, 0.0, -0.01]}]
    tr = _traj({"trajectory": "segments", "velocity_enu_mps": [0.0, 2.0, 0.0], "segments": segs})
    # derivatives inside segments (away from the acceleration steps at 10, 15 and 35 s)
    for t0, t1 in ((0.1, 9.9), (10.1, 14.9), (15.1, 34.9), (35.1, 60.0)):
        _check_derivatives(tr, t0, t1)
    # continuity of position and velocity across the segment boundaries, and the states themselves
    for tb in (10.0, 15.0, 35.0):
        p, v, _ = tr.state(np.array([tb - 1e-7, tb + 1e-7]))
        assert np.allclose(p[0], p[1], atol=1e-5) and np.allclose(v[0], v[1], atol=1e-5)
    ref = tr.state(0.0)[0][0]
    _, v, a = tr.state(np.array([12.0]))
    from receiver.gnss.geodesy import enu_matrix, ecef2lla
    lat, lon, _ = ecef2lla(ref)
    r = enu_matrix(lat, lon)
    assert np.allclose(r @ v[0], [10.0, 2.0 + 0.4 * 2 ** 2 / 2, 0.0], atol=1e-9)
    assert np.allclose(r @ a[0], [0.0, 0.8, 0.0], atol=1e-9)
    _, v, a = tr.state(np.array([100.0]))          # coasting after the last segment
    assert not np.any(np.abs(a) > 1e-12)


def test_figure_eight_peak_speed_and_shape():
    tr = _traj({"trajectory": "figure8", "figure8": {"size_m": 300.0, "peak_speed_mps": 15.0,
                                                     "heading_deg": 30.0}})
    p, v, a = _check_derivatives(tr, 0.0, 200.0)
    t = np.linspace(0, 200, 20001)
    p, v, _ = tr.state(t)
    speed = np.linalg.norm(v, axis=1)
    assert abs(speed.max() - 15.0) < 1e-6 and abs(speed[0] - 15.0) < 1e-9
    enu = ecef2enu(p, p[0])
    along = enu[:, 0] * np.sin(np.radians(30)) + enu[:, 1] * np.cos(np.radians(30))
    assert abs(along.max() - along.min() - 300.0) < 0.5
    assert np.max(np.abs(enu[:, 2])) < 0.01                           # horizontal (tangent plane)


@pytest.mark.parametrize("columns", ["ecef", "lla"])
def test_csv_spline(tmp_path, columns):
    t = np.arange(0.0, 130.0, 1.0)
    e, n = 50 * np.sin(0.05 * t), 30 * np.cos(0.03 * t)
    ref = lla2ecef(35.0, 139.0, 20.0)
    from receiver.gnss.geodesy import enu_matrix, ecef2lla
    xyz = ref + np.stack([e, n, 0.1 * t], axis=1) @ enu_matrix(35.0, 139.0)
    path = tmp_path / "traj.csv"
    if columns == "ecef":
        rows = np.column_stack([t, xyz])
        header = "time,x,y,z"
    else:
        lat, lon, h = ecef2lla(xyz)
        rows = np.column_stack([t, lat, lon, h])
        header = "time,lat,lon,h"
    np.savetxt(path, rows, delimiter=",", header=header, comments="", fmt="%.10f")
    tr = _traj({"trajectory": "csv", "csv": {"path": str(path), "columns": columns}})
    p, _, _ = _check_derivatives(tr, 1.0, 120.0)
    pk, _, _ = tr.state(t[5:-5])
    assert np.max(np.abs(pk - xyz[5:-5])) < 1e-3                      # passes through the points


def test_csv_errors(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,x,y,z\n0,1,2,3\n1,1,2,3\n")
    with pytest.raises(UserError, match="at least 4 rows"):
        _traj({"trajectory": "csv", "csv": {"path": str(path)}})
    with pytest.raises(UserError, match="receiver.segments\\[0\\].duration_s"):
        _traj({"trajectory": "segments", "segments": [{"duration_s": -1}]})
