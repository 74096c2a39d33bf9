"""Gamma(K, 1/K) quantiles for the detection thresholds (acquisition, re-acquisition, tone detection).

The same values as ``scipy.stats.gamma.isf(q, k, scale=1/k)`` and ``gamma.median(k, scale=1/k)`` (bit for
bit: scipy.stats evaluates them with these special functions), without importing scipy.stats, which costs
~0.5 s at start-up.
"""
from __future__ import annotations

from scipy.special import gammainccinv, gammaincinv


def gamma_isf(q: float, k: float) -> float:
    """Upper-tail quantile of Gamma(k, scale 1/k): P(X > x) = q."""
    return float(gammainccinv(k, q) * (1.0 / k))


def gamma_median(k: float) -> float:
    """Median of Gamma(k, scale 1/k)."""
    return float(gammaincinv(k, 0.5) * (1.0 / k))
