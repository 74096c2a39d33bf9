"""Correlators: the numba fast path (block-vectorised) and a plain-numpy reference.

One call correlates ``n`` samples against early/prompt/late replicas of a periodic code after carrier
wipe-off by a numerically controlled oscillator (NCO).  The code NCO has a fractional phase, so any
sample rate works (2.6 MS/s is not a multiple of 1.023 Mcps).  The prompt is also returned in two halves
(first and second half of the samples) for frequency discriminators.

Conventions: carrier wipe-off multiplies by exp(-j 2 pi phase(k)) with
phase(k) = carr_phase + k * carr_step (cycles); code chip of sample k is
code_phase + k * code_step (chips); early/late are offset by +/- half_el chips.
"""
import math

import numpy as np
from numba import njit

CODE_PAD = 4   # wrap-around chips stored before the code in extended-code arrays


def extend_code(code: np.ndarray, periods: int) -> np.ndarray:
    """Code repeated `periods`+1 times with CODE_PAD chips of wrap in front (for E/L offsets)."""
    reps = np.tile(code, periods + 2)
    return np.ascontiguousarray(reps[len(code) - CODE_PAD:], dtype=np.float32)


_FP = 4294967296.0     # 2**32: fixed-point scale of the code NCO accumulator (per chip)

#: samples per correlation block: the carrier table and the float32 partial sums cover one block (the
#: blocks' sums are turned by the carrier phasor at their first sample and added in float64)
BLOCK = 512


@njit(cache=True, nogil=True)
def workspace():
    """Scratch array of :func:`correlate_ws` (allocated once per block of epochs, not per epoch): the
    carrier table (2, BLOCK) and a 32-entry fine table (2, 32)."""
    return np.empty((2, BLOCK + 32), np.float32)


@njit(cache=True, fastmath=True, nogil=True)
def _block_sums(xs, rr, ri, code_ext, cp, dcp, hel, sh, m):
    """One block's float32 sums (E, P, L; re, im) of the samples xs wiped off by the carrier table
    rr + j ri; the code NCO cp (32.32 fixed point) advances by dcp per sample, early / late at +/- hel; the
    chip index is cp >> sh (sh = 32).  Compiled twice: with uint64 cp/dcp/hel/sh (indices numba need not
    test for negative values: 3 fewer operations per lookup; the kernel's case) and with int64 (a code
    phase outside code_ext wraps as a numpy index would).  (float32 sums: mixing float32 products into
    float64 sums costs 2.5x; a block's rounding is far below the noise.)"""
    zero = np.float32(0.0)
    er = zero
    ei = zero
    pr = zero
    pi_ = zero
    lr = zero
    li = zero
    for k in range(m):
        x = xs[k]
        c = rr[k]
        s = ri[k]
        yr = x.real * c - x.imag * s
        yi = x.real * s + x.imag * c
        ce = code_ext[(cp + hel) >> sh]
        cq = code_ext[cp >> sh]
        cl = code_ext[(cp - hel) >> sh]
        er += yr * ce
        ei += yi * ce
        pr += yr * cq
        pi_ += yi * cq
        lr += yr * cl
        li += yi * cl
        cp += dcp
    return er, ei, pr, pi_, lr, li


