"""Numba kernel of the IF generator: sums the satellites' signals into a block of complex samples.

The per-satellite truth is given on a uniform grid of receiver time (1 ms in the simulator).  Between two
grid points the code phase, the carrier phase and the amplitude are linear in the sample index (the code
and carrier rates are constant over one grid step), so each sample costs a few multiply-adds: the carrier
phasor is rotated by a constant step and re-anchored with exact sin/cos at every grid point and code
period boundary.

Signal of one satellite at sample n (complex baseband or complex IF):
    amp(n) * code[chip(n) mod L] * data[m(n)] * exp(+j 2 pi phase(n))
where L is the code length (1023 for GPS C/A), chip(n) counts chips from the first code period that starts
in the block and m(n) = chip(n) // L indexes the per-code-period data sign (+1 for data bit 0).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

@njit(cache=True, fastmath=True)
def synth_block(out, seg_start, seg_x0, inv_l, codes, chips, phase_frac, dphase, amps, dsign):
    """Add all satellites' signals into ``out`` (complex64, zeroed by the caller).

    seg_start[j]..seg_start[j+1]-1: samples of grid step j (block-relative, j = 0..n_seg-1);
    seg_x0[j]: offset (in samples, 0 <= x0 < 1) of sample seg_start[j] after grid point j;
    inv_l: 1 / (samples per grid step).
    Per satellite s and grid point j (n_seg + 1 points): chips[s, j] (float64, >= 0, chips since the
    start of the first code period of the block), phase_frac[s, j] (carrier phase mod 1, cycles),
    dphase[s, j] (phase increase over step j, cycles), amps[s, j] (float32); dsign[s, m] (float32) the
    data sign of code period m; codes[s, :] the +/-1 codes (all of the same length L).

    Each grid step is cut where the code period (hence the data sign) changes; inside a piece the
    samples are generated four at a time with four interleaved phasors, each rotated by four samples'
    phase step (re-anchored with exact sin/cos at every piece), which keeps the floating-point
    dependency chains short.
    """
    outf = out.view(np.float32)
    code_len = codes.shape[1]
    n_seg = seg_start.size - 1
    n_sat = chips.shape[0]
    two_pi = 2.0 * math.pi
    for j in range(n_seg):
        lo = seg_start[j]
        hi = seg_start[j + 1]
        x0 = seg_x0[j]
        for s in range(n_sat):
            a0 = amps[s, j]
            a1 = amps[s, j + 1]
            if a0 == 0.0 and a1 == 0.0:
                continue
            da = (a1 - a0) * inv_l
            dc = (chips[s, j + 1] - chips[s, j]) * inv_l
            c0 = chips[s, j] + x0 * dc
            dw = two_pi * dphase[s, j] * inv_l            # phase step per sample (rad)
            ph0 = two_pi * phase_frac[s, j] + x0 * dw
            cs = codes[s]
            n = lo
            while n < hi:
                k = n - lo
                c = c0 + k * dc
                m = int(c) // code_len
                n_end = lo + int(math.ceil(((m + 1) * float(code_len) - c0) / dc))   # next code period
                if n_end > hi:
                    n_end = hi
                if n_end <= n:
                    n_end = n + 1
                off = m * code_len
                amp0 = (a0 + (x0 + k) * da) * dsign[s, m]
                dam = da * dsign[s, m]
                p = ph0 + k * dw
                z0r, z0i = np.float32(math.cos(p)), np.float32(math.sin(p))
                z1r, z1i = np.float32(math.cos(p + dw)), np.float32(math.sin(p + dw))
                z2r, z2i = np.float32(math.cos(p + 2 * dw)), np.float32(math.sin(p + 2 * dw))
                z3r, z3i = np.float32(math.cos(p + 3 * dw)), np.float32(math.sin(p + 3 * dw))
                wr, wi = np.float32(math.cos(4 * dw)), np.float32(math.sin(4 * dw))
                cnt = n_end - n
                for q in range(cnt // 4):
                    kk = 4 * q
                    i0 = 2 * (n + kk)
                    ca = c + kk * dc
                    i_a = int(ca) - off
                    i_b = int(ca + dc) - off
                    i_c = int(ca + 2 * dc) - off
                    i_d = int(ca + 3 * dc) - off
                    if i_d >= code_len:               # rounding at the period boundary only
                        i_a = i_a - code_len if i_a >= code_len else i_a
                        i_b = i_b - code_len if i_b >= code_len else i_b
                        i_c = i_c - code_len if i_c >= code_len else i_c
                        i_d -= code_len
                    am = np.float32(amp0 + kk * dam)
                    va, vb, vc, vd = am * cs[i_a], am * cs[i_b], am * cs[i_c], am * cs[i_d]
                    outf[i0] += va * z0r
                    outf[i0 + 1] += va * z0i
                    outf[i0 + 2] += vb * z1r
                    outf[i0 + 3] += vb * z1i
                    outf[i0 + 4] += vc * z2r
                    outf[i0 + 5] += vc * z2i
                    outf[i0 + 6] += vd * z3r
                    outf[i0 + 7] += vd * z3i
                    t = z0r * wr - z0i * wi
                    z0i = z0r * wi + z0i * wr
                    z0r = t
                    t = z1r * wr - z1i * wi
                    z1i = z1r * wi + z1i * wr
                    z1r = t
                    t = z2r * wr - z2i * wi
                    z2i = z2r * wi + z2i * wr
                    z2r = t
                    t = z3r * wr - z3i * wi
                    z3i = z3r * wi + z3i * wr
                    z3r = t
                rem = cnt % 4
                if rem:
                    w1r, w1i = np.float32(math.cos(dw)), np.float32(math.sin(dw))
                    for kk in range(cnt - rem, cnt):
                        i0 = 2 * (n + kk)
                        ia = int(c + kk * dc) - off
                        if ia >= code_len:
                            ia -= code_len
                        va = np.float32(amp0 + kk * dam) * cs[ia]
                        outf[i0] += va * z0r
                        outf[i0 + 1] += va * z0i
                        t = z0r * w1r - z0i * w1i
                        z0i = z0r * w1i + z0i * w1r
                        z0r = t
                n = n_end
    return out


@njit(cache=True)
def _quantize_int(x, out, complex_out, lo, hi):
    if complex_out:
        for n in range(x.size):
            re = round(x[n].real)
            im = round(x[n].imag)
            out[2 * n] = min(max(re, lo), hi)
            out[2 * n + 1] = min(max(im, lo), hi)
    else:
        for n in range(x.size):
            out[n] = min(max(round(x[n].real), lo), hi)
    return out


def quantize_fast(x: np.ndarray, fmt: str) -> np.ndarray:
    """Fast path of :func:`receiver.source.io.quantize` (scale 1) for complex64 blocks: the same raw array
    (round half to even, saturation; real formats take the real part)."""
    from ..source.io import FORMATS
    f = FORMATS[fmt]
    dt, ncomp = f.dtype, f.ncomp
    if f.kind not in ("int", "float"):
        raise ValueError(f"quantize_fast: {fmt} is written through source.io.Encoder")
    x = np.ascontiguousarray(x, dtype=np.complex64)
    if dt == np.float32:
        return x.view(np.float32).copy() if ncomp == 2 else x.real.copy()
    info = np.iinfo(dt)
    out = np.empty(x.size * ncomp, dtype=dt)
    return _quantize_int(x, out, ncomp == 2, float(info.min), float(info.max))
