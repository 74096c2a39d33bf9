"""Narrowband-interference (CW / spur) detection for the input conditioning stage (receiver.source.conditioning).

Tone detector (:func:`detect_tones`)
    Averaged periodogram of ``K`` consecutive, non-overlapping segments of ``fft_size`` samples with a
    4-term Blackman-Harris window (sidelobes below -92 dB, so a tone 80 dB above the per-bin floor stays
    within +/-4 bins).  Under noise only every averaged bin is ``floor * Gamma(K, 1/K)``.  The floor is
    estimated robustly per bin as the running median over ``floor_bins`` neighbouring bins divided by the
    median of Gamma(K, 1/K) (tones, a band-limiting filter's roll-off and the GNSS signals leave it
    unbiased).  A bin is a detection when it exceeds ``floor * max(gamma.isf(pfa / fft_size, K, 1/K),
    10^(min_db / 10))``: under white noise the probability of one or more detections over the whole
    spectrum is <= ``pfa`` (union bound).  Contiguous detected bins form one tone; its frequency is the
    parabolic interpolation of the log spectrum around the largest bin, then refined from the phase
    slope of the tone over the detection span (sub-Hz for strong tones).  Reported per tone:
    ``freq_hz``, ``snr_bin_db`` (peak bin over the floor) and ``jnr_db`` (tone power over the total noise
    power in the sampled band, comparable with the simulator's ``impairments.tones[].power_db``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numba import njit

from ..estimation.stats import gamma_isf, gamma_median, median_last_axis

#: equivalent noise bandwidth of the 4-term Blackman-Harris window, in bins
ENBW_BH = 2.0044


@dataclass
class Tone:
    """A narrowband tone found by detect_tones: frequency (Hz, in the sampled complex band), peak bin SNR and
    JNR (dB), and whether a notch cancels it."""
    freq_hz: float          # frequency of the tone in the sampled (complex) band
    snr_bin_db: float       # peak periodogram bin over the local noise floor
    jnr_db: float           # tone power over the total noise power of the sampled band
    cancelled: bool = True  # a notch runs on it (False: DC, excision off, or beyond max_tones)
    dc: bool = False        # at 0 Hz: dc_removal takes it


@dataclass
class Detection:
    """What detect_tones found: the tones, the periodogram's size, segments and bin width (Hz), the detection
    threshold (dB over the floor), the total noise power and the DC offset of the span."""
    tones: list = field(default_factory=list)
    fft_size: int = 0
    segments: int = 0
    bin_hz: float = 0.0
    threshold_db: float = 0.0     # detection threshold over the floor
    noise_power: float = 0.0      # total noise power (floor summed over the band), input units^2
    dc: complex = 0j              # mean of the detection span (DC offset)


@lru_cache(maxsize=8)
def _bh_window(n):
    # 4-term Blackman-Harris (periodic form: the DFT-even window of an n-point segment); cached, read-only
    x = 2.0 * np.pi * np.arange(n) / n
    w = 0.35875 - 0.48829 * np.cos(x) + 0.14128 * np.cos(2 * x) - 0.01168 * np.cos(3 * x)
    w.flags.writeable = False
    return w


@njit(cache=True, nogil=True)
def _running_median_circular(x, w):
    """Median of the ``w`` (odd, <= len(x)) values of ``x`` centred on each index, wrapping around: the
    middle of a window kept sorted (one value out, one in per step), the same values as numpy's median of
    each window."""
    n, h = len(x), w // 2
    win = np.empty(w)
    for j in range(w):
        win[j] = x[(j - h) % n]
    win.sort()
    out = np.empty(n)
    out[0] = win[h]
    for i in range(1, n):
        old, new = x[(i - 1 - h) % n], x[(i + h) % n]
        j = np.searchsorted(win, old)          # (old is in the window: win[j] == old)
        while j + 1 < w and win[j + 1] < new:  # new above: shift the values between down one
            win[j] = win[j + 1]
            j += 1
        while j > 0 and win[j - 1] > new:      # new below: shift the values between up one
            win[j] = win[j - 1]
            j -= 1
        win[j] = new
        out[i] = win[h]
    return out


def running_median_circular(x: np.ndarray, w: int) -> np.ndarray:
    """Median over the ``w`` (odd) neighbouring values of each element of the 1-D ``x``, circularly (the
    noise floor of a periodogram); numpy's median of each window where ``x`` is not finite."""
    x = np.ascontiguousarray(x, np.float64)
    h = w // 2
    if w % 2 == 0 or w > len(x) or not np.isfinite(x).all():
        return median_last_axis(np.lib.stride_tricks.sliding_window_view(np.concatenate([x[-h:], x, x[:h]]), w))
    return _running_median_circular(x, int(w))


