"""Combined GPS + BeiDou single-point fixes (receiver.navigation.pvt with Observation.system): one receiver
clock plus an inter-system bias per extra system, on synthetic pseudoranges from the nominal GPS and
BeiDou constellations (consistent with the solver's model to ~1 cm: tolerances 5 cm)."""
import types

import numpy as np
import pytest

from receiver.gnss.ephemeris import earth_rotation, sat_state
from receiver.gnss.geodesy import ecef2lla, lla2ecef
from receiver.gnss.signals import C_LIGHT
from receiver.navigation.pvt import NavSolver, Observation
from receiver.sim.bds_constellation import bds_nominal_ephemerides
from receiver.sim.constellation import nominal_ephemerides

from repo_paths import ROOT as REPO
WEEK, T = 2300, 345600.0
X = np.array(lla2ecef(35.681298, 139.766247, 10.0))
BDS_KEY = 400            # BeiDou PRN p is satellite 400 + p in a combined epoch (GPS keeps 1..32)
CFG = types.SimpleNamespace(elevation_mask_deg=10.0, weighting="elevation", troposphere="none",
                            ionosphere="none", residual_threshold_m=30.0, max_pdop=20.0)


def _obs(eph, key, system, clock_m):
    """Exact observation of a receiver at X, true time T, clock reading T + clock_m / c."""
    tx, clk = T - 0.075, 0.0                   # true transmit time, satellite clock error
    for _ in range(8):
        pos, _, clk, _ = sat_state(eph, tx + clk)   # sat_state takes the satellite clock reading
        tx = T - np.linalg.norm(earth_rotation(pos, T - tx) - X) / C_LIGHT
    pos = earth_rotation(sat_state(eph, tx + clk)[0], T - tx)
    el = np.degrees(np.arcsin(np.dot(pos - X, X / np.linalg.norm(X)) / np.linalg.norm(pos - X)))
    # transmit time read by the satellite clock: true tx + its clock error; rx reading T + clock_m / c
    return Observation(prn=key, tx_tow=tx + clk, system=system), el


@pytest.fixture(scope="module")
def sky():
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", WEEK, T)
    bds, _ = bds_nominal_ephemerides(REPO / "data/bds_nominal_constellation.yaml", WEEK, T)
    g, c, ephs = [], [], {}
    for p, e in gps.items():
        o, el = _obs(e, p, "G", 0.0)
        if el > 15:
            g.append((el, o))
            ephs[p] = e
    for p, e in bds.items():
        o, el = _obs(e, BDS_KEY + p, "C", 0.0)
        if el > 15:
            c.append((el, o))
            ephs[BDS_KEY + p] = e
    return sorted(g, key=lambda t: -t[0]), sorted(c, key=lambda t: -t[0]), ephs


def _shift(obs, metres):
    """A receiver delay of `metres` on these signals (inter-system bias): the transmit time read earlier."""
    return [Observation(prn=o.prn, tx_tow=o.tx_tow - metres / C_LIGHT, system=o.system) for o in obs]


def test_combined_fix_estimates_the_inter_system_bias(sky):
    g, c, ephs = sky
    bias, isb = 1500.0, -34.5                   # receiver clock (m) and BeiDou-GPS bias (m)
    obs = [o for _, o in g] + _shift([o for _, o in c], isb)
    fix = NavSolver(CFG).fix(WEEK, T + bias / C_LIGHT, obs, ephs)
    assert fix is not None and fix.n_sats == len(g) + len(c)
    assert np.linalg.norm(fix.ecef - X) < 0.05
    assert fix.clock_bias_m == pytest.approx(bias, abs=0.05)
    assert fix.isb_m["C"] == pytest.approx(isb, abs=0.05)
    gps_only = NavSolver(CFG).fix(WEEK, T + bias / C_LIGHT, [o for _, o in g], ephs)
    assert gps_only.isb_m == {} and np.linalg.norm(gps_only.ecef - X) < 0.05
    assert fix.pdop < gps_only.pdop and fix.n_sats > gps_only.n_sats


