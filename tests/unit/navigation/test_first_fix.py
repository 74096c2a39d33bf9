"""navigation.first_fix_max_pdop: the first fix of a run (nothing checks it; the aiding and the filters start
from it) needs a better geometry than the fixes after it (navigation.max_pdop)."""
from itertools import combinations

import numpy as np

from receiver.gnss.geodesy import lla2ecef
from receiver.navigation.engine import NavigationEngine
from receiver.navigation.pvt import NavSolver
from receiver.schema import load_receiver_config
from test_navigation_pvt import RX_LLA, WEEK, brdc, cfg, simulate  # noqa: F401  (brdc: fixture)


def test_a_weak_geometry_waits_for_a_good_one_only_at_the_first_fix(brdc):
    ephs, iono = brdc
    rx = lla2ecef(*RX_LLA)
    rx_tow, obs = simulate(ephs, iono, rx, bias_m=100.0, drift_mps=0.0, sigma_m=2.0, seed=3)
    probe = NavSolver(cfg(max_pdop=1e9))
    subsets = [list(sub) for n in (4, 5) for sub in combinations(obs, n)]
    by_pdop = [(probe.fix(WEEK, rx_tow, sub, ephs, iono, x0=rx), sub) for sub in subsets]
    weak = [sub for f, sub in by_pdop if f is not None and 8.0 < f.pdop < 20.0]
    good = [sub for f, sub in by_pdop if f is not None and f.pdop < 4.0]
    assert weak and good
    nav = load_receiver_config(None, []).navigation
    eng = NavigationEngine(nav, 2.6e6, 0.0, 0)
    eng.x0 = rx + 100.0
    assert nav.first_fix_max_pdop == 8.0 and nav.max_pdop == 20.0
    assert eng._solve(WEEK, rx_tow, 1.0, weak[0], ephs) is None          # first fix: refused
    first = eng._solve(WEEK, rx_tow, 1.0, good[0], ephs)
    assert first is not None and np.linalg.norm(first.ecef - rx) < 20.0
    eng.last_fix = (2.6e6, first)
    later = eng._solve(WEEK, rx_tow, 1.1, weak[0], ephs)                 # after it: max_pdop 20 applies
    assert later is not None and 8.0 < later.pdop < 20.0