@njit(cache=True, fastmath=True, nogil=True)
def correlate_ws(samples, off, n, code_ext, code_phase, code_step, half_el, carr_phase, carr_step, ws):
    """Fast path (block-vectorised). Returns (E, P, L, P_first_half, P_second_half) as complex128.

    Carrier wipe-off by a table rot[k] = exp(-j 2 pi k carr_step), k < BLOCK (float32, from a 32-entry
    fine table and a float64 coarse recurrence), so one block's work is a single loop of float32
    multiply-adds that the compiler vectorises; each block's sums are then turned by the carrier phasor
    exp(-j 2 pi phase) at the block's first sample (float64) and added in float64.  The code NCO is a 32.32
    fixed-point accumulator (like a hardware NCO; resolution 2^-32 chip per sample) whose integer part
    indexes the extended code for the early, prompt and late chips.  ``ws``: :func:`workspace`.
    """
    cp0 = np.int64((code_phase + CODE_PAD) * _FP)
    dcp = np.int64(np.round(code_step * _FP))
    hel = np.int64(half_el * _FP)
    half = n // 2
    # ---- carrier table: rot[k] = fine[k % 32] x coarse[k // 32]
    nt = min(n, BLOCK)
    a1 = -2.0 * math.pi * carr_step
    w1r = math.cos(a1)
    w1i = math.sin(a1)
    w32r = math.cos(32.0 * a1)
    w32i = math.sin(32.0 * a1)
    rr = ws[0]
    ri = ws[1]
    zr = 1.0
    zi = 0.0
    for i in range(32):
        rr[BLOCK + i] = zr
        ri[BLOCK + i] = zi
        zr, zi = zr * w1r - zi * w1i, zr * w1i + zi * w1r
    zr = 1.0
    zi = 0.0
    for g in range((nt + 31) >> 5):
        gr = np.float32(zr)
        gi = np.float32(zi)
        for i in range(32):
            fr = rr[BLOCK + i]
            fi = ri[BLOCK + i]
            rr[g * 32 + i] = gr * fr - gi * fi
            ri[g * 32 + i] = gr * fi + gi * fr
        zr, zi = zr * w32r - zi * w32i, zr * w32i + zi * w32r
    ph0 = carr_phase - math.floor(carr_phase)
    # every code index of the epoch inside code_ext (always, for the kernel's code phases): unsigned
    # indices, which numba does not test for negative values (3 fewer operations per lookup)
    in_range = (cp0 - hel) >= 0 and ((cp0 + hel + (n - 1) * dcp) >> 32) < code_ext.shape[0]
    acc = np.zeros(8)        # E, P, L (re, im) and the first half of P, float64
    # two segments (first half, second half) split the blocks at the half-way sample
    for seg in range(2):
        s0 = 0 if seg == 0 else half
        s1 = half if seg == 0 else n
        k0 = s0
        while k0 < s1:
            m = min(BLOCK, s1 - k0)
            xs = samples[off + k0:off + k0 + m]      # a view: contiguous loads (samples[off + k] would
            cp = cp0 + k0 * dcp                      # test off + k for a negative index and gather)
            if in_range:
                er, ei, pr, pi_, lr, li = _block_sums(xs, rr, ri, code_ext, np.uint64(cp), np.uint64(dcp),
                                                      np.uint64(hel), np.uint64(32), m)
            else:
                er, ei, pr, pi_, lr, li = _block_sums(xs, rr, ri, code_ext, cp, dcp, hel, np.int64(32), m)
            # the block's sums turned by the carrier phasor at its first sample
            a = -2.0 * math.pi * (ph0 + k0 * carr_step)
            zr = math.cos(a)
            zi = math.sin(a)
            acc[0] += zr * er - zi * ei
            acc[1] += zr * ei + zi * er
            acc[2] += zr * pr - zi * pi_
            acc[3] += zr * pi_ + zi * pr
            acc[4] += zr * lr - zi * li
            acc[5] += zr * li + zi * lr
            k0 += m
        if seg == 0:
            acc[6] = acc[2]
            acc[7] = acc[3]
    return (complex(acc[0], acc[1]), complex(acc[2], acc[3]), complex(acc[4], acc[5]),
            complex(acc[6], acc[7]), complex(acc[2] - acc[6], acc[3] - acc[7]))


@njit(cache=True, nogil=True)
def correlate(samples, off, n, code_ext, code_phase, code_step, half_el, carr_phase, carr_step):
    """:func:`correlate_ws` with its own workspace (callers that correlate once; the tracking kernel keeps
    one workspace per block of epochs)."""
    return correlate_ws(samples, off, n, code_ext, code_phase, code_step, half_el, carr_phase, carr_step,
                        workspace())


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
