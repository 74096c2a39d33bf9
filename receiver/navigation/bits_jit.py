"""Compiled per-bit prompt sums of a channel's records (receiver.navigation.channel.ChannelNav.add).

:func:`bit_segments` returns, for the bit-synchronised records of one chunk, the bit index of each run of
records, the prompt sums over the bit's first and second 10-ms halves, the integration time and whether
a frequency-locked epoch is among them: what ``add`` computed with ~25 numpy calls per chunk and channel.
The sums are numpy's own: ``np.add.reduceat`` adds a segment's first element to the pairwise sum of the
rest (numpy's pairwise summation: 8 partial sums below 128 elements, halving above), and so does
:func:`_segment_sum`, so the values are bit-identical (tests/unit/navigation/test_navigation_bits_jit.py).
Self-contained
for numba's on-disk cache.

The entry point keeps the GIL (no ``nogil``), as do the other small compiled navigation kernels
(receiver.gnss.ephemeris_jit._states, receiver.navigation.wls_jit.linearise): they run for 10-100 us on the
main thread while the background writer and read-ahead threads want the GIL.  Releasing it for so short a
call handed the GIL to one of them, and taking it back waited out the interpreter's switch interval (5 ms):
~2 ms per call (20-s 16.368 MS/s 12-channel run, load ~7: bit_segments 467 calls 1.2 s of wall and
_states 223 calls 0.7 s; holding the GIL 0.11 s and 0.04 s).
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _pairwise(a, lo, n):
    """numpy's pairwise_sum of a[lo:lo+n]."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        i = 8
        top = n - n % 8
        while i < top:
            r0 += a[lo + i]
            r1 += a[lo + i + 1]
            r2 += a[lo + i + 2]
            r3 += a[lo + i + 3]
            r4 += a[lo + i + 4]
            r5 += a[lo + i + 5]
            r6 += a[lo + i + 6]
            r7 += a[lo + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise(a, lo, n2) + _pairwise(a, lo + n2, n - n2)


@njit(cache=True, nogil=True)
def _segment_sum(a, s, e):
    """np.add.reduceat's value for the segment a[s:e] (e > s)."""
    out = a[s]
    if e - s > 1:
        out += _pairwise(a, s + 1, e - s - 1)
    return out


@njit(cache=True)       # holds the GIL (module docstring)
def bit_segments(code_period, integration_ms, sample_index, p1i, p1q, p2i, p2q, bit_offset, bit_ms, nc_from):
    """Per run of equal bit index of the records (already the bit-synchronised ones): (bit index, first-half
    sum re, im, second-half sum re, im, integration ms, any epoch at or after sample nc_from (-1: none)).
    An epoch's halves (prompt1/2) go to the half-bit their start lies in."""
    n = code_period.size
    bits = np.empty(n, np.int64)
    har = np.empty(n)
    hai = np.empty(n)
    hbr = np.empty(n)
    hbi = np.empty(n)
    for i in range(n):
        d = code_period[i] - bit_offset
        bits[i] = d // bit_ms
        o = d % bit_ms
        late1 = o >= bit_ms // 2
        late2 = 2 * o + np.int64(integration_ms[i]) >= bit_ms
        a1r, a1i = np.float64(p1i[i]), np.float64(p1q[i])
        a2r, a2i = np.float64(p2i[i]), np.float64(p2q[i])
        har[i] = (0.0 if late1 else a1r) + (0.0 if late2 else a2r)
        hai[i] = (0.0 if late1 else a1i) + (0.0 if late2 else a2i)
        hbr[i] = (a1r + a2r) - har[i]
        hbi[i] = (a1i + a2i) - hai[i]
    starts = np.empty(n + 1, np.int64)
    k = 0
    for i in range(n):
        if i == 0 or bits[i] != bits[i - 1]:
            starts[k] = i
            k += 1
    starts[k] = n
    seg_bit = np.empty(k, np.int64)
    ar = np.empty(k)
    ai = np.empty(k)
    br = np.empty(k)
    bi = np.empty(k)
    ms = np.empty(k, np.int64)
    nc = np.zeros(k, np.bool_)
    for j in range(k):
        s, e = starts[j], starts[j + 1]
        seg_bit[j] = bits[s]
        ar[j] = _segment_sum(har, s, e)
        ai[j] = _segment_sum(hai, s, e)
        br[j] = _segment_sum(hbr, s, e)
        bi[j] = _segment_sum(hbi, s, e)
        t = 0
        for i in range(s, e):
            t += np.int64(integration_ms[i])
            if nc_from >= 0 and sample_index[i] >= nc_from:
                nc[j] = True
        ms[j] = t
    return seg_bit, ar, ai, br, bi, ms, nc
