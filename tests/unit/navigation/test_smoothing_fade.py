"""Carrier smoothing through a fade (issue 31): a channel handed to the weak loops keeps its carrier-smoothing fit
over its lock gap, and its weak code enters the fit with a weight proportional to the C/N0, so the smoothed
range stays at the strong signal's accuracy through 8 s at 24 dB-Hz and is not pulled off after it."""
import numpy as np
from synth import gauss_markov

from receiver.gnss.signals import C_LIGHT, LAMBDA_L1
from receiver.navigation.channel import ChannelNav

FS = 2.6e6
RATE = 10.0
WINDOW = 1000          # navigation.smoothing_s 100 s at 10 Hz


def _run(gap=(6.0, 6.3), fade=(6.0, 14.0)):
    """Smoothed-range errors (m) of one channel: 45 dB-Hz (code 0.5 m), 24 dB-Hz in the fade (code 15 m with
    0.5 s correlation: a 0.5-Hz DLL), no lock (no update) in the gap; range 2e7 m + 300 m/s t."""
    rng = np.random.default_rng(4)
    t = np.arange(1, int(22 * RATE)) / RATE
    weak = (t >= fade[0]) & (t < fade[1])
    err = np.where(weak, gauss_markov(t.size, 15.0, 0.5, RATE, rng), rng.normal(scale=0.5, size=t.size))
    rng_m = 2e7 + 300.0 * t
    ch = ChannelNav(5, 2190, 0.0, FS)
    ch.locked = True
    out = np.full(t.size, np.nan)
    for k, tk in enumerate(t):
        if gap[0] <= tk < gap[1]:
            continue
        s = tk * FS
        txrel = tk - (rng_m[k] + err[k]) / C_LIGHT
        phase = -rng_m[k] / LAMBDA_L1 + 1234.25
        ch.smooth_update(s, txrel, phase, WINDOW, 0, 24.0 if weak[k] else 45.0)
        out[k] = C_LIGHT * (tk - ch.smooth_value(s, txrel, phase, None)) - rng_m[k]
    return t, out, err


def test_smoothing_carries_the_strong_accuracy_through_a_fade():
    t, sm, raw = _run()
    fade = (t > 6.3) & (t < 14.0)
    after = (t > 14.5)
    assert np.sqrt(np.mean(raw[fade] ** 2)) > 10.0            # the raw weak code (the test's premise)
    assert np.sqrt(np.mean(sm[fade] ** 2)) < 2.0
    assert np.max(np.abs(sm[after])) < 1.0


def test_a_long_lock_gap_restarts_the_fit():
    """A lock gap longer than SMOOTH_GAP_S (3 s here) restarts the fit: after it the smoothed range is the raw
    code again at first (15 m class errors in the fade)."""
    t, sm, raw = _run(gap=(6.0, 9.0))
    first = (t >= 9.0) & (t < 9.15)          # (the fit needs 3 epochs)
    np.testing.assert_allclose(sm[first], raw[first], atol=1e-3)
