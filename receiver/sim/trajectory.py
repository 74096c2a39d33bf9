"""Receiver trajectories: position, velocity and acceleration (ECEF) as smooth functions of time.

Every trajectory is evaluated at arbitrary times ``t`` (true GPS time in seconds since the first sample,
numpy array) and returns ``(pos, vel, acc)`` arrays of shape (len(t), 3) in ECEF metres, m/s, m/s^2.
Velocity is the exact derivative of position and acceleration the exact derivative of velocity for every
kind (analytic formulas, or the derivatives of one cubic spline for CSV input).

Kinds (``receiver.trajectory``):
  static             fixed at lat/lon/height
  constant_velocity  straight line in ECEF from lat/lon/height with an ENU velocity given at the start
  segments           piecewise constant acceleration and jerk in the local tangent plane (ENU at the start
                     point); after the last segment the receiver coasts at constant velocity
  figure8            horizontal lemniscate of Gerono in the tangent plane at lat/lon/height, starting at
                     its centre at peak speed: x = A sin(wt) along the heading, y = (A/2) sin(2wt),
                     A = size/2, peak speed A w sqrt(2) (reached at the centre)
  csv                rows of time,x,y,z (ECEF) or time,lat,lon,h; a C2 cubic spline through the ECEF points
"""
from __future__ import annotations

import math
import os

import numpy as np

from ..errors import UserError
from ..suggest import did_you_mean
from ..gnss.geodesy import enu_matrix, lla2ecef

TRAJECTORY_KINDS = ("static", "constant_velocity", "segments", "figure8", "csv")


class Trajectory:
    """Base class: subclasses implement :meth:`state`."""
    kind = "base"

    def state(self, t):
        """(pos, vel, acc) at times ``t`` (s since the first sample, scalar or array): ECEF arrays of shape
        (len(t), 3) in m, m/s, m/s^2."""
        raise NotImplementedError

    def position(self, t):
        """ECEF position (m), shape (len(t), 3), at times ``t`` (s since the first sample)."""
        return self.state(t)[0]


