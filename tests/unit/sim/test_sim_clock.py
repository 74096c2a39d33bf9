"""Receiver clock: Allan deviation of the generated clock against the h-parameters' theory."""
import math

import numpy as np
import pytest

from receiver.sim.clock import CLOCK_PRESETS, ClockGenerator, allan_deviation, allan_variance_theory

DT = 1e-3


def _bias(h, seconds, seed, freq_error=0.0, chunk=100000, corner=None):
    gen = ClockGenerator(0.0, freq_error, *h, DT, seconds, np.random.default_rng(seed),
                         white_fm_corner_hz=corner)
    n = int(seconds / DT)
    parts = [gen.take(min(chunk, n - k)) for k in range(0, n, chunk)]
    return np.concatenate([b for b, _ in parts]), np.concatenate([y for _, y in parts])


@pytest.mark.slow
@pytest.mark.parametrize("name,h,corner", [
    ("tcxo", CLOCK_PRESETS["tcxo"], None),
    ("tcxo band-limited", CLOCK_PRESETS["tcxo"], 1.0),
    ("ocxo", CLOCK_PRESETS["ocxo"], None),
    ("flicker", (0.0, 1e-20, 0.0), None),
])
def test_allan_deviation_matches_theory(name, h, corner):
    b, _ = _bias(h, 1000.0, seed=3, corner=corner)
    taus = np.array([0.01, 0.1, 1.0, 10.0])
    m = np.round(taus / DT).astype(int)
    adev = allan_deviation(b, DT, m)
    theory = np.sqrt(allan_variance_theory(taus, *h, white_fm_corner_hz=corner))
    # overlapping ADEV over 1000 s: >= ~50 degrees of freedom up to tau = 10 s (random walk and flicker
    # dominated taus are the least certain)
    tol = np.array([0.05, 0.05, 0.12, 0.25])
    assert np.all(np.abs(adev / theory - 1.0) < tol), (adev / theory)


def test_band_limited_white_fm_is_quieter_at_short_tau_only():
    h = CLOCK_PRESETS["tcxo"]
    full = np.sqrt(allan_variance_theory(np.array([0.001, 0.01, 100.0]), *h))
    lim = np.sqrt(allan_variance_theory(np.array([0.001, 0.01, 100.0]), *h, white_fm_corner_hz=1.0))
    assert lim[0] < 0.1 * full[0] and lim[1] < 0.3 * full[1] and abs(lim[2] / full[2] - 1) < 0.01


def test_bias_integrates_frequency_error():
    b, y = _bias((0.0, 0.0, 0.0), 10.0, seed=1, freq_error=2e-6)
    t = np.arange(b.size) * DT
    assert np.allclose(y, 2e-6)
    assert np.allclose(b, t * 2e-6 / (1 + 2e-6), atol=1e-15)


def test_streaming_is_chunk_independent():
    h = CLOCK_PRESETS["tcxo"]
    b1, y1 = _bias(h, 20.0, seed=9, chunk=20000)
    b2, y2 = _bias(h, 20.0, seed=9, chunk=20000)
    assert np.array_equal(b1, b2) and np.array_equal(y1, y2)
    assert y1[0] == pytest.approx(0.0, abs=5 * math.sqrt(h[0] / (2 * DT)))
