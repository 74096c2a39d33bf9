"""Re-acquisition windows after an outage in a turn (receiver/tracking/channels.py, issue 31): the windows
hold the receiver's measured acceleration, and every other search uses the window that holds for any
acceleration (velocity change <= 2 x the speed bound); satellites the narrow searches do not find join the
cold round-robin after COLD_FALLBACK_S."""
from types import SimpleNamespace

import numpy as np

from receiver.config import build
from receiver.schema import RECEIVER_SCHEMA
from receiver.gnss.signals import CA_CODE_LEN, GPS_L1CA, C_LIGHT, L1_HZ
from receiver.tracking import channels as CH
from receiver.tracking.channels import ChannelManager

from synth import make_signal

FS = 2.6e6
LAMBDA = C_LIGHT / L1_HZ
AGE_S = 8.0
D0 = 1500.0                     # Doppler of the last good state (Hz)


class _Reader:
    """The file at the search point: the satellite where the turn has carried it (any read start)."""
    first, end = 0, int(60 * FS)

    def __init__(self, x):
        self.x = x

    def read(self, start, n):
        return self.x[:n]


class _Nav:
    """The navigation engine's part the manager uses: the last fix, no ephemeris (no line of sight)."""

    def __init__(self):
        self.last_fix, self.channels = None, {}

    def satellite_los(self, prn, s):
        return None

    def resume(self, *a, **k):
        pass

    def suspend(self, prn):
        pass


def _manager(x, nav=None):
    cfg = build(RECEIVER_SCHEMA, {})
    return ChannelManager(cfg, _Reader(x), nav, FS, 0.0, GPS_L1CA, acquire=None)


def _lost_sat(mgr, s_search):
    sat = mgr._sat(7)
    sat.state, sat.lost_at, sat.ref = "reacquiring", 0.0, (0.0, 0.0123, D0, 0.0, -1)
    dop, tx = mgr.predict(sat, s_search)
    return sat, dop, (tx * 1e3 % 1.0) * CA_CODE_LEN


def _signal(dop_true, cp_true):
    return make_signal([{"prn": 7, "doppler_hz": dop_true, "code_phase_chips": cp_true, "cn0_dbhz": 44.0}],
                       FS, 0.03, seed=3)


def test_narrow_window_misses_the_turn_the_speed_bounded_window_finds_it():
    """8 s in a turn: the line-of-sight velocity changed by 85 m/s (450 Hz) and the range by 880 m more
    than the constant-velocity prediction; the acceleration-bounded window (5 m/s^2: +/- 250 Hz, +/- 2.05
    chips) misses it, the next search's speed-bounded window (+/- 670 Hz, +/- 4.8 chips) finds it."""
    s = AGE_S * FS
    mgr = _manager(None)
    sat, dop, cp = _lost_sat(mgr, s)
    off_chips = 880.0 / (C_LIGHT / 1.023e6)
    mgr.reader = _Reader(_signal(dop + 450.0, (cp - off_chips) % CA_CODE_LEN))
    assert mgr._hot(sat, int(s)) is False
    assert 7 not in mgr.channels
    assert mgr._hot(sat, int(s)) is True
    ch = mgr.channels[7]
    assert abs(ch.doppler_hz - (dop + 450.0)) < 15.0
    assert sat.state == "tracking"


def test_measured_acceleration_widens_the_narrow_window():
    """The fixes before the outage show a 12 m/s^2 turn at 50 m/s: the first (acceleration-bounded) search
    already holds the satellite."""
    s = AGE_S * FS
    nav = _Nav()
    mgr = _manager(None, nav)
    for k in range(16):                     # 0.2-s fixes over 3 s before the loss: 12 m/s^2 centripetal
        t = -3.0 + 0.2 * k
        w = 12.0 / 50.0
        v = 50.0 * np.array([np.cos(w * t), np.sin(w * t), 0.0])
        nav.last_fix = (t * FS, SimpleNamespace(velocity_ecef=v, clock_drift_mps=0.0))
        mgr._note_fix()
    accel, speed = mgr._dynamics(0.0)
    assert abs(accel - CH.DYN_MARGIN * 12.0) < 0.5 and abs(speed - CH.DYN_MARGIN * 50.0) < 0.5
    sat, dop, cp = _lost_sat(mgr, s)
    off_chips = 880.0 / (C_LIGHT / 1.023e6)
    mgr.reader = _Reader(_signal(dop + 450.0, (cp - off_chips) % CA_CODE_LEN))
    assert mgr._hot(sat, int(s)) is True


def test_narrow_searches_in_vain_join_the_cold_round_robin():
    """A satellite re-acquired in vain for more than COLD_FALLBACK_S is among the cold search's PRNs (its
    prediction may be wrong); with fewer than 4 channels the cold searches come every STARVED_COLD_S."""
    picked = []

    def acquire(cfg, reader, start, prns, **kw):
        picked.append((start, list(prns)))
        return []

    cfg = build(RECEIVER_SCHEMA, {"acquisition": {"prns": [3, 7, 9]}})
    mgr = ChannelManager(cfg, _Reader(np.zeros(100000, np.complex64)), None, FS, 0.0, GPS_L1CA, acquire)
    mgr._next_cold = 0
    sat = mgr._sat(7)
    sat.state, sat.lost_at, sat.ref = "reacquiring", 0.0, (0.0, 0.0, D0, 0.0, -1)
    mgr._cold(0, int(1.0 * FS))                             # 1 s after the loss: still narrow only
    assert picked[-1][1] == [3, 9]
    assert mgr._next_cold == int(CH.STARVED_COLD_S * FS)     # no channel: the next attempt soon
    mgr._cold(int(4.0 * FS), int(4.5 * FS))                  # 4.5 s: cold as well
    assert 7 in picked[-1][1]
