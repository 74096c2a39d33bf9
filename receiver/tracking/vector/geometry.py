"""Satellite geometry for the vector loop, refreshed once per chunk.

For every vector channel the satellite position at transmission, rotated into the ECEF frame at reception
(Sagnac), and the satellite clock term c dt_sv are evaluated at three receiver times spanning the chunk and
fitted by quadratics in receiver time; the compiled epoch loop evaluates them (and their derivatives, the
effective satellite velocity and clock drift seen by a receiver clocking with the sample counter) every
epoch.  Over 0.6 s the neglected cubic term of a GPS orbit is below a micrometre.  The ionospheric and
tropospheric delays (the same models and switches as the navigation solution) are taken constant over the
chunk.
"""
from __future__ import annotations

import numpy as np

from ...gnss.geodesy import azel, ecef2lla
from ...gnss.atmosphere import klobuchar_delay_s, saastamoinen_m
from ...gnss.ephemeris import earth_rotation, sat_state
from ...gnss.signals import C_LIGHT, L1_HZ


def transmit_state(ephs, t_gps, rx_pos, delay_m=None, iterations=3, start=None):
    """Satellite positions (rotated into the reception frame) and c*dt_sv for receptions at GPS times.

    ephs: list of n Ephemeris; t_gps: (n,) true GPS reception times; rx_pos (3,) or (n, 3).
    ``start``: (travel (n,) s, cclk (n,) m) of a nearby solution to iterate from (each light-time
    iteration shrinks the error by ~v_sat / c, so one iteration from a solution 1 us off is exact).
    Returns (pos (n, 3), cclk (n,), travel (n,) s).
    """
    t_gps = np.asarray(t_gps, dtype=float)
    rx = np.broadcast_to(np.asarray(rx_pos, dtype=float), (len(ephs), 3))
    delay = np.zeros(len(ephs)) if delay_m is None else np.asarray(delay_m, dtype=float)
    if start is None:
        travel = np.full(len(ephs), 0.075)
        clk = np.zeros(len(ephs))
    else:
        travel = np.array(start[0], dtype=float)
        clk = np.asarray(start[1], dtype=float) / C_LIGHT
    for _ in range(iterations):
        pos, _, clk, _ = sat_state(ephs, t_gps - travel + clk)
        rot = earth_rotation(pos, travel)
        travel = (np.linalg.norm(rot - rx, axis=1) + delay) / C_LIGHT
    pos, _, clk, _ = sat_state(ephs, t_gps - travel + clk)
    rot = earth_rotation(pos, travel)
    return rot, C_LIGHT * clk, travel


def atmosphere_m(rx_pos, sat_pos, t_gps, iono_utc, nav_cfg, carrier_hz=None):
    """(iono + tropo delay (m), azimuth, elevation (rad)) per satellite, navigation-solution models.
    carrier_hz (per satellite, None: the model's own carrier): the Klobuchar delay, given on the model's
    reference carrier (GPS set L1, BeiDou set B1I), is scaled by (f_ref / f)^2 as in the navigation solution."""
    az, el = azel(rx_pos, sat_pos)
    lat, lon, h = ecef2lla(rx_pos)
    delay = np.zeros(len(el))
    el_m = np.maximum(el, np.radians(2.0))
    if getattr(nav_cfg, "ionosphere", "klobuchar") == "klobuchar" and iono_utc is not None:
        iono = C_LIGHT * klobuchar_delay_s(iono_utc, np.radians(lat), np.radians(lon), az, el_m, t_gps)
        if carrier_hz is not None:
            ratio = (float(getattr(iono_utc, "ref_hz", L1_HZ)) / np.asarray(carrier_hz, dtype=float)) ** 2
            if np.any(ratio != 1.0):
                iono = iono * ratio
        delay += iono
    if getattr(nav_cfg, "troposphere", "saastamoinen") == "saastamoinen" and -1000.0 < h < 50e3:
        delay += saastamoinen_m(np.radians(lat), h, el_m)
    return delay, az, el


def satellite_polys(ephs, t_ref, tau_a, h, b_m, drift_mps, rx_pos, iono_utc, nav_cfg, carrier_hz=None):
    """Quadratic fits of the satellites' reception-frame position and clock term in receiver time.

    ephs: list of m Ephemeris (GPS/QZSS LNAV or BeiDou, GEO included: receiver.gnss.ephemeris.sat_state takes
    GPS time for all); carrier_hz: per satellite, its signal's carrier (ionosphere, see atmosphere_m);
    receiver time tau (s) is relative to t_ref (receiver clock reading at tau 0);
    the fit nodes are tau_a, tau_a + h, tau_a + 2 h; the true reception time of receiver time tau is
    t_ref + tau - (b_m + drift_mps (tau - tau_a)) / c.  Returns (POLY (m, 3, 4): coefficients of
    1, (tau - tau_a), (tau - tau_a)^2 for x, y, z, c dt_sv;  ATM (m,) delay in metres; EL (m,) rad).
    """
    m = len(ephs)
    poly = np.zeros((m, 3, 4))
    if m == 0:
        return poly, np.zeros(0), np.zeros(0)
    nodes = tau_a + h * np.arange(3)
    t_gps = t_ref + nodes - (b_m + drift_mps * (nodes - tau_a)) / C_LIGHT
    eph3 = list(ephs) * 3
    tg = np.repeat(t_gps, m)
    # the positions for the atmosphere (elevations) need no converged light time (one iteration: mm);
    # the fit's then start from that solution (off by the delay / c, < 1 us: one iteration is exact)
    pos, cclk, travel = transmit_state(eph3, tg, rx_pos, iterations=1)
    delay, _, el = atmosphere_m(rx_pos, pos[m:2 * m], float(t_gps[1]), iono_utc, nav_cfg, carrier_hz)
    pos, cclk, _ = transmit_state(eph3, tg, rx_pos, np.tile(delay, 3), iterations=1, start=(travel, cclk))
    y = np.concatenate([pos, cclk[:, None]], axis=1).reshape(3, m, 4)
    poly[:, 0] = y[0]
    poly[:, 1] = (-3.0 * y[0] + 4.0 * y[1] - y[2]) / (2.0 * h)
    poly[:, 2] = (y[0] - 2.0 * y[1] + y[2]) / (2.0 * h * h)
    return poly, delay, el
