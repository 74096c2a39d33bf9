"""WGS-84 coordinate conversions (ECEF, geodetic, local ENU, azimuth/elevation)."""
import math

import numpy as np

WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)


def lla2ecef(lat_deg, lon_deg, h_m):
    """Geodetic latitude/longitude (deg) and ellipsoidal height (m) to ECEF (m). Broadcasts."""
    lat = np.radians(lat_deg)
    lon = np.radians(lon_deg)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
    x = (n + h_m) * np.cos(lat) * np.cos(lon)
    y = (n + h_m) * np.cos(lat) * np.sin(lon)
    z = (n * (1.0 - WGS84_E2) + h_m) * np.sin(lat)
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1)


def ecef2lla(xyz):
    """ECEF (m, ...x3) to (lat_deg, lon_deg, h_m), iterative (mm-level in 5 iterations)."""
    xyz = np.asarray(xyz, dtype=float)
    if xyz.shape == (3,):
        return _ecef2lla_point(float(xyz[0]), float(xyz[1]), float(xyz[2]))
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    lat = np.arctan2(z, p * (1.0 - WGS84_E2))
    h = np.zeros_like(p)
    for _ in range(8):
        n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
        h = np.where(np.abs(np.cos(lat)) > 1e-9, p / np.maximum(np.cos(lat), 1e-12) - n,
                     np.abs(z) - n * (1 - WGS84_E2))
        lat = np.arctan2(z, p * (1.0 - WGS84_E2 * n / (n + h)))
    return np.degrees(lat), np.degrees(lon), h


def _ecef2lla_point(x: float, y: float, z: float):
    """:func:`ecef2lla` of one point with the math module (the same iteration; numpy's per-call overhead on
    scalars made one conversion cost ~0.2 ms, and the navigation converts every fix and satellite)."""
    p = math.hypot(x, y)
    lon = math.atan2(y, x)
    lat = math.atan2(z, p * (1.0 - WGS84_E2))
    h = 0.0
    for _ in range(8):
        n = WGS84_A / math.sqrt(1.0 - WGS84_E2 * math.sin(lat) ** 2)
        c = math.cos(lat)
        h = p / max(c, 1e-12) - n if abs(c) > 1e-9 else abs(z) - n * (1 - WGS84_E2)
        lat = math.atan2(z, p * (1.0 - WGS84_E2 * n / (n + h)))
    return np.float64(math.degrees(lat)), np.float64(math.degrees(lon)), np.float64(h)


def enu_matrix(lat_deg, lon_deg):
    """Rotation matrix whose rows are the local East, North, Up unit vectors in ECEF."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.array([[-so, co, 0.0],
                     [-sl * co, -sl * so, cl],
                     [cl * co, cl * so, sl]])


def ecef2enu(xyz, ref_xyz):
    """ECEF points (..., 3) to local ENU (m) about ref_xyz."""
    lat, lon, _ = ecef2lla(ref_xyz)
    return (np.asarray(xyz, float) - np.asarray(ref_xyz, float)) @ enu_matrix(lat, lon).T


def azel(rx_xyz, sat_xyz):
    """Azimuth and elevation (rad) of satellites (..., 3) seen from rx_xyz."""
    enu = ecef2enu(sat_xyz, rx_xyz)
    e, n, u = enu[..., 0], enu[..., 1], enu[..., 2]
    az = np.arctan2(e, n) % (2 * np.pi)
    el = np.arctan2(u, np.hypot(e, n))
    return az, el
