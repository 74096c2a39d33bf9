"""Scenario layer over GPS-SDR-SIM: antenna trajectories at places and times of 2022-01-01.

A scenario is a mapping (all keys optional but ``dynamics``)::

    dynamics: static | walk | drive | circle | figure8 | highg     (DYNAMICS below)
    place: tokyo | ... (PLACES) or [lat_deg, lon_deg, height_m]
    start: "02:00:00"       GPS time of day on 2022-01-01 (the span of ../shared/data/brdc0010.22n:
                            00:00 .. 22:00; GPS-SDR-SIM floors it to a whole second)
    duration_s: 20          at most 399.9 s (GPS-SDR-SIM's motion-file limit)
    heading_deg: 0          initial heading (clockwise from north)
    speed_mps, radius_m, size_m: override the dynamics' defaults

:func:`trajectory_rows` returns the ECEF antenna positions at 10 Hz (row k at t0 + 0.1 k): exactly what
GPS-SDR-SIM is given (``-u``), so they are the truth the runs are scored against (GPS-SDR-SIM interpolates
ranges linearly between rows).  Kinematic dynamics are integrated in the local tangent plane at the place
at 100 Hz from (duration, along-track acceleration, turn rate) legs; the figure-eight is
:class:`receiver.sim.trajectory.FigureEight`.

DYNAMICS (defaults):
  static   fixed antenna
  walk     1.4 m/s, a 90 deg turn (30 deg/s) every 10 s
  drive    from rest: 2.5 m/s^2 to 15 m/s, cruise, 90 deg turns of 9 deg/s (2.4 m/s^2 lateral), braking
           to a 3-s stop; repeated (a 33-s cycle at 15 m/s)
  circle   constant speed (8 m/s) on a circle of radius 20 m (3.2 m/s^2)
  figure8  lemniscate of Gerono, peak speed 50 m/s, size 1000 m (~5 m/s^2 peak)
  highg    circle at 50 m/s, radius 64 m (39 m/s^2 = 4 g)
"""
from __future__ import annotations

import math

import numpy as np

from ..gnss.geodesy import enu_matrix, lla2ecef
from ..sim.trajectory import FigureEight

DATE = "2022/01/01"
GPS_WEEK = 2190
WEEK_START_TOW = 518400.0          # 2022-01-01 00:00:00 GPS time is Saturday 00:00 of week 2190

#: name -> (lat_deg, lon_deg, height_m)
PLACES = {
    "tokyo": (35.681298, 139.766247, 10.0),
    "sydney": (-33.8688, 151.2093, 40.0),
    "munich": (48.1374, 11.5755, 520.0),
    "saopaulo": (-23.5505, -46.6333, 760.0),
    "boulder": (40.0150, -105.2705, 1655.0),
    "nairobi": (-1.2921, 36.8219, 1795.0),
    "reykjavik": (64.1466, -21.9426, 30.0),
    "capetown": (-33.9249, 18.4241, 15.0),
}
#: starting times of day used by the seeds (rows rotate through them)
TIMES = ("02:00:00", "05:17:00", "08:41:30", "11:23:00", "14:06:00", "16:52:00", "19:34:00", "21:10:00")

DYNAMICS = ("static", "walk", "drive", "circle", "figure8", "highg")
_DEFAULTS = {
    "walk": {"speed_mps": 1.4},
    "drive": {"speed_mps": 15.0},
    "circle": {"speed_mps": 8.0, "radius_m": 20.0},
    "figure8": {"speed_mps": 50.0, "size_m": 1000.0},
    "highg": {"speed_mps": 50.0, "radius_m": 64.0},
}
_DT = 0.01


def place_lla(place):
    """(lat_deg, lon_deg, height_m) of a place name or a [lat, lon, h] triple."""
    if isinstance(place, str):
        if place not in PLACES:
            raise ValueError(f"unknown place '{place}' (one of {', '.join(PLACES)})")
        return PLACES[place]
    lat, lon, h = (float(v) for v in place)
    return lat, lon, h


def start_tow(start: str) -> float:
    """GPS time of week of the scenario start ('hh:mm:ss' on 2022-01-01)."""
    hh, mm, ss = start.split(":")
    return WEEK_START_TOW + int(hh) * 3600 + int(mm) * 60 + math.floor(float(ss))