def test_three_gps_satellites_fix_with_beidou(sky):
    g, c, ephs = sky
    three = [o for _, o in g[:3]]
    assert NavSolver(CFG).fix(WEEK, T, three, ephs) is None        # GPS alone: no fix
    fix = NavSolver(CFG).fix(WEEK, T, three + _shift([o for _, o in c], 25.0), ephs)
    assert fix is not None and fix.n_sats == 3 + len(c)
    assert np.linalg.norm(fix.ecef - X) < 0.05 and fix.isb_m["C"] == pytest.approx(25.0, abs=0.05)
    lat, lon, h = ecef2lla(fix.ecef)
    assert abs(h - 10.0) < 0.05


def test_one_system_fix_is_unchanged_by_the_system_field(sky):
    g, _, ephs = sky
    a = NavSolver(CFG).fix(WEEK, T, [o for _, o in g], ephs)
    b = NavSolver(CFG).fix(WEEK, T, [Observation(prn=o.prn, tx_tow=o.tx_tow, system="C") for _, o in g], ephs)
    np.testing.assert_array_equal(a.ecef, b.ecef)
    assert a.clock_bias_m == b.clock_bias_m and a.pdop == b.pdop


def test_klobuchar_delay_scaled_to_the_signal_carrier(sky):
    """The broadcast Klobuchar model gives the delay on its reference carrier (GPS set: L1, BeiDou set: B1I,
    IonoUtc.ref_hz); a B1I pseudorange corrected with the GPS set sees (f_L1 / f_B1I)^2 = 1.0184 of it."""
    from dataclasses import replace
    from receiver.gnss.atmosphere import klobuchar_delay_s
    from receiver.gnss.ephemeris import IonoUtc
    from receiver.gnss.geodesy import azel
    from receiver.gnss.signals import L1_HZ
    from receiver.gnss.signals_bds import B1I_HZ
    g, c, ephs = sky
    gps_set = IonoUtc(alpha=(1.2e-8, 1.5e-8, -6e-8, -1.2e-7), beta=(1.0e5, 1.2e5, -6.5e4, -4.0e5))
    lat, lon, _ = (np.radians(v) for v in ecef2lla(X))

    def delayed(obs, scale):
        out = []
        for o in obs:
            pos = sat_state(ephs[o.prn], o.tx_tow)[0]
            az, el = azel(X, pos)
            d = C_LIGHT * float(klobuchar_delay_s(gps_set, lat, lon, np.array([az]), np.array([el]), T)[0])
            out.append(Observation(prn=o.prn, tx_tow=o.tx_tow - scale * d / C_LIGHT, system=o.system))
        return out
    cfg = types.SimpleNamespace(**{**vars(CFG), "ionosphere": "klobuchar"})
    k = (L1_HZ / B1I_HZ) ** 2
    obs = delayed([o for _, o in g], 1.0) + delayed([o for _, o in c], k)
    fix = NavSolver(cfg).fix(WEEK, T, obs, ephs, gps_set, x0=X + 100.0)
    assert np.linalg.norm(fix.ecef - X) < 0.05 and abs(fix.isb_m["C"]) < 0.05
    # a BeiDou set (B1I reference) applies to B1I as it is: B1I-only ranges delayed by the model itself
    bds_set = replace(gps_set, ref_hz=B1I_HZ)
    only_c = delayed([o for _, o in c], 1.0)
    fix = NavSolver(cfg).fix(WEEK, T, only_c, ephs, bds_set, x0=X + 100.0)
    assert np.linalg.norm(fix.ecef - X) < 0.05
    wrong = NavSolver(cfg).fix(WEEK, T, only_c, ephs, gps_set, x0=X + 100.0)     # L1 set: 1.8 % too much
    assert np.linalg.norm(wrong.ecef - X) > 0.07                                   # (0.09 m; right: 0.02 m)


