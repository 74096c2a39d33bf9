"""Correlators: the numba fast path and a plain-numpy reference.

One call correlates ``n`` samples against early/prompt/late replicas of a periodic code after carrier
wipe-off by a numerically controlled oscillator (NCO).  The code NCO has a fractional phase, so any
sample rate works (2.6 MS/s is not a multiple of 1.023 Mcps).  The prompt is also returned in two halves
(first and second half of the samples) for frequency discriminators.

Conventions: carrier wipe-off multiplies by exp(-j 2 pi phase(k)) with
phase(k) = carr_phase + k * carr_step (cycles); code chip of sample k is
code_phase + k * code_step (chips); early/late are offset by +/- half_el chips.
"""
import numpy as np
from numba import njit

CODE_PAD = 4   # wrap-around chips stored before the code in extended-code arrays


def extend_code(code: np.ndarray, periods: int) -> np.ndarray:
    """Code repeated `periods`+1 times with CODE_PAD chips of wrap in front (for E/L offsets)."""
    reps = np.tile(code, periods + 2)
    return np.ascontiguousarray(reps[len(code) - CODE_PAD:], dtype=np.float32)


@njit(cache=True, fastmath=True)
def correlate(samples, off, n, code_ext, code_phase, code_step, half_el, carr_phase, carr_step):
    """Fast path. Returns (E, P, L, P_first_half, P_second_half) as complex128."""
    lo = np.exp(-2j * np.pi * carr_phase)
    rot = np.exp(-2j * np.pi * carr_step)
    e = 0j
    p = 0j
    l = 0j
    p1 = 0j
    half = n // 2
    base = code_phase + CODE_PAD
    for k in range(n):
        if k == half:
            p1 = p
        m = samples[off + k] * lo
        lo *= rot
        chip = base + k * code_step
        e += m * code_ext[int(chip + half_el)]
        p += m * code_ext[int(chip)]
        l += m * code_ext[int(chip - half_el)]
    return e, p, l, p1, p - p1


def correlate_reference(samples, off, n, code, code_phase, code_step, half_el, carr_phase, carr_step):
    """Plain-numpy reference of :func:`correlate` (for tests and for clarity)."""
    k = np.arange(n)
    x = samples[off:off + n].astype(np.complex128) * np.exp(-2j * np.pi * (carr_phase + k * carr_step))
    chips = code_phase + k * code_step
    L = len(code)

    def rep(offset):
        return code[np.floor(chips + offset).astype(np.int64) % L]

    e, p, l = (np.sum(x * rep(o)) for o in (half_el, 0.0, -half_el))
    half = n // 2
    p1 = np.sum(x[:half] * rep(0.0)[:half])
    return e, p, l, p1, p - p1
