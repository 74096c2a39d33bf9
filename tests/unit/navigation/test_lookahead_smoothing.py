"""Fixed-lag carrier smoothing (navigation.lookahead_s): an epoch's pseudorange smoothed with the fit of its carrier
arc as it stands lookahead_s later.  A weak channel's code error (a 0.5-Hz DLL at ~30 dB-Hz: metres, correlated
over a second) is averaged by a causal Hatch fit only over the epochs before it, so the first seconds of an arc
carry most of it; with the later epochs in the fit they are as good as the rest.  An arc that ends (a slip, a
lost lock) keeps its own fit: the epochs before the restart never see the code of the next arc."""
import numpy as np
from synth import gauss_markov

from receiver.gnss.signals import C_LIGHT, LAMBDA_L1
from receiver.navigation.channel import ChannelNav
from receiver.schema import load_receiver_config

FS = 2.048e6
RATE = 10.0
WINDOW = 1000          # navigation.smoothing_s 100 s at 10 Hz
LAG = int(10 * RATE)   # lookahead_s 10


def _arc(seed, slip_at_s=None, seconds=20.0):
    """One channel over `seconds`: (t, causal smoothed error, look-ahead smoothed error, raw code error) in m.
    Range 2.2e7 m + 400 m/s t; code error 5 m with 1 s correlation; a carrier slip of 40 m at slip_at_s (the
    fit restarts there).  As the engine does: each epoch keeps a reference to the fit it was smoothed with
    (the fit goes on growing while its arc lasts) and is smoothed again LAG epochs later."""
    rng = np.random.default_rng(seed)
    t = np.arange(1, int(seconds * RATE)) / RATE
    err = gauss_markov(t.size, 5.0, 1.0, RATE, rng)
    rng_m = 2.2e7 + 400.0 * t
    slip = np.where(t >= slip_at_s, 40.0, 0.0) if slip_at_s is not None else np.zeros(t.size)
    ch = ChannelNav(7, 2190, 0.0, FS)
    causal = np.full(t.size, np.nan)
    late = np.full(t.size, np.nan)
    kept = []                                  # (s, txrel, phase, the fit object) of every epoch
    for j, tj in enumerate(t):
        s = tj * FS
        txrel = tj - (rng_m[j] + err[j]) / C_LIGHT
        phase = -(rng_m[j] + slip[j]) / LAMBDA_L1 + 77.5
        ch.smooth_update(s, txrel, phase, WINDOW, 0, 30.0)
        causal[j] = C_LIGHT * (tj - ch.smooth_value(s, txrel, phase, None)) - rng_m[j]
        kept.append((s, txrel, phase, ch.hatch))
        k = j - LAG
        if k >= 0:
            sk, txk, phk, h = kept[k]
            late[k] = C_LIGHT * (t[k] - ch.smooth_value(sk, txk, phk, None, h)) - rng_m[k]
    return t, causal, late, err


def test_the_first_seconds_of_an_arc_get_the_later_accuracy():
    """Over 5 seeds: in the first 3 s of an arc the causal fit's error is close to the raw code's; with 10 s
    of look-ahead it is at least halved, and it is never worse than the causal error over the whole arc."""
    early_c, early_l, all_c, all_l = [], [], [], []
    for seed in range(5):
        t, causal, late, raw = _arc(seed)
        ok = np.isfinite(late)
        first = ok & (t < 3.0)
        early_c.append(causal[first])
        early_l.append(late[first])
        all_c.append(causal[ok])
        all_l.append(late[ok])
    rms = lambda parts: float(np.sqrt(np.mean(np.concatenate(parts) ** 2)))
    assert rms(early_c) > 2.0                          # the premise: the causal start is metres off
    assert rms(early_l) < 0.5 * rms(early_c)
    assert rms(all_l) < rms(all_c)


def test_an_arc_that_ends_keeps_its_own_fit():
    """A 40-m carrier slip at 6 s restarts the fit: the epochs before it, released 10 s later, are smoothed by
    the first arc's fit alone (no 40-m jump leaks back into them); after the slip the new arc is used."""
    t, causal, late, raw = _arc(3, slip_at_s=6.0)
    before = np.isfinite(late) & (t < 5.9)
    assert np.max(np.abs(late[before])) < 10.0
    after = np.isfinite(late) & (t > 6.5)
    assert np.max(np.abs(late[after])) < 10.0


def test_lookahead_is_off_by_default():
    """The default receiver's fixes are a real-time receiver's (causal)."""
    assert load_receiver_config(None, []).navigation.lookahead_s == 0.0


def test_epochs_are_held_for_the_lag_and_released_in_order():
    """FixedLag holds every epoch (with or without a fix) lag_s and gives them back in epoch order; the end of
    the input releases the rest; epochs without a context (no fix) come back as they were."""
    from receiver.navigation.lookahead import FixedLag
    fl = FixedLag(1.0, solver=None, max_pdop=8.0, fix_row=None)
    out = []
    for k in range(25):                         # 10 Hz epochs, 2.4 s
        out += fl.hold(0.1 * k, None if k % 7 == 0 else ("fix", k), [("obs", k)], None)
        assert all(o[0][1] <= k - 10 for _, o in out)          # nothing younger than 1 s has come back
    assert len(out) == 15
    out += fl.release()
    assert [o[0][1] for _, o in out] == list(range(25))
    assert [f for f, _ in out if f is not None] == [("fix", k) for k in range(25) if k % 7]
    assert FixedLag.for_run(load_receiver_config(None, []).navigation, None, None, None, None) is None
