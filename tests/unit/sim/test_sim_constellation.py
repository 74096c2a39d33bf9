"""Ephemeris sources of the simulator: the embedded nominal constellation and RINEX files."""
import math

import numpy as np
import pytest

from receiver.gnss.geodesy import azel, lla2ecef
from receiver.gnss.ephemeris import sat_state
from receiver.gnss.lnav import LnavDecoder, EphemerisEvent, encode_subframes
from receiver.sim.constellation import nominal_ephemerides, quantize_ephemeris, rinex_ephemerides
from receiver.sim.scenario import NOMINAL_CONSTELLATION, REPO_ROOT

NOMINAL = REPO_ROOT / NOMINAL_CONSTELLATION
SHARED = REPO_ROOT.parent / "shared" / "data"


def test_nominal_geometry():
    ephs, iono = nominal_ephemerides(NOMINAL, 2300, 345600.0)
    assert len(ephs) == 31
    a = np.array([e.sqrt_a ** 2 for e in ephs.values()])
    inc = np.degrees([e.i0 for e in ephs.values()])
    assert np.all(np.abs(a - 26559.7e3) < 20e3)
    assert np.all(np.abs(inc - 55.0) < 2.0)
    # six planes 60 degrees apart in (Earth-fixed) node longitude at toe
    raan = np.degrees([e.omega0 - 7.2921151467e-5 * e.toe for e in ephs.values()]) % 360.0
    planes = np.round(raan / 60.0).astype(int) % 6
    assert sorted(set(planes)) == list(range(6)) and max(np.bincount(planes)) <= 6
    # orbital radius from the orbit model
    pos = np.array([sat_state(e, e.toe)[0] for e in ephs.values()])
    r = np.linalg.norm(pos, axis=1)
    assert np.all(np.abs(r - 26559.7e3) < 0.03 * 26559.7e3)
    assert len(iono.alpha) == 4 and len(iono.beta) == 4


def test_reepoch_gives_the_same_sky_on_any_date():
    rx = lla2ecef(46.5, 6.6, 400.0)
    views = []
    for week, tow in ((2300, 345600.0), (1800, 12345.0), (2500, 600000.0)):
        ephs, _ = nominal_ephemerides(NOMINAL, week, tow)
        t = math.floor(tow / 16) * 16
        pos = np.array([sat_state(ephs[p], t + ephs[p].af0)[0] for p in sorted(ephs)])
        az, el = azel(rx, pos)
        views.append(np.degrees(el))
    assert np.allclose(views[0], views[1], atol=0.05) and np.allclose(views[0], views[2], atol=0.05)
    assert np.sum(views[0] > 5.0) >= 6


def test_quantized_ephemeris_survives_lnav_round_trip():
    ephs, iono = nominal_ephemerides(NOMINAL, 2300, 345600.0)
    for prn in (1, 12, 32):
        eph = ephs[prn]
        assert quantize_ephemeris(eph) == eph                 # already on the LSB grid
        bits = np.concatenate([encode_subframes(eph, iono, 345600.0 + 30 * k, 2300) for k in range(2)])
        dec = LnavDecoder(prn=prn, week_hint=2300)
        ev = [e for e in dec.feed(1.0 - 2.0 * bits, 0) if isinstance(e, EphemerisEvent)]
        assert ev and ev[0].ephemeris == eph


@pytest.mark.skipif(not (SHARED / "brdc0010.22n").exists(), reason="../shared/data is not available")
def test_rinex_selection_and_tokyo_sky():
    ephs, iono = rinex_ephemerides(str(SHARED / "brdc0010.22n"), 2190, 525606.0)
    assert all(abs(e.toe - 525606.0) <= 30 and e.health == 0 for e in ephs.values())
    assert iono is not None
    import yaml
    meta = yaml.safe_load(open(SHARED / "gpssim_static_tokyo.yaml"))
    rx = np.array(meta["truth"]["ecef_m"])
    up = []
    for prn, e in ephs.items():
        pos = sat_state(e, 525584.0)[0]
        if np.degrees(azel(rx, pos)[1]) > 0:
            up.append(prn)
    assert sorted(up) == sorted(meta["satellites_above_horizon"])
