"""The compiled satellite states of the navigation solver (receiver.gnss.ephemeris_jit) against the numpy
reference (receiver.gnss.ephemeris.sat_state): the same values to float rounding."""
from dataclasses import replace

import numpy as np
import pytest

from receiver.gnss.ephemeris import Ephemeris, sat_state, select
from receiver.gnss.ephemeris_jit import sat_states
from receiver.gnss.rinex import read_rinex_nav

from repo_paths import TOKYO_NAV as BRDC


def _synthetic(n: int, rng) -> list:
    """n GPS-like ephemerides with random elements (eccentricities up to 0.3: more Kepler iterations)."""
    out = []
    for prn in range(1, n + 1):
        out.append(Ephemeris(
            prn=prn, week=2190, toe=float(rng.choice([0.0, 7200.0, 597600.0])), toc=7200.0,
            af0=rng.uniform(-5e-4, 5e-4), af1=rng.uniform(-1e-11, 1e-11), af2=0.0, tgd=rng.uniform(-1e-8, 1e-8),
            iode=1, iodc=1, sqrt_a=rng.uniform(5100.0, 5200.0), e=rng.uniform(0.0, 0.3),
            i0=rng.uniform(0.9, 1.0), omega0=rng.uniform(-3, 3), omega=rng.uniform(-3, 3),
            m0=rng.uniform(-3, 3), delta_n=rng.uniform(0, 5e-9), idot=rng.uniform(-1e-10, 1e-10),
            omega_dot=rng.uniform(-8e-9, -7e-9), cuc=rng.uniform(-1e-5, 1e-5), cus=rng.uniform(-1e-5, 1e-5),
            crc=rng.uniform(100, 300), crs=rng.uniform(-100, 100), cic=rng.uniform(-1e-7, 1e-7),
            cis=rng.uniform(-1e-7, 1e-7)))
    return out


def _check(ephs, t):
    ref = sat_state(ephs, t)
    got = sat_states(ephs, t)
    assert got[0].shape == (len(ephs), 3) and got[2].shape == (len(ephs),)
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-6)       # m (values ~2.6e7 m)
    np.testing.assert_allclose(got[1], ref[1], rtol=0, atol=1e-9)       # m/s
    np.testing.assert_allclose(got[2], ref[2], rtol=0, atol=1e-18)      # s
    np.testing.assert_allclose(got[3], ref[3], rtol=0, atol=1e-21)      # s/s


@pytest.mark.slow
def test_synthetic_matches_numpy():
    rng = np.random.default_rng(7)
    ephs = _synthetic(14, rng)
    for t0 in (3600.0, 604790.0, 5.0):           # either side of the week crossover too
        _check(ephs, t0 + rng.uniform(0.06, 0.09, len(ephs)))
        _check(ephs, t0)                           # a scalar time broadcast to every satellite


def test_broadcast_matches_numpy():
    if not BRDC.exists():
        pytest.skip(f"shared test data absent: {BRDC}")
    ephs, _ = read_rinex_nav(BRDC)
    rng = np.random.default_rng(3)
    for t0 in np.linspace(518400.0, 604000.0, 12):
        sel = [e for e in (select(v, t0) for v in ephs.values()) if e is not None]
        assert len(sel) >= 20
        _check(sel, t0 + rng.uniform(0.065, 0.085, len(sel)))


def test_parameter_cache_follows_the_objects():
    """A replaced ephemeris (a new object, as the decoder makes) is not served from the cache."""
    rng = np.random.default_rng(1)
    ephs = _synthetic(3, rng)
    a = sat_states(ephs, 7300.0)[0]
    ephs2 = [ephs[0], replace(ephs[1], m0=ephs[1].m0 + 0.01), ephs[2]]
    b = sat_states(ephs2, 7300.0)[0]
    np.testing.assert_array_equal(a[[0, 2]], b[[0, 2]])
    assert np.linalg.norm(a[1] - b[1]) > 1e3
    np.testing.assert_allclose(b, sat_state(ephs2, 7300.0)[0], rtol=0, atol=1e-6)


def test_constants_are_those_of_the_signals_module():
    """The compiled module keeps its constants as literals (numba's cache does not track imported
    globals): they must be receiver.gnss.signals'."""
    from receiver.gnss import ephemeris_jit, signals
    assert (ephemeris_jit.OMEGA_E, ephemeris_jit.MU_GPS, ephemeris_jit.F_REL) == \
        (signals.OMEGA_E, signals.MU_GPS, signals.F_REL)
