"""Pulsed-interference detection and adaptive pulse blanking (part of the input conditioning stage,
:mod:`receiver.source.conditioning`; ``input.conditioning.pulse_detection``).

Detector (:func:`pulse_test`, numpy, on a span of conditioned samples: the detection span and every monitor
check's span)
    The span is cut into blocks of ``BLOCK`` samples; the mean power of each block is, under Gaussian
    noise, ``floor * Gamma(B, 1/B)``.  The floor is estimated robustly as the median block power divided by
    the median of Gamma(B, 1/B) (unbiased while pulses cover less than half of the blocks; for a quantised
    input -- 1 to 3 bits -- the block mean is still close to continuous).  A block is *over* when its power
    exceeds ``10^(threshold_db / 10)`` times the floor (6 dB: probability 2e-13 per block under noise).
    The span is *pulsed* when it holds at least ``min_pulses`` separate runs of over blocks: a tone or a
    front end switching on, or the recording's AGC changing its gain, is one step (one run) and does not
    count; pulses repeat.

Blanker (:func:`cancel_blank`, numba; replaces the tone canceller's kernel while pulses are present)
    Per sample, after the tone notches: ``p = |y|^2``.  The floor is tracked by a multiplicative median
    tracker on the powers of consecutive ``BLOCK``-sample blocks (step ``ETA`` per block: it follows an AGC
    gain change of 30 dB in ~2 ms, and a pulse train covering less than half of the blocks does not move
    it).  A sample is blanked (set to 0) when ``p`` exceeds ``INSTANT`` x floor (a strong pulse's first
    sample; 1e-11 per sample under noise) or when the short-term power -- an exponential average over
    ``SMOOTH`` samples of ``min(p, CAP x floor)`` -- exceeds the threshold (a weak pulse, after a few
    samples), and for ``HOLD`` samples after the last such sample (the filtered pulse's tail).  The capped
    average decays from a pulse in ~25 samples, so the guard after a strong pulse stays short.  The notches'
    amplitude estimates and frequency loops are not updated on blanked samples (a pulse does not pull them).

The blanker is switched on when a span is pulsed and off again after ``QUIET_CHECKS`` monitor checks
without a blanked run; while it is off the samples are exactly the tone canceller's.  The correlators of a
blanked stream see a fraction ``b`` of zeros: signal amplitude and noise power both scale by (1 - b), so
the C/N0 the tracking loops estimate is the effective one after blanking, (1 - b) times the signal's (the
run summary reports ``b``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..estimation.stats import gamma_median

BLOCK = 16          # samples per block of the detector and of the blanker's floor tracker
ETA = 0.02          # the floor tracker's multiplicative step per block
SMOOTH = 16         # samples of the blanker's short-term power average
CAP = 20.0          # the average takes min(p, CAP x floor)
INSTANT = 25.0      # a single sample over INSTANT x floor is blanked at once
HOLD = 8            # samples blanked after the last sample over the thresholds

# indices of the blanker's state array
S_Q, S_EMA, S_ACC, S_CNT, S_HOLD, S_BLANKED, S_RUNS, S_INRUN = range(8)
N_STATE = 8


@dataclass
class PulseTest:
    """What :func:`pulse_test` found in a span: the noise floor (mean power per sample), the number of
    separate runs of over blocks, the share of over blocks and the pulses' excess energy over the span's
    noise energy."""
    floor: float
    runs: int
    fraction: float
    excess: float
    pulsed: bool


def pulse_test(y: np.ndarray, threshold_db: float = 6.0, min_pulses: int = 3) -> PulseTest:
    """Test a span of complex samples for pulsed interference (module doc)."""
    y = np.asarray(y)
    n = len(y) // BLOCK
    if n < 8:
        return PulseTest(0.0, 0, 0.0, 0.0, False)
    p = np.abs(y[:n * BLOCK].astype(np.complex128)) ** 2
    bp = p.reshape(n, BLOCK).mean(axis=1)
    floor = float(np.median(bp)) / gamma_median(BLOCK)
    if floor <= 0:
        return PulseTest(0.0, 0, 0.0, 0.0, False)
    over = bp > 10 ** (threshold_db / 10.0) * floor
    runs = int(over[0]) + int(np.count_nonzero(over[1:] & ~over[:-1]))
    excess = float(np.sum(bp[over] - floor)) / (floor * n)
    return PulseTest(floor, runs, float(np.mean(over)), excess, runs >= int(min_pulses))


@njit(cache=True, nogil=True)
def _over_blocks(y, threshold, margin):
    """The number of BLOCK-sample blocks of ``y`` whose mean power exceeds ``threshold`` x (their median /
    the median of Gamma(BLOCK, 1/BLOCK)) x ``margin``, or -1 when that floor is not positive."""
    n = len(y) // BLOCK
    bp = np.empty(n)
    for b in range(n):
        acc = 0.0
        for i in range(b * BLOCK, (b + 1) * BLOCK):
            v = y[i]
            acc += np.float64(v.real) * np.float64(v.real) + np.float64(v.imag) * np.float64(v.imag)
        bp[b] = acc / BLOCK
    floor = np.median(bp)
    if not floor > 0.0:
        return -1
    lim = threshold * floor * margin
    count = 0
    for b in range(n):
        if bp[b] > lim:
            count += 1
    return count


def may_be_pulsed(y: np.ndarray, threshold_db: float = 6.0, min_pulses: int = 3) -> bool:
    """False only when :func:`pulse_test` of the span would find it not pulsed: fewer than ``min_pulses``
    blocks over a threshold 1e-6 below the test's (each run of the test holds at least one such block;
    one compiled pass instead of the test's numpy steps -- the monitor's screen on a clean stream)."""
    y = np.ascontiguousarray(y)
    if len(y) // BLOCK < 8 or y.dtype != np.complex64:
        return True
    count = _over_blocks(y, 10 ** (threshold_db / 10.0) * gamma_median(BLOCK) ** -1, 1.0 - 1e-6)
    return count < 0 or count >= int(min_pulses)


def blank_mask(y: np.ndarray, floor: float, threshold_db: float = 6.0) -> np.ndarray:
    """The samples of a span the detector's over blocks cover, with one block on each side (to blank a span
    before its tones are detected: a pulse train's spectral lines are not tones)."""
    n = len(y) // BLOCK
    mask = np.zeros(len(y), bool)
    if n < 1 or floor <= 0:
        return mask
    bp = (np.abs(y[:n * BLOCK].astype(np.complex128)) ** 2).reshape(n, BLOCK).mean(axis=1)
    over = bp > 10 ** (threshold_db / 10.0) * floor
    over = over | np.r_[over[1:], False] | np.r_[False, over[:-1]]
    mask[:n * BLOCK] = np.repeat(over, BLOCK)
    if n * BLOCK < len(y) and over[-1]:
        mask[n * BLOCK:] = True
    return mask


