"""Compiled satellite states of one epoch's GPS/QZSS ephemerides (the navigation solver's hot path).

:func:`sat_states` is :func:`receiver.gnss.ephemeris.sat_state` for a list of n LNAV ephemerides and n
transmit times, the same operations in the same order (the Kepler iteration runs in lock step over the
satellites until every step is below 1e-15, as the numpy version does), compiled: the numpy version
spends ~1 ms per epoch in per-call overhead on 12-element arrays.  Results agree with it to the last
bits (tests/unit/gnss/test_gnss_ephemeris_jit.py).  The compiled function is self-contained (it calls no compiled
function of another module, and its constants are written here), so numba's on-disk cache, keyed on this
file, cannot go stale.
"""
from __future__ import annotations

import numpy as np
from numba import njit

# The constants as literals: numba freezes globals into the cached machine code without tracking the module
# they came from, so they live in this file (tests/unit/gnss/test_gnss_ephemeris_jit.py checks them against
# receiver.gnss.signals).
OMEGA_E = 7.2921151467e-5        # Earth rotation rate, rad/s (WGS-84)
MU_GPS = 3.986005e14             # Earth's gravitational constant, m^3/s^2 (IS-GPS-200)
F_REL = -4.442807633e-10         # relativistic clock constant, s/sqrt(m)

#: the columns of the parameter matrix (one row per ephemeris)
FIELDS = ("toe", "toc", "af0", "af1", "af2", "tgd", "sqrt_a", "e", "i0", "omega0", "omega",
          "m0", "delta_n", "idot", "omega_dot", "cuc", "cus", "crc", "crs", "cic", "cis")

_CACHE: dict = {}         # tuple of ephemeris ids -> (the ephemerides, their parameter matrix)
_CACHE_MAX = 64


def params(ephs) -> np.ndarray:
    """(n, len(FIELDS)) float64 matrix of the ephemerides (cached by identity: ephemerides are not
    modified after creation, replacements are new objects)."""
    key = tuple(map(id, ephs))
    hit = _CACHE.get(key)
    if hit is not None and all(a is b for a, b in zip(hit[0], ephs)):
        return hit[1]
    p = np.array([[float(getattr(e, k)) for k in FIELDS] for e in ephs], dtype=np.float64).reshape(-1, len(FIELDS))
    if len(_CACHE) >= _CACHE_MAX:
        _CACHE.clear()
    _CACHE[key] = (tuple(ephs), p)
    return p


def sat_states(ephs, t_tx):
    """(pos (n,3), vel (n,3), clk_bias (n,), clk_drift (n,)) of n GPS/QZSS ephemerides at their transmit
    times t_tx (n,) (satellite clock, s of week): see receiver.gnss.ephemeris.sat_state."""
    p = params(ephs)
    t = np.ascontiguousarray(np.broadcast_to(np.asarray(t_tx, dtype=np.float64), (len(p),)))
    return _states(p, t)


@njit(cache=True, nogil=True)
def _wrap(dt):
    return (dt + 302400.0) % 604800.0 - 302400.0


