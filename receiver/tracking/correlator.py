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


CARR_TABLE_BITS = 10
_N_TABLE = 1 << CARR_TABLE_BITS
# carrier wipe-off table exp(-j 2 pi phase) at bin centres (phase error <= 2 pi / 2048, mean zero)
_COS = np.cos(2 * np.pi * (np.arange(_N_TABLE) + 0.5) / _N_TABLE).astype(np.float32)
_SIN = np.sin(2 * np.pi * (np.arange(_N_TABLE) + 0.5) / _N_TABLE).astype(np.float32)
_FP = 4294967296.0     # 2**32: fixed-point scale of the NCO accumulators (per cycle / per chip)


@njit(cache=True, fastmath=True, nogil=True)
def correlate(samples, off, n, code_ext, code_phase, code_step, half_el, carr_phase, carr_step):
    """Fast path. Returns (E, P, L, P_first_half, P_second_half) as complex128.

    Both NCOs are 32.32 fixed-point accumulators (like hardware NCOs): the carrier phase indexes a
    1024-entry cos/sin table with its top 10 fractional bits, the code phase indexes the extended code
    with its integer part.  Resolution: 2^-32 cycle and chip per sample.
    """
    cos_t = _COS
    sin_t = _SIN
    ph = np.int64((carr_phase - np.floor(carr_phase)) * _FP)
    dph = np.int64(np.round(carr_step * _FP))
    cp = np.int64((code_phase + CODE_PAD) * _FP)
    dcp = np.int64(np.round(code_step * _FP))
    hel = np.int64(half_el * _FP)
    shift = 32 - CARR_TABLE_BITS
    mask = _N_TABLE - 1
    # float32 accumulators (mixing float32 products into float64 sums costs 2.5x); the rounding error
    # over a 20 ms epoch is orders of magnitude below the thermal noise of the sums
    zero = np.float32(0.0)
    er = zero
    ei = zero
    pr = zero
    pi_ = zero
    lr = zero
    li = zero
    half = n // 2
    p1r = zero
    p1i = zero
    # two passes (first half, second half) instead of a test for the half-way sample in every iteration
    k0 = 0
    for part in range(2):
        k1 = half if part == 0 else n
        for k in range(k0, k1):
            idx = (ph >> shift) & mask
            c = cos_t[idx]
            s = sin_t[idx]
            x = samples[off + k]
            xr = x.real
            xi = x.imag
            mr = xr * c + xi * s
            mi = xi * c - xr * s
            ce = code_ext[(cp + hel) >> 32]
            cpp = code_ext[cp >> 32]
            cl = code_ext[(cp - hel) >> 32]
            er += mr * ce
            ei += mi * ce
            pr += mr * cpp
            pi_ += mi * cpp
            lr += mr * cl
            li += mi * cl
            ph += dph
            cp += dcp
        if part == 0:
            p1r = pr
            p1i = pi_
        k0 = half
    return (complex(er, ei), complex(pr, pi_), complex(lr, li), complex(p1r, p1i),
            complex(pr - p1r, pi_ - p1i))


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