def test_combined_fix_weights_each_signal_by_its_code_noise(sky):
    """B1I (2.046 Mcps) ranges are twice as precise as L1 C/A ones at the same C/N0 and elevation: a fix mixing
    them weights each satellite by the inverse of its code variance, (1.023 / 2.046)^2 = 1/4 for B1I.  With
    seeded noise of those standard deviations the combined fix is better than the better system alone, and
    better than with the one-signal weights; one-system fixes are unchanged (all weights scaled alike)."""
    g, c, ephs = sky
    rng = np.random.default_rng(5)
    err = {"G": [], "C": [], "GC": [], "GC equal": []}
    solver = NavSolver(CFG)
    equal = NavSolver(CFG)
    equal._weights = lambda el, cn0, iono=None, ura_m=None, code_var=None: NavSolver._weights(equal, el, cn0, iono,
                                                                                                 ura_m)
    for _ in range(100):
        obs = [Observation(prn=o.prn, tx_tow=o.tx_tow - rng.normal(0.0, 1.0 if o.system == "G" else 0.5) / C_LIGHT,
                           system=o.system) for _, o in g + c]
        for name, sy, sv in (("G", "G", solver), ("C", "C", solver), ("GC", "GC", solver), ("GC equal", "GC", equal)):
            fix = sv.fix(WEEK, T, [o for o in obs if o.system in sy], ephs, x0=X)
            err[name].append(np.sum((fix.ecef - X) ** 2))
    rms = {k: float(np.sqrt(np.mean(v))) for k, v in err.items()}
    assert rms["GC"] < min(rms["G"], rms["C"]) and rms["GC"] < rms["GC equal"]
    w = solver._weights(np.radians([30.0, 30.0, 60.0]), np.full(3, 45.0), code_var=np.array([1.0, 0.25, 1.0]))
    assert w[1] == pytest.approx(4.0 * w[0]) and w[2] == pytest.approx(w[1] * np.sin(np.radians(60)) ** 2 / 4
                                                                      / np.sin(np.radians(30)) ** 2)
    one = solver._weights(np.radians([30.0, 60.0]), np.full(2, 45.0), code_var=np.array([0.25, 0.25]))
    np.testing.assert_array_equal(one, solver._weights(np.radians([30.0, 60.0]), np.full(2, 45.0)))


def test_code_variance_table_per_system():
    """Each system's range variance relative to L1 C/A (pvt.CODE_VAR_REL_CA): B1I 1/4 (chip length), Galileo E1
    2 (measured, docs/multi-gnss.md), GPS and QZSS 1; a mixed epoch's satellites get their system's value."""
    from receiver.navigation.pvt import CODE_VAR_REL_CA, _Sats
    assert CODE_VAR_REL_CA["C"] == pytest.approx(0.25) and CODE_VAR_REL_CA["E"] == 2.0
    assert "G" not in CODE_VAR_REL_CA and "J" not in CODE_VAR_REL_CA
    n = 4
    s = _Sats(range(n), np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.full(n, 45.0),
              np.zeros(n), systems=["G", "E", "C", "J"])
    np.testing.assert_array_equal(s.code_var, [1.0, 2.0, 0.25, 1.0])


def test_combined_run_applies_the_gps_klobuchar_set_to_every_satellite():
    """A GPS + BeiDou run: the GPS set (decoded, else the fallback set) corrects every satellite; a decoded
    BeiDou D1/D2 set (B1I reference) only while neither is there.  BeiDou-only runs keep their own set."""
    from receiver.gnss.ephemeris import IonoUtc
    from receiver.gnss.signals_bds import B1I_HZ
    from receiver.navigation.ephemeris_store import EphemerisStore
    from receiver.runfile.record import IONO_BROADCAST, IONO_FALLBACK

    def ch(io):
        return types.SimpleNamespace(decoder=types.SimpleNamespace(iono_utc=io))
    gps_set = IonoUtc(alpha=(1e-8, 0, 0, 0), beta=(9e4, 0, 0, 0))
    bds_set = IonoUtc(alpha=(2e-8, 0, 0, 0), beta=(0, 0, 0, 0), ref_hz=B1I_HZ)
    fallback = IonoUtc(alpha=(3e-8, 0, 0, 0), beta=(8e4, 0, 0, 0))
    st = EphemerisStore()
    st.iono_utc, st.solver = None, types.SimpleNamespace(ionosphere="klobuchar")
    st.signals, st.iono_fallback = {"G": None, "C": None}, fallback
    st.channels = {5: ch(None), 406: ch(bds_set)}
    assert st.iono() is fallback and st.iono_params() == IONO_FALLBACK
    st.channels[7] = ch(gps_set)
    assert st.iono() is gps_set and st.iono_params() == IONO_BROADCAST
    del st.channels[7]
    st.iono_fallback = None                      # no fallback: the BeiDou set rather than none
    assert st.iono() is bds_set
    st.signals, st.iono_fallback, st.channels = None, fallback, {6: ch(bds_set)}     # BeiDou-only run
    assert st.iono() is bds_set and st.iono_params() == IONO_BROADCAST