@njit(cache=True, nogil=True)
def _orbit(p, t, pos, vel, ek_out, edot_out):
    n_sat = p.shape[0]
    mk = np.empty(n_sat)
    ek = np.empty(n_sat)
    tk = np.empty(n_sat)
    nn = np.empty(n_sat)
    for i in range(n_sat):
        a = p[i, 6] ** 2
        n0 = np.sqrt(MU_GPS / a ** 3)
        nn[i] = n0 + p[i, 12]
        tk[i] = _wrap(t[i] - p[i, 0])
        mk[i] = p[i, 11] + nn[i] * tk[i]
        ek[i] = mk[i]
    for _ in range(30):                  # lock step, as the numpy version
        done = True
        for i in range(n_sat):
            e = p[i, 7]
            f = ek[i] - e * np.sin(ek[i]) - mk[i]
            step = f / (1.0 - e * np.cos(ek[i]))
            ek[i] = ek[i] - step
            if not abs(step) < 1e-15:
                done = False
        if done:
            break
    for i in range(n_sat):
        a = p[i, 6] ** 2
        e = p[i, 7]
        cus, cuc, crs, crc, cis, cic = p[i, 16], p[i, 15], p[i, 18], p[i, 17], p[i, 20], p[i, 19]
        sin_e, cos_e = np.sin(ek[i]), np.cos(ek[i])
        one_m_ecos = 1.0 - e * cos_e
        nu = np.arctan2(np.sqrt(1.0 - e * e) * sin_e, cos_e - e)
        phi = nu + p[i, 10]
        s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
        du = cus * s2 + cuc * c2
        dr = crs * s2 + crc * c2
        di = cis * s2 + cic * c2
        u = phi + du
        r = a * one_m_ecos + dr
        inc = p[i, 8] + p[i, 13] * tk[i] + di
        big_omega = p[i, 9] + (p[i, 14] - OMEGA_E) * tk[i] - OMEGA_E * p[i, 0]
        e_dot = nn[i] / one_m_ecos
        phi_dot = np.sqrt(1.0 - e * e) * e_dot / one_m_ecos
        u_dot = phi_dot * (1.0 + 2.0 * (cus * c2 - cuc * s2))
        r_dot = a * e * sin_e * e_dot + 2.0 * phi_dot * (crs * c2 - crc * s2)
        i_dot = p[i, 13] + 2.0 * phi_dot * (cis * c2 - cic * s2)
        om_dot = p[i, 14] - OMEGA_E
        cu, su = np.cos(u), np.sin(u)
        xp, yp = r * cu, r * su
        xp_dot = r_dot * cu - r * u_dot * su
        yp_dot = r_dot * su + r * u_dot * cu
        co, so = np.cos(big_omega), np.sin(big_omega)
        ci, si = np.cos(inc), np.sin(inc)
        x = xp * co - yp * ci * so
        y = xp * so + yp * ci * co
        z = yp * si
        pos[i, 0], pos[i, 1], pos[i, 2] = x, y, z
        vel[i, 0] = xp_dot * co - yp_dot * ci * so + yp * si * so * i_dot - y * om_dot
        vel[i, 1] = xp_dot * so + yp_dot * ci * co - yp * si * co * i_dot + x * om_dot
        vel[i, 2] = yp_dot * si + yp * ci * i_dot
        ek_out[i] = ek[i]
        edot_out[i] = e_dot


@njit(cache=True)       # holds the GIL: see receiver/navigation/bits_jit.py
def _states(p, t_sv):
    n_sat = p.shape[0]
    pos = np.empty((n_sat, 3))
    vel = np.empty((n_sat, 3))
    ek = np.empty(n_sat)
    edot = np.empty(n_sat)
    t = t_sv.copy()
    rel = np.zeros(n_sat)
    for _ in range(3):
        for i in range(n_sat):
            dt = _wrap(t[i] - p[i, 1])
            bias_poly = p[i, 2] + p[i, 3] * dt + p[i, 4] * dt * dt
            t[i] = t_sv[i] - (bias_poly - p[i, 5] + rel[i])
        _orbit(p, t, pos, vel, ek, edot)
        for i in range(n_sat):
            rel[i] = F_REL * p[i, 7] * p[i, 6] * np.sin(ek[i])
    clk = np.empty(n_sat)
    drift = np.empty(n_sat)
    bias_poly = np.empty(n_sat)
    drift_poly = np.empty(n_sat)
    for i in range(n_sat):
        dt = _wrap(t[i] - p[i, 1])
        bias_poly[i] = p[i, 2] + p[i, 3] * dt + p[i, 4] * dt * dt
        drift_poly[i] = p[i, 3] + 2.0 * p[i, 4] * dt
    _orbit(p, t, pos, vel, ek, edot)
    for i in range(n_sat):
        rel_i = F_REL * p[i, 7] * p[i, 6] * np.sin(ek[i])
        rel_dot = F_REL * p[i, 7] * p[i, 6] * np.cos(ek[i]) * edot[i]
        clk[i] = bias_poly[i] + rel_i - p[i, 5]
        drift[i] = drift_poly[i] + rel_dot
    return pos, vel, clk, drift
