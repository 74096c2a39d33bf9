"""Compiled linearisation of one Gauss-Newton step of the navigation solver (receiver.navigation.pvt).

:func:`linearise` computes, for the active satellites at the current position x and clock b, what
``NavSolver._wls`` computed with ~60 numpy calls on 4-12 element arrays per iteration: travel times,
Sagnac-rotated positions, ranges and lines of sight, azimuth / elevation, Klobuchar and Saastamoinen
delays, the weights and the residuals -- the same formulas in the same order, compiled (the numpy
version is kept, ``NavSolver._linearise_numpy``; tests/unit/navigation/test_navigation_wls_jit.py checks they agree to
float rounding).  The position's geodetic coordinates come from the caller (receiver.gnss.geodesy).
Self-contained: the compiled functions call no compiled function of another module (numba's on-disk
cache is keyed on this file).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

# literals (numba freezes globals into the cached code; tests/unit/navigation/test_navigation_wls_jit.py checks them
# against
# receiver.gnss.signals / atmosphere)
C_LIGHT = 299792458.0
OMEGA_E = 7.2921151467e-5
GPS_PI = 3.1415926535898
WEIGHTING = {"elevation": 0, "cn0": 1, "none": 2, "rtklib": 3, "cn0_elevation": 4}


@njit(cache=True, nogil=True)
def _polyval(x, c):
    v = c[3]
    for i in range(2, 5):
        v = c[4 - i] + v * x
    return v


@njit(cache=True)       # holds the GIL: see receiver/navigation/bits_jit.py
def linearise(pos_tx, x, b, rho_c, cn0, ura, known, corr, lat_deg, lon_deg, h_m, iono_on, alpha, beta, tow,
              tropo_on, weighting, tropo_none, cn0_ref_dbhz):
    """-> (tau, los, az, el, iono, tropo, w, resid_without_isb, h4) for the satellites pos_tx (n, 3).

    known: |x| > 5000 km (az/el exist); corr: apply the corrections (needs known); iono_on: Klobuchar
    with alpha/beta; tropo_on: Saastamoinen (the caller checks the height range); weighting: WEIGHTING
    code; tropo_none: navigation.troposphere == 'none' (the rtklib weighting's unmodelled 3 m); cn0_ref_dbhz:
    the cn0_elevation weighting's navigation.cn0_ref_dbhz."""
    n = pos_tx.shape[0]
    tau = np.empty(n)
    los = np.empty((n, 3))
    rng = np.empty(n)
    az = np.zeros(n)
    el = np.zeros(n)
    iono = np.zeros(n)
    tropo = np.zeros(n)
    for i in range(n):
        dx = pos_tx[i, 0] - x[0]
        dy = pos_tx[i, 1] - x[1]
        dz = pos_tx[i, 2] - x[2]
        tau[i] = math.sqrt(dx * dx + dy * dy + dz * dz) / C_LIGHT
        th = OMEGA_E * tau[i]
        c, s = np.cos(th), np.sin(th)
        px = c * pos_tx[i, 0] + s * pos_tx[i, 1]
        py = -s * pos_tx[i, 0] + c * pos_tx[i, 1]
        pz = pos_tx[i, 2]
        ex, ey, ez = px - x[0], py - x[1], pz - x[2]
        r = math.sqrt(ex * ex + ey * ey + ez * ez)
        rng[i] = r
        los[i, 0], los[i, 1], los[i, 2] = ex / r, ey / r, ez / r
        if known:
            lat, lon = np.radians(lat_deg), np.radians(lon_deg)
            sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
            e = ex * -so + ey * co + ez * 0.0
            nn = ex * (-sl * co) + ey * (-sl * so) + ez * cl
            u = ex * (cl * co) + ey * (cl * so) + ez * sl
            az[i] = np.arctan2(e, nn) % (2 * np.pi)
            el[i] = np.arctan2(u, np.hypot(e, nn))
    if corr and known:
        lat, lon = np.radians(lat_deg), np.radians(lon_deg)
        if iono_on:
            phi_u = lat / GPS_PI
            lam_u = lon / GPS_PI
            for i in range(n):
                eli = el[i] / GPS_PI
                psi = 0.0137 / (eli + 0.11) - 0.022
                phi_i = min(max(phi_u + psi * np.cos(az[i]), -0.416), 0.416)
                lam_i = lam_u + psi * np.sin(az[i]) / np.cos(phi_i * GPS_PI)
                phi_m = phi_i + 0.064 * np.cos((lam_i - 1.617) * GPS_PI)
                t_local = (4.32e4 * lam_i + tow) % 86400.0
                obliquity = 1.0 + 16.0 * (0.53 - eli) ** 3
                amp = max(_polyval(phi_m, alpha), 0.0)
                per = max(_polyval(phi_m, beta), 72000.0)
                xx = 2.0 * np.pi * (t_local - 50400.0) / per
                day = 5e-9 + amp * (1.0 - xx * xx / 2.0 + xx ** 4 / 24.0)
                iono[i] = C_LIGHT * (obliquity * (day if abs(xx) < 1.57 else 5e-9))
        if tropo_on:
            h_t = min(max(h_m, -500.0), 11000.0)
            temp = 288.15 - 6.5e-3 * h_t
            pres = 1013.25 * (temp / 288.15) ** 5.25588
            above = h_m > 11000.0
            if above:
                pres = pres * np.exp(-(max(h_m, 11000.0) - 11000.0) / 6341.62)
            tc = temp - 273.15
            e_sat = 6.1078 * np.exp(17.27 * tc / (tc + 237.3))
            vap = 0.0 if above else 0.7 * e_sat
            h_km = min(max(h_m, -0.5e3), 50e3) / 1e3
            grav = 1.0 - 0.00266 * np.cos(2.0 * lat) - 0.00028 * h_km
            zhd = 0.0022768 * pres / grav
            zwd = 0.002277 * (1255.0 / temp + 0.05) * vap
            for i in range(n):
                sn = np.sin(max(el[i], 0.0))
                tropo[i] = (zhd + zwd) * (1.001 / np.sqrt(0.002001 + sn * sn))
    w = np.empty(n)
    have_el = corr and known
    rad1 = np.radians(1.0)
    cn0_ok = True
    for i in range(n):
        if not np.isfinite(cn0[i]):
            cn0_ok = False
    for i in range(n):
        if weighting == 3 and have_el:
            se = np.sin(max(el[i], rad1))
            var = 100.0 ** 2 * (0.003 ** 2 + 0.003 ** 2 / se) + 0.3 ** 2 + (0.5 * iono[i]) ** 2 + ura[i] ** 2
            var += 9.0 if tropo_none else (0.3 / se) ** 2
            w[i] = 1.0 / var
        elif weighting == 4 and have_el and cn0_ok:
            se = np.sin(max(el[i], rad1))
            w[i] = 1.0 / (10.0 ** ((cn0_ref_dbhz - cn0[i]) / 10.0) + 1.0 / (se * se))
        elif (weighting == 0 or weighting == 4) and have_el:     # (cn0_elevation without a C/N0: sin^2(el))
            w[i] = np.sin(max(el[i], rad1)) ** 2
        elif weighting == 1 and cn0_ok:
            w[i] = 10.0 ** (cn0[i] / 10.0)
        else:
            w[i] = 1.0
    wmax = w[0]
    for i in range(1, n):
        wmax = max(wmax, w[i])
    resid = np.empty(n)
    h4 = np.empty((n, 4))
    for i in range(n):
        w[i] = w[i] / wmax
        resid[i] = rho_c[i] - iono[i] - tropo[i] - (rng[i] + b)
        h4[i, 0], h4[i, 1], h4[i, 2], h4[i, 3] = -los[i, 0], -los[i, 1], -los[i, 2], 1.0
    return tau, los, az, el, iono, tropo, w, resid, h4
