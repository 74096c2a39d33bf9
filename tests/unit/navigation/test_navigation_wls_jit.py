"""The compiled linearisation of the navigation solver's Gauss-Newton step (receiver.navigation.wls_jit)
against the numpy version (NavSolver._linearise_numpy): geometry, Klobuchar and Saastamoinen delays,
weights and residuals agree to float rounding for every weighting and model setting."""
from types import SimpleNamespace

import numpy as np
import pytest

from receiver.gnss.ephemeris import IonoUtc
from receiver.gnss.geodesy import lla2ecef
from receiver.navigation.pvt import NavSolver

IONO = IonoUtc(alpha=(1.118e-08, 7.451e-09, -5.961e-08, -5.961e-08), beta=(9.011e4, 4.915e4, -1.966e5, -3.277e5))


def _scene(seed, h_m=40.0):
    rng = np.random.default_rng(seed)
    x = lla2ecef(35.68, 139.77, h_m)
    n = 9
    # satellites at 20200 km altitude in random directions above the horizon, plus one below it
    pos = []
    for k in range(n):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if k < n - 1 and d @ x < 0:
            d = -d
        pos.append(d * 26.56e6)
    pos = np.array(pos)
    rho = np.linalg.norm(pos - x, axis=1) + rng.normal(0, 5.0, n) + 1234.5
    cn0 = rng.uniform(30, 50, n)
    ura = rng.choice([2.4, 3.4, 4.85], n)
    return x + rng.normal(0, 30.0, 3), pos, rho, cn0, ura


@pytest.mark.parametrize("weighting", ["elevation", "cn0", "none", "rtklib", "cn0_elevation"])
@pytest.mark.parametrize("models", [("saastamoinen", "klobuchar"), ("none", "none"), ("saastamoinen", "none")])
def test_compiled_linearisation_matches_numpy(weighting, models):
    tropo, iono = models
    solver = NavSolver(SimpleNamespace(weighting=weighting, troposphere=tropo, ionosphere=iono))
    for seed, h in ((1, 40.0), (2, 15000.0), (3, -2000.0)):       # tropo above 11 km, off below -1 km
        x, pos, rho, cn0, ura = _scene(seed, h)
        for xx, corr in ((x, True), (x, False), (np.zeros(3), False), (x * 0.5, True)):   # unknown position
            for iono_utc in (IONO, None):
                assert solver._compiled_ok([], iono_utc)
                a = solver._linearise(pos, xx, 17.0, rho, cn0, ura, corr, iono_utc, 302400.0 + seed * 7000)
                b = solver._linearise_numpy(pos, xx, 17.0, rho, cn0, ura, np.zeros((len(pos), 0)), np.zeros(0),
                                            corr, iono_utc, 302400.0 + seed * 7000)
                assert a[0] == b[0]
                for name, u, v, tol in zip(("tau", "los", "az", "el", "iono", "tropo", "w", "resid", "h"),
                                           a[1:], b[1:], (1e-18, 1e-14, 1e-12, 1e-12, 1e-9, 1e-9, 1e-12, 1e-7, 1e-14)):
                    if v is None:
                        assert u is None, name
                        continue
                    np.testing.assert_allclose(u, v, rtol=0, atol=tol, err_msg=name)


def test_multi_system_and_odd_models_use_numpy():
    solver = NavSolver(SimpleNamespace(weighting="elevation", troposphere="saastamoinen", ionosphere="klobuchar"))
    assert not solver._compiled_ok([1], IONO)                      # an inter-system bias column
    assert not solver._compiled_ok([], IonoUtc(alpha=(1e-8,) * 3, beta=(1e5,) * 3))


def test_constants_are_those_of_the_gnss_modules():
    """wls_jit keeps its constants as literals (numba's cache does not track imported globals)."""
    from receiver.gnss import atmosphere, signals
    from receiver.navigation import wls_jit
    assert (wls_jit.C_LIGHT, wls_jit.OMEGA_E, wls_jit.GPS_PI) == \
        (signals.C_LIGHT, signals.OMEGA_E, atmosphere.GPS_PI)