class _TangentPlane(Trajectory):
    """Motion defined in the ENU tangent plane at a reference point, mapped linearly to ECEF."""

    def __init__(self, lat_deg, lon_deg, h_m):
        self.ref = lla2ecef(lat_deg, lon_deg, h_m).astype(float)
        self.rot = enu_matrix(lat_deg, lon_deg)        # rows E, N, U in ECEF

    def _enu_state(self, t):
        raise NotImplementedError

    def state(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        p, v, a = self._enu_state(t)
        return self.ref + p @ self.rot, v @ self.rot, a @ self.rot


class Static(_TangentPlane):
    """Fixed at lat/lon/height: velocity and acceleration zero."""
    kind = "static"

    def _enu_state(self, t):
        z = np.zeros((t.size, 3))
        return z, z.copy(), z.copy()


class ConstantVelocity(_TangentPlane):
    """Straight line in ECEF from lat/lon/height at a constant velocity given in ENU (m/s) at the start
    point; acceleration zero."""
    kind = "constant_velocity"

    def __init__(self, lat_deg, lon_deg, h_m, velocity_enu):
        super().__init__(lat_deg, lon_deg, h_m)
        self.v = np.asarray(velocity_enu, dtype=float).reshape(3)

    def _enu_state(self, t):
        p = t[:, None] * self.v
        return p, np.broadcast_to(self.v, p.shape).copy(), np.zeros_like(p)


class Segments(_TangentPlane):
    """Piecewise constant acceleration (and jerk): a(tau) = accel + jerk * tau within each segment."""
    kind = "segments"

    def __init__(self, lat_deg, lon_deg, h_m, velocity_enu, segments):
        super().__init__(lat_deg, lon_deg, h_m)
        starts, p0, v0, a0, jk = [], [], [], [], []
        t, p, v = 0.0, np.zeros(3), np.asarray(velocity_enu, dtype=float).reshape(3)
        for seg in segments:
            d, a, j = seg["duration_s"], seg["accel"], seg["jerk"]
            starts.append(t)
            p0.append(p.copy())
            v0.append(v.copy())
            a0.append(a)
            jk.append(j)
            p = p + v * d + a * d * d / 2.0 + j * d ** 3 / 6.0
            v = v + a * d + j * d * d / 2.0
            t += d
        starts.append(t)                       # coasting after the last segment
        p0.append(p)
        v0.append(v)
        a0.append(np.zeros(3))
        jk.append(np.zeros(3))
        self.t0 = np.array(starts)
        self.p0, self.v0 = np.array(p0), np.array(v0)
        self.a0, self.j = np.array(a0), np.array(jk)

    def _enu_state(self, t):
        k = np.clip(np.searchsorted(self.t0, t, side="right") - 1, 0, len(self.t0) - 1)
        tau = (t - self.t0[k])[:, None]
        a0, j = self.a0[k], self.j[k]
        p = self.p0[k] + self.v0[k] * tau + a0 * tau ** 2 / 2.0 + j * tau ** 3 / 6.0
        v = self.v0[k] + a0 * tau + j * tau ** 2 / 2.0
        a = a0 + j * tau
        return p, v, a


class FigureEight(_TangentPlane):
    """Horizontal lemniscate of Gerono centred on the reference point."""
    kind = "figure8"

    def __init__(self, lat_deg, lon_deg, h_m, size_m, peak_speed_mps, heading_deg):
        super().__init__(lat_deg, lon_deg, h_m)
        self.amp = size_m / 2.0
        self.w = peak_speed_mps / (self.amp * math.sqrt(2.0))
        h = math.radians(heading_deg)
        self.major = np.array([math.sin(h), math.cos(h), 0.0])     # along the heading (E, N)
        self.minor = np.array([math.cos(h), -math.sin(h), 0.0])

    def _enu_state(self, t):
        A, w = self.amp, self.w
        th = w * t
        s1, c1, s2, c2 = np.sin(th), np.cos(th), np.sin(2 * th), np.cos(2 * th)
        x, xd, xdd = A * s1, A * w * c1, -A * w * w * s1
        y, yd, ydd = A / 2 * s2, A * w * c2, -2 * A * w * w * s2
        mj, mn = self.major, self.minor
        p = x[:, None] * mj + y[:, None] * mn
        v = xd[:, None] * mj + yd[:, None] * mn
        a = xdd[:, None] * mj + ydd[:, None] * mn
        return p, v, a


class CsvTrajectory(Trajectory):
    """Cubic spline through ECEF points read from a CSV file (time in seconds since the first sample)."""
    kind = "csv"

    def __init__(self, times, ecef, path="<csv>"):
        from scipy.interpolate import CubicSpline
        times = np.asarray(times, dtype=float)
        ecef = np.asarray(ecef, dtype=float)
        if times.size < 4:
            raise UserError(f"trajectory CSV {path} needs at least 4 rows")
        if np.any(np.diff(times) <= 0):
            raise UserError(f"trajectory CSV {path}: times must be strictly increasing")
        self.t_first, self.t_last = float(times[0]), float(times[-1])
        self.spline = CubicSpline(times, ecef, axis=0)
        self.d1 = self.spline.derivative(1)
        self.d2 = self.spline.derivative(2)

    def state(self, t):
        """(pos, vel, acc) of the spline and its first two derivatives at ``t`` (s): ECEF, m, m/s, m/s^2;
        outside the CSV's time span the end polynomials are extrapolated."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self.spline(t), self.d1(t), self.d2(t)


def read_csv_trajectory(path, columns: str = "ecef", time_offset_s: float = 0.0) -> CsvTrajectory:
    """CSV rows time,x,y,z (columns='ecef') or time,lat_deg,lon_deg,h_m (columns='lla').

    A header line (non-numeric) and '#' comments are skipped. ``time_offset_s`` is subtracted from the
    time column (to turn GPS time of week into seconds since the first sample).
    """
    if not os.path.isfile(path):
        raise UserError(f"trajectory CSV not found: {path}")
    from ..config import read_utf8
    rows = []
    for lineno, line in enumerate(read_utf8(path, "trajectory CSV").splitlines(), 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        parts = [p for p in text.replace(";", ",").replace("\t", ",").split(",")]
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            if not rows:            # header
                continue
            raise UserError(f"trajectory CSV {path} line {lineno}: not numbers") from None
        if len(vals) < 4:
            raise UserError(f"trajectory CSV {path} line {lineno}: expected 4 columns "
                            f"(time and 3 coordinates), got {len(vals)}")
        rows.append(vals[:4])
    arr = np.array(rows, dtype=float).reshape(-1, 4)
    t = arr[:, 0] - time_offset_s
    xyz = arr[:, 1:] if columns == "ecef" else lla2ecef(arr[:, 1], arr[:, 2], arr[:, 3])
    return CsvTrajectory(t, xyz, path)


def _vec3(value, key):
    if value is None:
        return np.zeros(3)
    try:
        arr = np.asarray(value, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise UserError(f"config key '{key}' must be a list of 3 numbers (E, N, U), got {value!r}") from None
    if not np.all(np.isfinite(arr)):
        raise UserError(f"config key '{key}' must be finite")
    return arr


def _segments(raw):
    out = []
    if not isinstance(raw, list):
        raise UserError("config key 'receiver.segments' must be a list")
    for i, seg in enumerate(raw):
        key = f"receiver.segments[{i}]"
        if not isinstance(seg, dict):
            raise UserError(f"config key '{key}' must be a mapping with duration_s, accel_enu_mps2, "
                            "jerk_enu_mps3")
        unknown = set(seg) - {"duration_s", "accel_enu_mps2", "jerk_enu_mps3"}
        if unknown:
            raise UserError(f"unknown config key '{key}.{sorted(unknown)[0]}'"
                            + did_you_mean(sorted(unknown)[0], ("duration_s", "accel_enu_mps2", "jerk_enu_mps3")))
        d = seg.get("duration_s")
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not d > 0:
            raise UserError(f"config key '{key}.duration_s' must be a positive number")
        out.append({"duration_s": float(d),
                    "accel": _vec3(seg.get("accel_enu_mps2"), key + ".accel_enu_mps2"),
                    "jerk": _vec3(seg.get("jerk_enu_mps3"), key + ".jerk_enu_mps3")})
    return out


def make_trajectory(rx, resolve_path=lambda p: p, start_true_tow: float = 0.0) -> Trajectory:
    """Build the trajectory of a scenario's ``receiver`` section."""
    kind = rx.trajectory
    lat, lon, h = rx.lat_deg, rx.lon_deg, rx.height_m
    if kind == "static":
        return Static(lat, lon, h)
    if kind == "constant_velocity":
        return ConstantVelocity(lat, lon, h, _vec3(rx.velocity_enu_mps, "receiver.velocity_enu_mps"))
    if kind == "segments":
        return Segments(lat, lon, h, _vec3(rx.velocity_enu_mps, "receiver.velocity_enu_mps"),
                        _segments(rx.segments))
    if kind == "figure8":
        f8 = rx.figure8
        return FigureEight(lat, lon, h, f8.size_m, f8.peak_speed_mps, f8.heading_deg)
    if kind == "csv":
        c = rx.csv
        if not c.path:
            raise UserError("receiver.trajectory is 'csv' but receiver.csv.path is empty")
        offset = start_true_tow if c.time == "gps_tow" else 0.0
        return read_csv_trajectory(resolve_path(c.path), c.columns, offset)
    raise UserError(f"unknown trajectory kind '{kind}'")
