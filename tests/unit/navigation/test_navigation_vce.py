"""Per-system variance factors of combined fixes (navigation.weighting_per_system vce, receiver.navigation.pvt):
the simplified Helmert estimator over a window of fixes, on synthetic GPS + BeiDou pseudoranges (nominal
constellations, exact to ~1 cm) with seeded white noise whose variance is known per system."""
import types

import numpy as np
import pytest

from receiver.gnss.ephemeris import earth_rotation, sat_state
from receiver.gnss.geodesy import lla2ecef
from receiver.gnss.signals import C_LIGHT
from receiver.navigation.pvt import CODE_VAR_REL_CA, NavSolver, Observation
from receiver.sim.bds_constellation import bds_nominal_ephemerides
from receiver.sim.constellation import nominal_ephemerides

from repo_paths import ROOT as REPO

WEEK, T = 2300, 345600.0
X = np.array(lla2ecef(35.681298, 139.766247, 10.0))
BDS_KEY = 400
CFG = dict(elevation_mask_deg=10.0, weighting="elevation", troposphere="none", ionosphere="none",
           residual_threshold_m=30.0, max_pdop=20.0, weighting_per_system="fixed", vce_window_s=1000.0)


def _cfg(**kw):
    return types.SimpleNamespace(**{**CFG, **kw})


def _obs(eph, key, system):
    """Exact observation of a receiver at X at true time T with a zero clock; and the elevation (rad)."""
    tx, clk = T - 0.075, 0.0
    for _ in range(8):
        pos, _, clk, _ = sat_state(eph, tx + clk)
        tx = T - np.linalg.norm(earth_rotation(pos, T - tx) - X) / C_LIGHT
    pos = earth_rotation(sat_state(eph, tx + clk)[0], T - tx)
    el = np.arcsin(np.dot(pos - X, X / np.linalg.norm(X)) / np.linalg.norm(pos - X))
    return Observation(prn=key, tx_tow=tx + clk, system=system), el


@pytest.fixture(scope="module")
def sky():
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", WEEK, T)
    bds, _ = bds_nominal_ephemerides(REPO / "data/bds_nominal_constellation.yaml", WEEK, T)
    sats, ephs = [], {}
    for src, system, off in ((gps, "G", 0), (bds, "C", BDS_KEY)):
        for p, e in src.items():
            o, el = _obs(e, off + p, system)
            if el > np.radians(15.0):
                sats.append((o, el))
                ephs[off + p] = e
    return sats, ephs


def _noisy(sats, rng, scale):
    """The observations with white range noise of standard deviation scale[system] sqrt(code variance) /
    sin(el) metres: the elevation weighting's model, times scale[system]."""
    out = []
    for o, el in sats:
        sd = scale[o.system] * np.sqrt(CODE_VAR_REL_CA.get(o.system, 1.0)) / np.sin(el)
        out.append(Observation(prn=o.prn, tx_tow=o.tx_tow - rng.normal(0.0, sd) / C_LIGHT, system=o.system))
    return out


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_vce_finds_a_threefold_noise_and_beats_the_fixed_weights(sky, seed):
    """BeiDou ranges with 3 times the noise the fixed weights assume (variance 9 times): the estimated BeiDou
    factor (GPS = 1) is within 30 % of 9, and the combined fixes after the first 10 epochs are better than with
    the fixed weights on the same observations."""
    sats, ephs = sky
    rng = np.random.default_rng(seed)
    fixed, vce = NavSolver(_cfg()), NavSolver(_cfg(weighting_per_system="vce"))
    err = {"fixed": [], "vce": []}
    for k in range(60):
        obs = _noisy(sats, rng, {"G": 0.5, "C": 1.5})
        fa = fixed.fix(WEEK, T, obs, ephs, x0=X)
        fb = vce.fix(WEEK, T, obs, ephs, x0=X)
        assert fa.var_factors == {} and fb.n_sats == len(sats)
        if k >= 10:
            err["fixed"].append(np.sum((fa.ecef - X) ** 2))
            err["vce"].append(np.sum((fb.ecef - X) ** 2))
            assert fb.var_factors["G"] == 1.0
    ratio = vce.vce_factors(["G", "C"])["C"]
    assert ratio == pytest.approx(9.0, rel=0.3)
    assert np.sqrt(np.mean(err["vce"])) < np.sqrt(np.mean(err["fixed"]))


def test_vce_keeps_the_fixed_weights_when_they_are_right(sky):
    """Noise exactly as the fixed weights model it: the factor stays near 1 (within 30 %)."""
    sats, ephs = sky
    rng = np.random.default_rng(11)
    vce = NavSolver(_cfg(weighting_per_system="vce"))
    for _ in range(60):
        vce.fix(WEEK, T, _noisy(sats, rng, {"G": 1.0, "C": 1.0}), ephs, x0=X)
    assert vce.vce_factors(["G", "C"])["C"] == pytest.approx(1.0, rel=0.3)


def test_vce_is_a_no_op_for_one_system_and_for_trial_fixes(sky):
    """One-system fixes are bit-identical with vce on and off (nothing learned, no factor); fixes with
    learn=False (the assisted ambiguity search) leave the window untouched; the window drops old fixes."""
    sats, ephs = sky
    rng = np.random.default_rng(3)
    gps = [(o, el) for o, el in sats if o.system == "G"]
    a, b = NavSolver(_cfg()), NavSolver(_cfg(weighting_per_system="vce"))
    for _ in range(5):
        obs = _noisy(gps, rng, {"G": 1.0})
        fa, fb = a.fix(WEEK, T, obs, ephs, x0=X), b.fix(WEEK, T, obs, ephs, x0=X)
        np.testing.assert_array_equal(fa.ecef, fb.ecef)
        assert fa.clock_bias_m == fb.clock_bias_m and fb.var_factors == {}
    assert len(b._vce_hist) == 0
    both = _noisy(sats, rng, {"G": 1.0, "C": 1.0})
    b.fix(WEEK, T, both, ephs, x0=X, learn=False)
    assert len(b._vce_hist) == 0
    short = NavSolver(_cfg(weighting_per_system="vce", vce_window_s=2.0))
    for k in range(6):
        short.fix(WEEK, T + k, both, ephs, x0=X)
    assert [t - WEEK * 604800.0 for t, _ in short._vce_hist] == [T + 3, T + 4, T + 5]
    assert short.vce_factors(["G", "C"])       # enough redundancy in 3 fixes of ~20 satellites


def test_vce_keeps_the_fixed_weights_for_a_system_of_two_satellites(sky):
    """Two BeiDou satellites beside GPS: after their own inter-system bias almost no redundancy is left to them
    (less than VCE_MIN_MEAN_REDUNDANCY per fix), so no factor is estimated and the fixes are those of the fixed
    weights, even with a threefold BeiDou noise."""
    sats, ephs = sky
    two = [t for t in sats if t[0].system == "G"] + [t for t in sats if t[0].system == "C"][:2]
    rng = np.random.default_rng(7)
    fixed, vce = NavSolver(_cfg()), NavSolver(_cfg(weighting_per_system="vce"))
    for _ in range(20):
        obs = _noisy(two, rng, {"G": 0.5, "C": 1.5})
        fa, fb = fixed.fix(WEEK, T, obs, ephs, x0=X), vce.fix(WEEK, T, obs, ephs, x0=X)
        assert fb.var_factors == {}
        np.testing.assert_allclose(fb.ecef, fa.ecef, rtol=0, atol=1e-9)
    assert len(vce._vce_hist) == 20 and vce.vce_factors(["G", "C"]) == {}
