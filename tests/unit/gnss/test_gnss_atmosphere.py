"""Klobuchar ionosphere and Saastamoinen troposphere: invariants and hand-computed values."""
from types import SimpleNamespace

import numpy as np
import pytest

from receiver.gnss.atmosphere import (klobuchar_delay_s, saastamoinen_m, saastamoinen_zenith_m,
                                     standard_atmosphere, tropo_mapping)
from receiver.gnss.ephemeris import IonoUtc

# broadcast coefficients of 2022-01-01 (brdc0010.22n header)
IONO = IonoUtc(alpha=(0.1211e-07, -0.7451e-08, -0.5960e-07, 0.1192e-06),
               beta=(0.1167e+06, -0.2458e+06, -0.6554e+05, 0.1114e+07))
SC = 3.1415926535898  # one semicircle in rad


def test_klobuchar_hand_computed_zenith():
    # user at 0.2 semicircles latitude, longitude 0, satellite at zenith, 14:00 local time.
    # psi = 0.0137/(0.5+0.11) - 0.022 = 4.590164e-4 sc ; phi_i = 0.2004590 (az 0) ; lam_i = 0
    # phi_m = phi_i + 0.064 cos(-1.617 pi) = 0.2234571 ; t = 50400 -> x = 0
    # AMP = sum alpha_n phi_m^n = 8.799031e-9 s ; F = 1 + 16 (0.53-0.5)^3 = 1.000432
    # T = F (5e-9 + AMP) = 1.3804992e-8 s
    t = klobuchar_delay_s(IONO, 0.2 * SC, 0.0, 0.0, 0.5 * SC, 50400.0)
    assert t == pytest.approx(1.3804992e-8, rel=1e-6)


def test_klobuchar_night_floor_and_obliquity():
    el = np.radians(np.array([90.0, 45.0, 20.0, 10.0, 5.0]))
    for lat, lon in ((0.6, 2.4), (-0.3, -1.0), (0.0, 0.0)):
        # local night (02:00 local for the pierce point, far from 14:00)
        tow = (2 * 3600 - 4.32e4 * lon / SC) % 86400
        t = klobuchar_delay_s(IONO, lat, lon, 0.0, el, tow)
        obliquity = 1.0 + 16.0 * (0.53 - el / SC) ** 3
        np.testing.assert_allclose(t, 5e-9 * obliquity, rtol=1e-12)
    assert np.all(np.diff(t) > 0)                       # lower elevation -> longer path
    assert 5e-9 * 3.0 < t[-1] < 5e-9 * 3.1              # ~3x obliquity at 5 deg


def test_klobuchar_invariants():
    rng = np.random.default_rng(0)
    lat = rng.uniform(-1.4, 1.4, 500)
    lon = rng.uniform(-np.pi, np.pi, 500)
    az = rng.uniform(0, 2 * np.pi, 500)
    el = rng.uniform(0.0, np.pi / 2, 500)
    tow = rng.uniform(0, 604800, 500)
    t = klobuchar_delay_s(IONO, lat, lon, az, el, tow)
    obliquity = 1.0 + 16.0 * (0.53 - el / SC) ** 3
    assert np.all(t >= 5e-9 * obliquity * (1 - 1e-12))
    assert np.all(t * 299792458.0 < 60.0)                # tens of metres at most
    # zero alpha: the model is the 5 ns night value at every time of day
    flat = IonoUtc(alpha=(0, 0, 0, 0), beta=IONO.beta)
    np.testing.assert_allclose(klobuchar_delay_s(flat, lat, lon, az, el, tow), 5e-9 * obliquity)
    # daytime maximum at 14:00 local time of the pierce point (zenith, lon 0)
    tows = np.arange(0, 86400, 600.0)
    day = klobuchar_delay_s(IONO, 0.3, 0.0, 0.0, np.pi / 2, tows)
    assert abs(tows[np.argmax(day)] - 50400) <= 600
    # any object with alpha/beta is accepted
    ns = SimpleNamespace(alpha=IONO.alpha, beta=IONO.beta)
    assert klobuchar_delay_s(ns, 0.3, 0.0, 0.0, 1.0, 50400.0) == klobuchar_delay_s(IONO, 0.3, 0.0, 0.0, 1.0, 50400.0)


def test_standard_atmosphere():
    p, t, e = standard_atmosphere(0.0)
    assert p == pytest.approx(1013.25) and t == pytest.approx(288.15)
    # saturation vapour pressure at 15 degC is about 17.05 hPa; RH 0.7
    assert e == pytest.approx(0.7 * 17.05, rel=0.01)
    p5, t5, _ = standard_atmosphere(5000.0)
    assert p5 == pytest.approx(540.2, rel=0.01) and t5 == pytest.approx(255.65)
    p20, t20, e20 = standard_atmosphere(20000.0)
    assert 50 < p20 < 60 and t20 == pytest.approx(216.65) and e20 == 0


def test_saastamoinen_hand_computed_zenith():
    # 45 deg latitude, sea level: ZHD = 0.0022768 * 1013.25 / (1 - 0.00266 cos 90deg) = 2.30697 m
    # ZWD = 0.002277 (1255/288.15 + 0.05) * 0.7 * 6.1078 exp(17.27*15/252.3) = 0.11974 m
    zhd, zwd = saastamoinen_zenith_m(np.radians(45.0), 0.0)
    assert zhd == pytest.approx(2.30697, abs=1e-4)
    assert zwd == pytest.approx(0.11974, abs=2e-4)
    assert saastamoinen_m(np.radians(45.0), 0.0, np.pi / 2) == pytest.approx(2.4267, abs=1e-3)


def test_saastamoinen_invariants():
    el = np.radians(np.array([90, 60, 30, 15, 10, 5, 2]))
    d = saastamoinen_m(0.6, 100.0, el)
    assert 2.3 < d[0] < 2.5
    assert np.all(np.diff(d) > 0)
    np.testing.assert_allclose(d[:4] / d[0], 1 / np.sin(el[:4]), rtol=0.02)  # ~1/sin(el) when high
    assert 9.5 < d[5] / d[0] < 11                         # ~10x at 5 deg
    # decreases with height (about -12% per km near the ground)
    heights = np.array([0.0, 1000.0, 3000.0, 8000.0])
    z = saastamoinen_m(0.6, heights, np.pi / 2)
    assert np.all(np.diff(z) < 0) and 0.85 < z[1] / z[0] < 0.9
    assert tropo_mapping(np.pi / 2) == pytest.approx(1.0, abs=1e-6)
