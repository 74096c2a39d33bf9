"""Gamma(K, 1/K) quantiles of the detection thresholds (receiver/estimation/stats.py) against scipy."""
import numpy as np
import pytest
from scipy.special import gammainccinv, gammaincinv

from receiver.estimation.stats import gamma_isf, gamma_median


@pytest.mark.slow
@pytest.mark.parametrize("k", [1, 2, 3, 4, 5, 10, 20, 40, 63, 100, 250, 1000, 4096])
def test_integer_shapes_match_scipy(k):
    # the receiver's tail probabilities: pfa / cells (1e-3 / ~4e5 ... 1e-12) and the median
    for q in (1e-300, 1e-30, 1e-12, 1e-3 / 418600, 1e-6, 1e-3, 0.05, 0.3, 0.5):
        ref = float(gammainccinv(k, q) / k)
        assert gamma_isf(q, k) == pytest.approx(ref, rel=1e-13, abs=0)
    assert gamma_median(k) == pytest.approx(float(gammaincinv(k, 0.5) / k), rel=1e-13, abs=0)


def test_tail_probability_of_the_quantile():
    # P(X > x) for Gamma(10, 1/10) from the closed form, at the computed quantile
    k, q = 10, 2.4e-9
    x = gamma_isf(q, k) * k
    tail = np.exp(-x) * sum(x ** i / np.prod(np.arange(1, i + 1, dtype=float)) for i in range(k))
    assert tail == pytest.approx(q, rel=1e-12)


def test_other_shapes_and_upper_probabilities_use_scipy():
    assert gamma_isf(1e-3, 2.5) == float(gammainccinv(2.5, 1e-3) / 2.5)
    assert gamma_median(7.5) == float(gammaincinv(7.5, 0.5) / 7.5)
    assert gamma_isf(0.9, 10) == float(gammainccinv(10, 0.9) / 10)


def test_median_last_axis_equals_numpy():
    from receiver.estimation.stats import median_last_axis
    rng = np.random.default_rng(7)
    cases = [rng.exponential(size=(161, 2600)).astype(np.float32),          # an acquisition grid
             rng.integers(0, 4, size=(5, 64)).astype(np.float32),           # ties
             rng.standard_normal((2, 3, 101)),                              # odd length, float64, 3-D
             np.lib.stride_tricks.sliding_window_view(rng.exponential(size=300), 31),   # strided view
             np.array([[1.0, np.nan, 3.0, 4.0]], np.float32), np.ones((3, 1))]
    for n in range(2, 40):
        cases.append(rng.exponential(size=(3, n)).astype(np.float32))
    for a in cases:
        ref, got = np.median(a, axis=-1), median_last_axis(a)
        assert got.dtype == ref.dtype and got.shape == ref.shape
        np.testing.assert_array_equal(got, ref)
