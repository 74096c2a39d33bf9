"""A weak channel's measurements wait for the end of its DLL hold (issue 31): tracking.weak.dll_hold_ms keeps a
weak channel's DLL at the pull-in bandwidth (4 Hz: ~15 m of code noise at 32 dB-Hz), so navigation.settle_s
counts from the hold's end.  On GPS-SDR-SIM's path-loss recordings the fixes of the first 2 s used those
measurements: 39-103 m errors (tests/system/test_validate_cases.py)."""
import numpy as np

from receiver.navigation.channel import ChannelNav
from receiver.runfile.record import EPOCH_DTYPE, STATE_TRACK
from receiver.schema import load_receiver_config
from receiver.tracking.scalar import Channel

FS = 2.048e6


def _recs(t0, t1):
    t = np.arange(t0, t1, 1e-3)
    r = np.zeros(t.size, EPOCH_DTYPE)
    r["time_s"], r["sample_index"], r["state"] = t, np.round(t * FS), STATE_TRACK
    return r


def test_the_tracking_channel_states_its_hold():
    """A channel opened weak holds for tracking.weak.dll_hold_ms; a strong one, or with the weak mode off, not."""
    cfg = load_receiver_config(None, [("tracking.weak.dll_hold_ms", 1500)])
    assert Channel(3, 500.0, 10.0, 0, cfg.tracking, FS, 0.0, weak=True).dll_hold_s == 1.5
    assert Channel(3, 500.0, 10.0, 0, cfg.tracking, FS, 0.0, weak=False).dll_hold_s == 0.0
    off = load_receiver_config(None, [("tracking.weak.enabled", False)])
    assert Channel(3, 500.0, 10.0, 0, off.tracking, FS, 0.0, weak=True).dll_hold_s == 0.0


def test_settle_counts_from_the_end_of_the_hold():
    """Pull-in ends at 0.3 s; settle 1 s: a strong channel is used from 1.3 s, a weak one (2-s hold) from 3.3 s;
    the hold of a previous track judges that track's epochs after a continuous re-acquisition."""
    strong, weak = ChannelNav(5, 2190, 0.0, FS), ChannelNav(6, 2190, 0.0, FS)
    strong.add(_recs(0.3, 3.5), -1)
    weak.add(_recs(0.3, 3.5), -1, dll_hold_s=2.0)
    for t, s_ok, w_ok in ((1.25, False, False), (1.35, True, False), (3.25, True, False), (3.35, True, True)):
        assert strong.settled(t * FS, 1.0) == s_ok and weak.settled(t * FS, 1.0) == w_ok, t
    weak.tow_ref = 1.0                                   # has time: a continuous track keeps the old records
    weak.resume(continuous=True, settle_s=0.1)
    weak.add(_recs(4.0, 4.5), -1)                         # the new track is not weak
    assert not weak.settled(3.25 * FS, 1.0) and weak.settled(3.4 * FS, 1.0)   # old track: its own hold
    assert not weak.settled(4.05 * FS, 1.0) and weak.settled(4.15 * FS, 1.0)  # new track: 0.1 s, no hold
