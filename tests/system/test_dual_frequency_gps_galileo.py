"""GPS L1/L5 + Galileo E1/E5a in one ionosphere-free fix (issue 38): the project's simulator writes the GPS +
Galileo L1/E1 file and an L5 and an E5a file on one clock (configs/scenarios/gps_gal_l5_e5a_static.yaml, an
ionosphere 1.5 times the broadcast set); the receiver run over the four signals (the simulator's fragment)
tracks both bands, and /navigation_ionofree holds fixes over both systems' combinations with the Galileo-GPS
clock bias of the combined fix.  Assisted with the scenario's broadcast ephemerides (RINEX, BGDs included), so
10 s of recording give fixes with both systems from the first seconds."""
import h5py
import numpy as np
import pytest

from receiver.gnss.geodesy import ecef2enu
from receiver.pipeline import run
from receiver.schema import load_receiver_config
from receiver.sim.simulate import simulate, write_broadcast_nav

from repo_paths import CONFIGS

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    d = tmp_path_factory.mktemp("ge")
    scenario = CONFIGS / "scenarios/gps_gal_l5_e5a_static.yaml"
    over = ["time.tow_s=345599.0", "time.duration_s=10.0", "l5.sample_rate_hz=10.5e6", "e5a.sample_rate_hz=10.5e6"]
    simulate(scenario, str(d / "x.bin"), progress=False, overrides=over)
    # assisted (the scenario's broadcast ephemerides, BGDs included, as RINEX): both systems from the start
    write_broadcast_nav(scenario, d / "nav.rnx", over)
    run(load_receiver_config(d / "x.yaml", [("output.path", str(d / "run.h5")),
                                            ("navigation.ephemeris", str(d / "nav.rnx"))]), quiet=True)
    return d


def test_both_pairs_in_one_ionofree_fix(both):
    with h5py.File(both / "run.h5") as h, h5py.File(both / "x.truth.h5") as t:
        assert h.attrs["band_signal"] == "gps_l5,gal_e5a"
        n5, ne = len(set(h["observables_l5/prn"][:].tolist())), len(set(h["observables_e5a/prn"][:].tolist()))
        assert n5 >= 5 and ne >= 4
        g = h["navigation_ionofree"]
        tm, ns = g["time_s"][:], g["n_sats"][:]
        late = tm >= tm[-1] - 2.0
        # the last 2 s: every fix over GPS and Galileo (more satellites than either system has)
        assert late.sum() >= 15 and np.all(ns[late] > max(n5, ne))
        e = ecef2enu(g["ecef"][:][late], t["receiver/ecef"][0])
        assert np.sqrt(np.mean(np.sum(e ** 2, axis=1))) < 1.5
        # the used flags: both bands' observables enter the fixes
        for name in ("observables_l5", "observables_e5a"):
            o = h[name]
            assert np.mean(o["used_in_fix"][:][o["time_s"][:] >= tm[-1] - 2.0]) > 0.9
