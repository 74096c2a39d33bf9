"""Simulator propagation geometry: satellite orbits by Hermite interpolation, light time with Sagnac,
atmospheric delays, elevation/azimuth and range rate (the conventions are receiver.sim.simulate's)."""
from __future__ import annotations

import math

import numpy as np

from ..estimation.interpolation import hermite
from ..gnss.atmosphere import klobuchar_delay_s, saastamoinen_m
from ..gnss.ephemeris import earth_rotation, sat_state
from ..gnss.geodesy import ecef2lla
from ..gnss.signals import C_LIGHT, OMEGA_E


def enu_components(vec, lat_deg, lon_deg):
    """ENU components of ECEF vectors (N,3) at per-row geodetic lat/lon (deg)."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    x, y, z = vec[..., 0], vec[..., 1], vec[..., 2]
    e = -so * x + co * y
    n = -sl * co * x - sl * so * y + cl * z
    u = cl * co * x + cl * so * y + sl * z
    return e, n, u



class SatelliteTrack:
    """Satellite position, velocity and clock at TRUE GPS times, by cubic Hermite interpolation.

    :func:`receiver.gnss.ephemeris.sat_state` is evaluated at nodes ``step`` apart (true time; position,
    velocity, clock offset and drift at each node) covering [t_lo, t_hi]; between nodes the cubic Hermite
    interpolant of (value, derivative) is accurate to far below a micrometre for GPS orbits at
    step = 0.1 s (error ~ step^4 n^4 a / 384).
    """

    def __init__(self, eph, t_lo, t_hi, step=0.1):
        k0, k1 = math.floor(t_lo / step) - 1, math.ceil(t_hi / step) + 1
        self.t_lo, self.t_hi = (k0 + 1) * step, (k1 - 1) * step
        self.tn = np.arange(k1 - k0 + 1) * step + k0 * step
        clk = np.zeros_like(self.tn)
        for _ in range(2):               # sat_state takes satellite-clock time: t_sv = t + clk(t)
            pos, vel, clk, drift = sat_state(eph, self.tn + clk)
        self.pos, self.vel, self.clk, self.drift = pos, vel, clk, drift

    def covers(self, t_lo, t_hi):
        """True when the interpolation nodes span the true times [t_lo, t_hi] (s)."""
        return self.t_lo <= t_lo and t_hi <= self.t_hi

    def __call__(self, t, rates=True):
        """(pos (n,3), vel (n,3), clk (n,), clk_dot (n,)) at true times t (vel/clk_dot None without rates)."""
        pos = hermite(self.tn, self.pos, self.vel, t)
        clk = hermite(self.tn, self.clk, self.drift, t)
        if not rates:
            return pos, None, clk, None
        return (pos, hermite(self.tn, self.pos, self.vel, t, True), clk,
                hermite(self.tn, self.clk, self.drift, t, True))


def satellite_geometry(track, t_rx, rx_pos, rx_vel, lat_deg, lon_deg, h_m, iono, tropo, iono_scale=1.0):
    """Propagation quantities of one satellite at reception times t_rx (true GPS s of week, array).

    track: a :class:`SatelliteTrack` (or any callable t_true -> pos, vel, clk, clk_dot).
    Returns a dict of arrays: rho (m, geometric incl. Sagnac), rho_dot (m/s, d rho/dt), iono_m, tropo_m
    (group delays, m), clk (s, satellite clock offset incl. relativity - TGD), clk_dot, el, az (rad),
    tau (s, total code propagation time).  iono_scale: the Klobuchar delay is the model's times this factor
    ((f_ref / f)^2 for a signal on another frequency than the model's reference).
    """
    n = t_rx.size
    tau = np.full(n, 0.075)
    atm = np.zeros(n)
    iono_m = np.zeros(n)
    tropo_m = np.zeros(n)
    lat_r, lon_r = np.radians(lat_deg), np.radians(lon_deg)
    for it in range(4):
        pos, vel, clk, clk_dot = track(t_rx - tau, rates=it == 3)
        rot = earth_rotation(pos, tau)
        los = rot - rx_pos
        rho = np.sqrt(np.einsum("ij,ij->i", los, los))
        if it == 1:
            e, nn, u = enu_components(los, lat_deg, lon_deg)
            el_c = np.maximum(np.arctan2(u, np.hypot(e, nn)), 0.0)
            az = np.arctan2(e, nn) % (2 * np.pi)
            if iono is not None:
                iono_m = C_LIGHT * klobuchar_delay_s(iono, lat_r, lon_r, az, el_c, t_rx)
                if iono_scale != 1.0:
                    iono_m = iono_m * iono_scale
            if tropo:
                tropo_m = saastamoinen_m(lat_r, h_m, el_c)
            atm = iono_m + tropo_m
        if it < 3:
            tau = (rho + atm) / C_LIGHT
    e, nn, u = enu_components(los, lat_deg, lon_deg)
    el = np.arctan2(u, np.hypot(e, nn))
    az = np.arctan2(e, nn) % (2 * np.pi)
    # range rate: d/dt |R(w tau) r_sat(t - tau) - r_rx(t)|, with d tau/dt = rho_dot / c
    uvec = los / rho[:, None]
    vrot = earth_rotation(vel, tau)
    sag = OMEGA_E * np.stack([rot[:, 1], -rot[:, 0], np.zeros(n)], axis=1)
    num = np.einsum("ij,ij->i", uvec, vrot - rx_vel)
    den = 1.0 - np.einsum("ij,ij->i", uvec, sag - vrot) / C_LIGHT
    return {"rho": rho, "rho_dot": num / den, "iono_m": iono_m, "tropo_m": tropo_m, "clk": clk,
            "clk_dot": clk_dot, "el": el, "az": az, "tau": tau}


def scan_elevations(ephs, traj, t_ref_true, duration):
    """(t (s since the start), {prn: elevation (deg) at t}): coarse scan over the run, no light time."""
    step = 1.0 if duration <= 3600 else 10.0
    ts = np.append(np.arange(0.0, duration, step), duration)
    pos = traj.state(ts)[0]
    lat, lon, _ = ecef2lla(pos)
    out = {}
    for prn, eph in ephs.items():
        sp = sat_state(eph, t_ref_true + ts)[0]
        e, n, u = enu_components(earth_rotation(sp, 0.075) - pos, lat, lon)
        out[prn] = np.degrees(np.arctan2(u, np.hypot(e, n)))
    return ts, out

