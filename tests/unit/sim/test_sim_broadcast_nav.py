"""The RINEX navigation file of what a scenario broadcasts (receiver.sim.simulate.write_broadcast_nav,
scripts/tools/scenario_nav.py): every system of a GPS + Galileo + BeiDou scenario, read back by the receiver's
assisted-mode reader as the simulator's own ephemerides (orbit and clock within the RINEX print precision)."""
import numpy as np
import pytest

from receiver.gnss.ephemeris import sat_state
from receiver.gnss.rinex import read_rinex_nav_for
from receiver.sim.simulate import _Simulator, write_broadcast_nav
from receiver.sim.scenario import load_scenario

from repo_paths import CONFIGS


def test_three_system_scenario_nav_round_trip(tmp_path):
    sc = CONFIGS / "scenarios/gps_gal_bds_static.yaml"
    path = tmp_path / "ggb.nav"
    n = write_broadcast_nav(sc, path, ["time.duration_s=2"])
    sim = _Simulator(load_scenario(sc, ["time.duration_s=2"]))
    assert n == len(sim.ephs) and n > 20
    ephs, iono = read_rinex_nav_for(path, ["G", "E", "C"])
    assert iono is not None and np.allclose(iono.alpha, sim.iono_b.alpha, rtol=1e-3, atol=1e-12)
    assert {type(e).__name__ for e in sim.ephs.values()} == {"Ephemeris", "GalEphemeris", "BdsEphemeris"}
    assert set(ephs) == set(sim.ephs)
    t = float(sim.sc.time.tow_s) + 1.0
    for key, e in sim.ephs.items():
        got = ephs[key]                       # the simulator's keys are the run's satellite keys
        got = got[0] if isinstance(got, list) else got
        pa, _, ca, _ = sat_state(e, t)
        pb, _, cb, _ = sat_state(got, t)
        assert np.linalg.norm(np.asarray(pa) - np.asarray(pb)) < 0.01
        assert float(ca) == pytest.approx(float(cb), abs=1e-11)