def _legs(kind, p, duration):
    """[(duration_s, accel_mps2, yaw_rate_dps)] and the initial speed of a kinematic dynamics."""
    if kind == "walk":
        cyc = [(7.0, 0.0, 0.0), (3.0, 0.0, 30.0)]
        return cyc * int(duration // 10 + 1), p["speed_mps"]
    if kind == "drive":
        v = p["speed_mps"]
        ta = v / 2.5
        cyc = [(ta, 2.5, 0.0), (4.0, 0.0, 0.0), (10.0, 0.0, 9.0), (4.0, 0.0, 0.0), (ta, -2.5, 0.0),
               (3.0, 0.0, 0.0)]
        n = int(duration // sum(c[0] for c in cyc) + 1)
        return cyc * n, 0.0
    if kind in ("circle", "highg"):
        v = p["speed_mps"]
        return [(duration + 1.0, 0.0, math.degrees(v / p["radius_m"]))], v
    raise ValueError(kind)


def _integrate(legs, v0, heading_deg, duration):
    """ENU positions at 10 Hz of the kinematic legs (midpoint integration at 100 Hz)."""
    n = int(round(duration / _DT)) + 1
    acc = np.zeros(n)
    yaw = np.zeros(n)
    t = 0.0
    for d, a, w in legs:
        i0, i1 = int(round(t / _DT)), min(n, int(round((t + d) / _DT)))
        acc[i0:i1] = a
        yaw[i0:i1] = math.radians(w)
        t += d
        if i1 >= n:
            break
    v = np.empty(n)
    v[0] = v0
    v[1:] = np.maximum(v0 + np.cumsum(acc[:-1]) * _DT, 0.0)
    h = math.radians(heading_deg) + np.concatenate(([0.0], np.cumsum(yaw[:-1]) * _DT))
    vm = 0.5 * (v[1:] + v[:-1])
    hm = 0.5 * (h[1:] + h[:-1])
    e = np.concatenate(([0.0], np.cumsum(vm * np.sin(hm)) * _DT))
    nn = np.concatenate(([0.0], np.cumsum(vm * np.cos(hm)) * _DT))
    step = int(round(0.1 / _DT))
    return np.stack([e[::step], nn[::step], np.zeros(e[::step].size)], axis=1)


def trajectory_rows(scn: dict) -> np.ndarray:
    """ECEF antenna positions (rows at 10 Hz, duration_s * 10 + 1 of them) of a scenario mapping."""
    kind = scn["dynamics"]
    if kind not in DYNAMICS:
        raise ValueError(f"unknown dynamics '{kind}' (one of {', '.join(DYNAMICS)})")
    lat, lon, h = place_lla(scn.get("place", "tokyo"))
    dur = float(scn.get("duration_s", 20.0))
    rows = int(round(dur * 10)) + 1
    p = dict(_DEFAULTS.get(kind, {}))
    p.update({k: float(scn[k]) for k in ("speed_mps", "radius_m", "size_m") if k in scn})
    heading = float(scn.get("heading_deg", 0.0))
    ref = lla2ecef(lat, lon, h).astype(float)
    if kind == "static":
        return np.repeat(ref[None, :], rows, axis=0)
    if kind == "figure8":
        t = np.arange(rows) / 10.0
        return FigureEight(lat, lon, h, p["size_m"], p["speed_mps"], heading).state(t)[0]
    legs, v0 = _legs(kind, p, dur)
    enu = _integrate(legs, v0, heading, dur)[:rows]
    return ref + enu @ enu_matrix(lat, lon)


def seed_scenario(scn: dict, k: int) -> dict:
    """Seed ``k`` (0, 1, 2 ...) of a matrix row: a place and time of day rotated by k (unless the row fixes
    them), and a heading."""
    out = dict(scn)
    names = list(PLACES)
    off = int(scn.get("rotate", 0))
    if "place" not in scn:
        out["place"] = names[(off + 3 * k) % len(names)]
    if "start" not in scn:
        out["start"] = TIMES[(off + 5 * k) % len(TIMES)]
    out.setdefault("heading_deg", (37.0 * k + 11.0 * off) % 360.0)
    out.pop("rotate", None)
    return out