def blanker_state(floor: float) -> np.ndarray:
    """A fresh blanker state at the noise floor ``floor`` (mean power per sample)."""
    st = np.zeros(N_STATE, np.float64)
    st[S_Q] = floor * gamma_median(BLOCK)
    st[S_EMA] = floor
    return st


def blanker_params(threshold_db: float) -> np.ndarray:
    """The kernel's parameters: alpha, cap, threshold, instant, eta, block, hold, gamma median."""
    return np.array([1.0 / SMOOTH, CAP, 10 ** (threshold_db / 10.0), INSTANT, ETA, BLOCK, HOLD,
                     gamma_median(BLOCK)], np.float64)


def restart(st: np.ndarray) -> None:
    """A restarted stream: the short-term state starts again at the floor (the floor is kept)."""
    st[S_EMA] = st[S_Q] / gamma_median(BLOCK)
    st[S_ACC] = 0.0
    st[S_CNT] = 0.0
    st[S_HOLD] = 0.0
    st[S_INRUN] = 0.0


@njit(cache=True, fastmath=True, nogil=True)
def cancel_blank(x, out, steps, rot, amp, mu, blank_level, dw, dr, res, g1, g2, g3, pfloor, st, par, zb):
    """The tone canceller (receiver.source.conditioning.cancel: same notches, frequency loops and DC removal)
    followed by the adaptive pulse blanker (module doc).  ``st`` the blanker's state (updated), ``par`` its
    parameters (blanker_params), ``zb`` scratch of 2 x the number of notches; blank_level > 0: the static
    blanker's level (input.conditioning.pulse_blanking) applies too."""
    nt = steps.size
    alpha, cap, thr, inst, eta, blk, hold, gm = par[0], par[1], par[2], par[3], par[4], par[5], par[6], par[7]
    q, ema, acc, cnt, hl = st[0], st[1], st[2], st[3], st[4]
    blanked, runs, inrun = st[5], st[6], st[7]
    for n in range(x.size):
        vr = np.float64(x[n].real)
        vi = np.float64(x[n].imag)
        for k in range(nt):
            rr, ri = rot[k].real, rot[k].imag
            ar, ai = amp[k].real, amp[k].imag
            zb[2 * k] = vr * rr + vi * ri
            zb[2 * k + 1] = vi * rr - vr * ri
            vr -= ar * rr - ai * ri
            vi -= ar * ri + ai * rr
        p = vr * vr + vi * vi
        fl = q / gm
        acc += p
        cnt += 1.0
        if cnt >= blk:
            if acc / blk > q:
                q *= 1.0 + eta
            else:
                q /= 1.0 + eta
            acc = 0.0
            cnt = 0.0
        ema += alpha * (min(p, cap * fl) - ema)
        hit = p > inst * fl or ema > thr * fl or (blank_level > 0.0 and p > blank_level * blank_level)
        if hit:
            hl = hold
        elif hl > 0.0:
            hl -= 1.0
        blank = hit or hl > 0.0
        if blank:
            if inrun == 0.0:
                runs += 1.0
            inrun = 1.0
            blanked += 1.0
            out[n] = 0.0
        else:
            inrun = 0.0
            out[n] = complex(vr, vi)
        for k in range(nt):
            rr, ri = rot[k].real, rot[k].imag
            ar, ai = amp[k].real, amp[k].imag
            zr, zi = zb[2 * k], zb[2 * k + 1]
            sr, si = steps[k].real, steps[k].imag
            if not blank:
                amp[k] = complex(ar + mu[k] * (zr - ar), ai + mu[k] * (zi - ai))
                if g1[k] > 0.0:
                    pa = ar * ar + ai * ai
                    res[k] += 10.0 * mu[k] * (zr * zr + zi * zi - res[k])
                    if pa > pfloor[k] and res[k] > 0.5 * pa:
                        e = (zi * ar - zr * ai) / pa
                        dr[k] += g3[k] * e
                        dw[k] += g2[k] * e + dr[k]
                        th = g1[k] * e + dw[k]
                        cr = 1.0 - 0.5 * th * th
                        sr, si = sr * cr - si * th, sr * th + si * cr
            elif g1[k] > 0.0:                      # held loop: the tracked frequency goes on
                th = dw[k]
                cr = 1.0 - 0.5 * th * th
                sr, si = sr * cr - si * th, sr * th + si * cr
            nr = rr * sr - ri * si
            ni = rr * si + ri * sr
            g = 1.5 - 0.5 * (nr * nr + ni * ni)
            rot[k] = complex(nr * g, ni * g)
    st[0], st[1], st[2], st[3], st[4] = q, ema, acc, cnt, hl
    st[5], st[6], st[7] = blanked, runs, inrun
    return out
