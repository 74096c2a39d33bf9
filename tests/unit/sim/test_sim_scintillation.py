"""Cornell-model scintillation: S4, sigma_phi and decorrelation time of the generated series."""
import math

import numpy as np
import pytest

from receiver.sim.scintillation import Scintillation, butterworth_cutoff_hz, rician_k, s4_index, sigma_phi

DT = 1e-3


def _series(s4, sp, tau0, seconds, seed=1, chunk=7919):
    gen = Scintillation(s4, sp, tau0, DT, np.random.default_rng(seed))
    n = int(round(seconds / DT))
    parts, got = [], 0
    while got < n:                       # odd chunk sizes: streaming must not matter
        a, p = gen.take(min(chunk, n - got))
        parts.append((a, p))
        got += a.size
    return np.concatenate([a for a, _ in parts]), np.concatenate([p for _, p in parts])


@pytest.mark.parametrize("s4,sp", [(0.3, 0.25), (0.9, 0.75)])
@pytest.mark.parametrize("tau0", [0.3, 1.0])
def test_s4_and_sigma_phi_match_targets_over_60s(s4, sp, tau0):
    for seed in (1, 2):
        amp, ph = _series(s4, sp, tau0, 60.0, seed)
        assert abs(s4_index(amp ** 2) / s4 - 1.0) < 0.10
        assert abs(sigma_phi(ph) / sp - 1.0) < 0.10
        assert abs(np.mean(amp ** 2) - 1.0) < 0.05            # unit mean power


def test_later_windows_and_continuity():
    amp, ph = _series(0.6, 0.5, 0.5, 180.0, seed=5)
    w = 60000
    for k in range(3):
        assert abs(s4_index(amp[k * w:(k + 1) * w] ** 2) / 0.6 - 1.0) < 0.10
        assert abs(sigma_phi(ph[k * w:(k + 1) * w]) / 0.5 - 1.0) < 0.10
    # smooth: a 1 ms step is small compared with the fluctuations (tau0 = 0.5 s)
    assert np.max(np.abs(np.diff(amp))) < 0.05
    assert np.max(np.abs(np.diff(ph))) < 0.05


def test_decorrelation_time():
    """The diffuse field's autocorrelation falls to 1/e at tau0 (weak scintillation: amplitude and
    phase fluctuations are its two quadratures)."""
    tau0 = 0.2
    amp, ph = _series(0.1, 0.1, tau0, 600.0, seed=3)
    x = ph - ph.mean()
    lags = np.arange(0, int(3 * tau0 / DT))
    spec = np.fft.rfft(x, 2 * x.size)
    ac = np.fft.irfft(spec * np.conj(spec))[:lags.size]
    ac /= ac[0]
    lag_e = np.argmax(ac < math.exp(-1)) * DT
    assert abs(lag_e / tau0 - 1.0) < 0.15


def test_rician_k_and_cutoff():
    # S4^2 = (1 + 2K) / (1 + K)^2
    for s4 in (0.2, 0.5, 0.9):
        k = rician_k(s4)
        assert math.isclose((1 + 2 * k) / (1 + k) ** 2, s4 * s4, rel_tol=1e-12)
    assert math.isclose(butterworth_cutoff_hz(1.0), math.sqrt(2) * 1.23964643681047 / (2 * math.pi))


def test_no_scintillation_is_identity():
    amp, ph = _series(0.0, 0.0, 1.0, 5.0)
    assert np.allclose(amp, 1.0) and np.allclose(ph, 0.0)
