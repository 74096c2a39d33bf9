"""Atmospheric delay models for single-frequency GPS L1 positioning.

* Ionosphere: the broadcast Klobuchar model (IS-GPS-200 20.3.3.5.2.5).
* Troposphere: Saastamoinen zenith delays for a standard atmosphere, mapped to the slant
  direction with the simple mapping function 1.001 / sqrt(0.002001 + sin^2(el))
  (the one used by RTCA MOPS DO-229).

Standard atmosphere (documented assumptions): sea-level pressure 1013.25 hPa, temperature
15 degC (288.15 K), lapse rate 6.5 K/km up to 11 km, isothermal (216.65 K) above with an
exponential pressure decay, relative humidity 0.7 (no water vapour above 11 km); the water
vapour pressure from the Magnus-Tetens formula.  Zenith hydrostatic delay (Saastamoinen with
the Davis et al. gravity correction): 0.0022768 P / (1 - 0.00266 cos 2phi - 0.00028 h_km);
zenith wet delay (Saastamoinen): 0.002277 (1255 / T + 0.05) e.  Pressures in hPa, T in K.
"""
from __future__ import annotations

import numpy as np

GPS_PI = 3.1415926535898

# Fallback Klobuchar coefficients (navigation.klobuchar_fallback), used while no broadcast set is known (LNAV
# sends its set in subframe 4 page 18, once every 12.5 minutes).  Source: the header lines ION ALPHA / ION BETA
# of the IGS merged broadcast navigation file brdc0010.22n (GPS, 2022-01-01; ../shared/data/brdc0010.22n), as
# printed there (4 significant digits; the broadcast integers behind them are alpha 13, -1, -1, 2 x 2^-30,
# 2^-27, 2^-24, 2^-24 and beta 57, -15, -1, 17 x 2^11, 2^14, 2^16, 2^16, within 0.1 %).  One day's set
# (moderate solar activity, early 2022); on other days it describes the ionosphere less well than that day's
# broadcast set.  tests/unit/navigation/test_navigation_iono.py checks these values against the file when ../shared is
# there.
FALLBACK_KLOBUCHAR_ALPHA = (0.1211e-07, -0.7451e-08, -0.5960e-07, 0.1192e-06)      # s, s/sc, s/sc^2, s/sc^3
FALLBACK_KLOBUCHAR_BETA = (0.1167e+06, -0.2458e+06, -0.6554e+05, 0.1114e+07)       # s, s/sc, s/sc^2, s/sc^3
FALLBACK_KLOBUCHAR_SOURCE = "brdc0010.22n (GPS broadcast, 2022-01-01)"


def klobuchar_delay_s(iono, lat_rad, lon_rad, az_rad, el_rad, gps_tow):
    """Klobuchar L1 ionospheric group delay (s).

    iono: object with ``alpha`` and ``beta`` (4 coefficients each, broadcast units:
    s, s/semicircle, ...). lat/lon: user geodetic position (rad); az/el: satellite azimuth
    and elevation (rad, arrays allowed); gps_tow: GPS seconds of week.
    """
    alpha = np.asarray(iono.alpha, dtype=float)
    beta = np.asarray(iono.beta, dtype=float)
    phi_u = np.asarray(lat_rad, dtype=float) / GPS_PI            # semicircles
    lam_u = np.asarray(lon_rad, dtype=float) / GPS_PI
    az = np.asarray(az_rad, dtype=float)
    el = np.asarray(el_rad, dtype=float) / GPS_PI

    psi = 0.0137 / (el + 0.11) - 0.022                            # earth-centred angle
    phi_i = np.clip(phi_u + psi * np.cos(az), -0.416, 0.416)      # sub-ionospheric latitude
    lam_i = lam_u + psi * np.sin(az) / np.cos(phi_i * GPS_PI)     # ... longitude
    phi_m = phi_i + 0.064 * np.cos((lam_i - 1.617) * GPS_PI)      # geomagnetic latitude
    t_local = np.mod(4.32e4 * lam_i + np.asarray(gps_tow, dtype=float), 86400.0)
    obliquity = 1.0 + 16.0 * (0.53 - el) ** 3
    amp = np.maximum(np.polynomial.polynomial.polyval(phi_m, alpha), 0.0)
    per = np.maximum(np.polynomial.polynomial.polyval(phi_m, beta), 72000.0)
    x = 2.0 * np.pi * (t_local - 50400.0) / per
    day = 5e-9 + amp * (1.0 - x * x / 2.0 + x ** 4 / 24.0)
    return obliquity * np.where(np.abs(x) < 1.57, day, 5e-9)


def standard_atmosphere(h_m, rel_humidity: float = 0.7):
    """(pressure hPa, temperature K, water vapour pressure hPa) at height h_m (m)."""
    h = np.asarray(h_m, dtype=float)
    h_t = np.clip(h, -500.0, 11000.0)
    temp = 288.15 - 6.5e-3 * h_t
    pres = 1013.25 * (temp / 288.15) ** 5.25588
    above = h > 11000.0
    pres = np.where(above, pres * np.exp(-(np.maximum(h, 11000.0) - 11000.0) / 6341.62), pres)
    tc = temp - 273.15
    e_sat = 6.1078 * np.exp(17.27 * tc / (tc + 237.3))
    vap = np.where(above, 0.0, rel_humidity * e_sat)
    return pres, temp, vap


def tropo_mapping(el_rad):
    """Slant / zenith ratio 1.001 / sqrt(0.002001 + sin^2 el) (el clipped at 0)."""
    s = np.sin(np.maximum(np.asarray(el_rad, dtype=float), 0.0))
    return 1.001 / np.sqrt(0.002001 + s * s)


def saastamoinen_zenith_m(lat_rad, h_m, rel_humidity: float = 0.7):
    """(zenith hydrostatic, zenith wet) delays (m) for the standard atmosphere."""
    pres, temp, vap = standard_atmosphere(h_m, rel_humidity)
    h_km = np.clip(np.asarray(h_m, dtype=float), -0.5e3, 50e3) / 1e3
    grav = 1.0 - 0.00266 * np.cos(2.0 * np.asarray(lat_rad, dtype=float)) - 0.00028 * h_km
    zhd = 0.0022768 * pres / grav
    zwd = 0.002277 * (1255.0 / temp + 0.05) * vap
    return zhd, zwd


def saastamoinen_m(lat_rad, h_m, el_rad, rel_humidity: float = 0.7):
    """Slant tropospheric delay (m) for a standard atmosphere (see module docstring)."""
    zhd, zwd = saastamoinen_zenith_m(lat_rad, h_m, rel_humidity)
    return (zhd + zwd) * tropo_mapping(el_rad)
