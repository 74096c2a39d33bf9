"""The assisted first fix's candidate transmit times (receiver/navigation/assisted_search.py): with GPS and
BeiDou MEO satellites down to the horizon the travel times span more than 20 ms, so no common travel time
puts every satellite's guess within the +/-10 ms that picks its right 20-ms bit; the travel times predicted
from the satellites' mean direction do, at every place tried (the satellites each place sees, from our
simulator's constellation)."""
import numpy as np
import pytest

from receiver.gnss.ephemeris import sat_state, select
from receiver.gnss.geodesy import azel, lla2ecef
from receiver.gnss.rinex import read_rinex_nav
from receiver.navigation.assisted_search import common_guesses, predicted_guesses
from receiver.navigation.engine import DEEP_ORBIT_SQRT_A
from receiver.sim.simulate import write_broadcast_nav

C = 299792458.0
TOW = 345604.0
PLACES = {"tokyo": (35.68, 139.77, 10.0), "reykjavik": (64.15, -21.94, 20.0), "sydney": (-33.87, 151.21, 10.0),
          "sao_paulo": (-23.55, -46.63, 760.0), "nairobi": (-1.29, 36.82, 1700.0), "denver": (39.74, -104.99, 1600.0)}


def _sky(tmp_path, lla):
    """(prns, satellite ECEF 75 ms before TOW, true travel times s) of the GPS and BeiDou MEO satellites above
    the horizon at ``lla`` (BeiDou keys 400 + PRN; its ephemerides in BDT = GPS - 14 s)."""
    nav = tmp_path / "sky.nav"
    write_broadcast_nav("configs/scenarios/gps_bds_static_tokyo.yaml", nav,
                        ["constellation.elevation_mask_deg=0", f"receiver.lat_deg={lla[0]}",
                         f"receiver.lon_deg={lla[1]}", f"receiver.height_m={lla[2]}"])
    rx = lla2ecef(*lla)
    prns, pos, tau = [], [], []
    for letter, key, dt in (("G", 0, 0.0), ("C", 400, 14.0)):
        ephs, _ = read_rinex_nav(nav, (letter,))
        for prn, lst in ephs.items():
            e = select(lst, TOW - dt)
            if e is None or getattr(e, "sqrt_a", 0.0) > DEEP_ORBIT_SQRT_A:
                continue
            p = np.asarray(sat_state(e, TOW - dt - 0.075)[0], float)
            if azel(rx, p)[1] > 0.0:
                prns.append(key + prn)
                pos.append(p)
                tau.append(np.linalg.norm(p - rx) / C)
    return prns, np.array(pos), np.array(tau)


def _all_right(guess, prns, tau):
    """Every satellite's guess within 10 ms of its true transmit time (receiver clock error 0)."""
    return all(abs(guess[p] - (TOW - t)) < 0.010 for p, t in zip(prns, tau))


@pytest.mark.parametrize("place", sorted(PLACES))
def test_predicted_travel_times_resolve_what_a_common_one_cannot(tmp_path, place):
    prns, pos, tau = _sky(tmp_path, PLACES[place])
    assert len(prns) >= 8
    common = [g for g in common_guesses(prns, TOW, set()) if _all_right(g, prns, tau)]
    predicted = [g for g in predicted_guesses(prns, pos, TOW) if _all_right(g, prns, tau)]
    assert predicted, f"{place}: no predicted guess within 10 ms of every satellite"
    if tau.max() - tau.min() > 0.0205:
        assert not common, f"{place}: travel times span {1e3 * np.ptp(tau):.1f} ms, yet a common one fits"
    else:
        assert common, f"{place}: travel times span {1e3 * np.ptp(tau):.1f} ms and no common one fits"


def test_a_failing_first_fix_search_is_retried_every_epoch_then_once_a_second():
    from receiver.navigation.assisted_search import Retries
    r = Retries(eager_s=5.0, every_s=1.0)
    tried = []
    for k in range(130):                       # 10-Hz navigation epochs from 1.3 s, every search failing
        t = 1.3 + 0.1 * k
        if r.due(t):
            tried.append(round(t, 1))
            r.done(t, found=False)
    assert tried[:51] == [round(1.3 + 0.1 * k, 1) for k in range(51)]        # 1.3 .. 6.3 s: every epoch
    assert all(abs(b - a - 1.0) < 0.11 for a, b in zip(tried[50:], tried[51:]))   # then about once a second
    assert len(tried) == 51 + 7
    r.done(20.0, found=True)
    assert r.due(20.1)