@pytest.fixture(scope="module")
def gal_sky():
    """The nominal Galileo constellation seen from X (satellite keys 300 + PRN), with BGD(E1,E5b) = 7 ns."""
    from dataclasses import replace
    from receiver.gnss.satid import sat_key
    from receiver.sim.gal_constellation import gal_nominal_content
    content = gal_nominal_content(REPO / "data/gal_nominal_constellation.yaml", WEEK, T)
    e, ephs = [], {}
    for p, cont in content.items():
        eph = replace(cont.eph, tgd=7e-9)
        o, el = _obs(eph, sat_key("E", p), "E", 0.0)
        if el > 15:
            e.append((el, o))
            ephs[sat_key("E", p)] = eph
    return sorted(e, key=lambda t: -t[0]), ephs


def test_gps_galileo_beidou_fix_estimates_one_bias_per_extra_system(sky, gal_sky):
    g, c, ephs = sky
    e, gal_ephs = gal_sky
    assert len(e) >= 4
    ephs = {**ephs, **gal_ephs}
    bias, isb_c, isb_e = 800.0, -34.5, 12.25
    obs = [o for _, o in g] + _shift([o for _, o in c], isb_c) + _shift([o for _, o in e], isb_e)
    fix = NavSolver(CFG).fix(WEEK, T + bias / C_LIGHT, obs, ephs)
    assert fix is not None and fix.n_sats == len(g) + len(c) + len(e)
    assert np.linalg.norm(fix.ecef - X) < 0.05 and fix.clock_bias_m == pytest.approx(bias, abs=0.05)
    assert fix.isb_m["C"] == pytest.approx(isb_c, abs=0.05) and fix.isb_m["E"] == pytest.approx(isb_e, abs=0.05)
    # Galileo alone: its own clock, no bias column
    gal_only = NavSolver(CFG).fix(WEEK, T + bias / C_LIGHT, _shift([o for _, o in e], isb_e), ephs)
    assert gal_only.isb_m == {} and np.linalg.norm(gal_only.ecef - X) < 0.05
    assert gal_only.clock_bias_m == pytest.approx(bias + isb_e, abs=0.05)
    gps_gal = NavSolver(CFG).fix(WEEK, T + bias / C_LIGHT, [o for _, o in g] + _shift([o for _, o in e], isb_e), ephs)
    gps_only = NavSolver(CFG).fix(WEEK, T + bias / C_LIGHT, [o for _, o in g], ephs)
    assert gps_gal.pdop < gps_only.pdop and gps_gal.pdop < gal_only.pdop


def test_three_gps_satellites_fix_with_galileo(sky, gal_sky):
    g, _, ephs = sky
    e, gal_ephs = gal_sky
    three = [o for _, o in g[:3]]
    fix = NavSolver(CFG).fix(WEEK, T, three + _shift([o for _, o in e], -8.0), {**ephs, **gal_ephs})
    assert fix is not None and fix.n_sats == 3 + len(e)
    assert np.linalg.norm(fix.ecef - X) < 0.05 and fix.isb_m["E"] == pytest.approx(-8.0, abs=0.05)


def test_three_gps_satellites_fix_with_galileo_and_beidou(sky, gal_sky):
    """GPS reduced to three satellites in a GPS + Galileo + BeiDou fix: one clock, two inter-system biases."""
    g, c, ephs = sky
    e, gal_ephs = gal_sky
    obs = [o for _, o in g[:3]] + _shift([o for _, o in c], 21.0) + _shift([o for _, o in e], -8.0)
    fix = NavSolver(CFG).fix(WEEK, T, obs, {**ephs, **gal_ephs})
    assert fix is not None and fix.n_sats == 3 + len(c) + len(e)
    assert np.linalg.norm(fix.ecef - X) < 0.05
    assert fix.isb_m["E"] == pytest.approx(-8.0, abs=0.05) and fix.isb_m["C"] == pytest.approx(21.0, abs=0.05)


def test_galileo_clock_uses_bgd_e1e5b(gal_sky):
    """ICD Eq. 15: the single-frequency E1 user's satellite clock is the E1,E5b clock minus BGD(E1,E5b)."""
    from dataclasses import replace
    _, ephs = gal_sky
    eph = next(iter(ephs.values()))
    t = eph.toe + 100.0
    c0 = sat_state(replace(eph, tgd=0.0), t)[2]
    c1 = sat_state(eph, t)[2]
    assert float(c0 - c1) == pytest.approx(7e-9, abs=1e-13)