def _floor_lower_bound(spec: np.ndarray, fb: int) -> np.ndarray | None:
    """A lower bound of the running median over ``fb`` (odd) circular neighbours of every bin of ``spec``,
    cheaply: bin i's window lies inside the three blocks of fb // 2 bins around it, and the median of a
    window (its (fb // 2 + 1)-th smallest value) is at least that order statistic of any superset.  None
    when the blocks do not tile the spectrum."""
    b = fb // 2
    n = len(spec)
    if b < 1 or n % b or n < 3 * b:
        return None
    blocks = spec.reshape(n // b, b)
    trip = np.concatenate([np.roll(blocks, 1, axis=0), blocks, np.roll(blocks, -1, axis=0)], axis=1)
    lb = np.partition(trip, b, axis=1)[:, b]                 # per block: its window's bound
    return np.repeat(lb, b)


def detect_tones(x: np.ndarray, fs: float, fft_size: int = 4096, pfa: float = 1e-3, min_db: float = 6.0,
                 max_tones: int = 32, floor_bins: int = 129, screen: bool = False) -> Detection | None:
    """Detect CW tones / spurs in complex samples ``x`` (see the module doc for the test and Pfa).

    ``screen``: return None, without the floor, when a lower bound of the floor shows that no bin is over
    the threshold (the common case of a monitor check on a clean stream: what the floor would give -- no
    tones -- without its running median; a caller that needs ``noise_power`` does not screen)."""
    x = np.asarray(x)
    nfft = int(fft_size)
    while nfft > 64 and len(x) < nfft:
        nfft //= 2
    k = len(x) // nfft
    det = Detection(fft_size=nfft, segments=k, bin_hz=fs / nfft)
    if k < 1:
        return det
    seg = x[:k * nfft].astype(np.complex128).reshape(k, nfft)
    det.dc = complex(seg.mean())
    w = _bh_window(nfft)
    spec = np.fft.fftshift(np.mean(np.abs(np.fft.fft(seg * w[None, :], axis=1)) ** 2, axis=0))
    freqs = (np.arange(nfft) - nfft // 2) * fs / nfft
    fb = min(floor_bins, nfft // 4) | 1
    thr = max(float(gamma_isf(pfa / nfft, k)), 10 ** (min_db / 10.0))
    if screen and np.all(np.isfinite(spec)):
        lb = _floor_lower_bound(spec, fb)
        # (the margin covers the rounding of the products; the bound itself is exact)
        if lb is not None and not np.any(spec > thr * np.maximum(lb / gamma_median(k), 1e-30) * (1 - 1e-9)):
            return None
    med = running_median_circular(spec, fb)            # running median over fb bins, wrapping around
    floor = med / gamma_median(k)
    floor = np.maximum(floor, 1e-30)
    det.threshold_db = 10 * np.log10(thr)
    wp = float(np.sum(w ** 2))
    det.noise_power = float(np.sum(floor)) / (wp * nfft)       # per-sample noise power
    over = spec > thr * floor
    if not over.any():
        return det
    # contiguous runs (circularly) -> one tone each
    idx = np.flatnonzero(over)
    runs, cur = [], [idx[0]]
    for i in idx[1:]:
        if i == cur[-1] + 1:
            cur.append(i)
        else:
            runs.append(cur)
            cur = [i]
    runs.append(cur)
    if len(runs) > 1 and runs[0][0] == 0 and runs[-1][-1] == nfft - 1:
        runs[0] = runs.pop() + runs[0]
    tones = []
    for r in runs:
        r = np.asarray(r)
        i = int(r[np.argmax(spec[r])])
        lo, hi = spec[(i - 1) % nfft], spec[(i + 1) % nfft]
        a, b, c = np.log(max(lo, 1e-30)), np.log(spec[i]), np.log(max(hi, 1e-30))
        den = a - 2 * b + c
        d = 0.5 * (a - c) / den if den < 0 else 0.0
        f = freqs[i] + float(np.clip(d, -0.5, 0.5)) * fs / nfft
        excess = float(np.sum(np.maximum(spec[r] - floor[r], 0.0)))
        p_tone = excess / (wp * nfft)          # Parseval: the lobe sums to the tone power
        tones.append(Tone(f, 10 * np.log10(spec[i] / floor[i]),
                          10 * np.log10(max(p_tone, 1e-30) / det.noise_power)))
    tones.sort(key=lambda t: -t.jnr_db)
    tones = tones[:max_tones]
    for t in tones:
        t.freq_hz = refine_tone_frequency(x, fs, t.freq_hz, nfft)
    det.tones = tones
    return det


def refine_tone_frequency(x: np.ndarray, fs: float, f0: float, block: int) -> float:
    """Frequency of a tone near ``f0``: slope of the phase of ``block``-sample sums of the mixed-down
    signal (two passes; needs >= 3 blocks, else ``f0`` is returned)."""
    k = len(x) // block
    if k < 3:
        return float(f0)
    n = np.arange(k * block)
    f = float(f0)
    for _ in range(2):
        y = x[:k * block] * np.exp(-2j * np.pi * (f / fs) * n)
        s = y.reshape(k, block).sum(axis=1)
        ph = np.unwrap(np.angle(s))
        w = np.abs(s)
        tk = np.arange(k) * block / fs
        A = np.vstack([tk, np.ones(k)]).T * w[:, None]
        slope = np.linalg.lstsq(A, ph * w, rcond=None)[0][0]
        f += slope / (2 * np.pi)
    return f
