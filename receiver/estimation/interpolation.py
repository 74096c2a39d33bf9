"""Interpolation helpers shared by the simulator and the evaluation of runs against truth."""
from __future__ import annotations

import numpy as np


def hermite(xn, yn, dyn, x, deriv=False):
    """Cubic Hermite interpolation through nodes xn (increasing) with values yn and slopes dyn.

    yn / dyn may have trailing dimensions (n, ...).  With deriv, the derivative of the interpolant."""
    xn = np.asarray(xn, dtype=float)
    k = np.clip(np.searchsorted(xn, x, side="right") - 1, 0, xn.size - 2)
    h = xn[k + 1] - xn[k]
    s = (x - xn[k]) / h
    s2 = s * s
    if deriv:
        c = (6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s)
    else:
        s3 = s2 * s
        c = (2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2)
    extra = (slice(None),) + (None,) * (np.ndim(yn) - 1)
    c = [ci[extra] for ci in c]
    hh = h[extra]
    out = c[0] * yn[k] + c[1] * hh * dyn[k] + c[2] * yn[k + 1] + c[3] * hh * dyn[k + 1]
    return out / hh if deriv else out


def interp_columns(xn, yn, x):
    """Linear interpolation (``np.interp``, end values held) of every column of ``yn`` (n,) or (n, k) at
    ``x``; returns (m,) or (m, k)."""
    yn = np.asarray(yn, dtype=float)
    if yn.ndim == 1:
        return np.interp(x, xn, yn)
    return np.stack([np.interp(x, xn, yn[:, k]) for k in range(yn.shape[1])], axis=1)
