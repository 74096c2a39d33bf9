"""Time-frequency excision of moving narrowband interference (swept / chirp jammers, hopping tones): part of
the input conditioning stage, :mod:`receiver.source.conditioning` (``input.conditioning.tf_excision``).

A notch that tracks its tone follows a few kHz per ms; a jammer sweeping +/-800 kHz every 10 ms moves
~300 kHz per ms.  Here the raw samples are cut into short frames (``N`` samples, ~50 us: a power of two,
:func:`frame_size`), Hann-windowed with a hop of N/4; in each frame's spectrum the bins far above the
noise are zeroed (the bin and its two neighbours), and the frames are Hann-windowed again and overlap-added
(the squared windows sum to 1.5 at every sample: with nothing excised the output is the input, to float
rounding).  The sweep crosses ~(rate x T) bins of 1/T in a frame of T: at 300 MHz/s and 49 us under one
20-kHz bin, so a few bins of 128 are excised per frame (a few % of the band).

Noise floor per bin ``floor_k``: the median over the frames of a span of |X_k|^2 / ln 2 (a bin that a
moving tone visits in few frames keeps its noise floor; a stationary tone raises its bin's floor: stationary
tones are the notches' task, not excised).  Each frame's level is the median over its bins of
|X_k|^2 / floor_k / ln 2 (a recording's AGC gain step or a pulse raises every bin: not excised).  A bin
is excised when |X_k|^2 > 10^(threshold_db / 10) x floor_k x level (12 dB: 1.3e-7 per bin under noise).

Switched on by :func:`tf_test` on a span (the detection span and every monitor check's span): moving
interference = over a higher threshold (gate_db, 15 dB: 2e-14 per bin) in >= 5 % of the frames and in at
least N / 8 distinct bins (a stationary tone is a few bins; a frame with more than N / 4 bins over -- where a
tone switches on or a pulse starts, splattering over the band -- is not counted); off after the monitor's quiet checks
with fewer than 1 % of the frames excised.  While it is off the samples are untouched.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..estimation.stats import median_last_axis

GATE_DB = 15.0          # tf_test: per-bin level over the floor that counts
MIN_FRAMES = 0.05       # share of the span's frames with such a bin
LN2 = math.log(2.0)


def frame_size(fs: float, frame_us: float = 50.0) -> int:
    """Frame length: the power of two nearest to ``frame_us`` at ``fs`` (at least 32)."""
    return max(32, 1 << int(round(math.log2(max(fs * frame_us * 1e-6, 1.0)))))


@lru_cache(maxsize=8)
def _hann(n: int) -> np.ndarray:
    w = (0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)).astype(np.float32)
    w.flags.writeable = False                   # (cached: shared by every call)
    return w


def _spectra(x: np.ndarray, n: int, hop: int, light: bool = False) -> np.ndarray:
    """Hann-windowed frame spectra (complex64) of frames starting every hop samples.  ``light``: numpy's FFT
    (the detection test every run makes: a run that never excises does not load scipy.fft)."""
    f = (len(x) - n) // hop + 1
    if f < 1:
        return np.zeros((0, n), np.complex64)
    fr = np.lib.stride_tricks.sliding_window_view(np.asarray(x, np.complex64), n)[::hop][:f]
    if light:
        return np.fft.fft(fr * _hann(n)[None, :], axis=1).astype(np.complex64, copy=False)
    from scipy import fft as sfft
    return sfft.fft(fr * _hann(n)[None, :], axis=1, overwrite_x=True)


def _level(r: np.ndarray) -> np.ndarray:
    """Each frame's level: the median over its bins of the power re the floor, / ln 2 (frames x 1)."""
    k = r.shape[1] // 2
    return np.maximum(np.partition(r, k, axis=1)[:, k:k + 1] / LN2, 1e-30)


@dataclass
class TfTest:
    """What :func:`tf_test` found: the per-bin floor, the share of frames and the number of distinct bins
    over the gate, and whether the span holds moving narrowband interference."""
    floor: np.ndarray
    frames: float
    bins: int
    moving: bool


def bin_floor(p: np.ndarray) -> np.ndarray:
    """Per-bin noise floor (mean power) from frame spectra powers ``p`` (frames x bins)."""
    # (np.median's values, from one partition of the contiguous transpose: ~4x faster)
    return np.maximum(median_last_axis(np.ascontiguousarray(p.T)) / LN2, 1e-30)


def tf_test(x: np.ndarray, n: int, gate_db: float = GATE_DB) -> TfTest:
    """Test a span of raw complex samples for moving narrowband interference (module doc)."""
    p = np.abs(_spectra(x, n, n, light=True)).astype(np.float64) ** 2      # non-overlapping frames
    if p.shape[0] < 16:
        return TfTest(np.zeros(n), 0.0, 0, False)
    floor = bin_floor(p)
    r = p / floor[None, :]
    over = r > 10 ** (gate_db / 10.0) * _level(r)
    over = over[over.sum(axis=1) <= n // 4]        # a frame where a tone or a pulse starts splatters: not counted
    frames = float(np.sum(over.any(axis=1))) / p.shape[0]
    bins = int(np.count_nonzero(over.any(axis=0)))
    return TfTest(floor, frames, bins, frames >= MIN_FRAMES and bins >= max(4, n // 8))


def tf_excise(read, first: int, s0: int, count: int, n: int, floor: np.ndarray, threshold_db: float):
    """Samples [s0, s0 + count) after excision (module doc).  ``read(start, k)`` reads raw samples (the file
    starts at ``first``; before it and after its end zeros); frames lie on the grid of multiples of n / 4,
    so the output does not depend on how a stream is cut into reads.  Returns (samples complex64, frames
    with a bin excised, frames)."""
    hop = n // 4
    a = (s0 // hop - 3) * hop
    last = (s0 + count - 1) // hop * hop
    b = last + n
    lo = max(a, first)
    raw = read(lo, b - lo) if b > lo else np.zeros(0, np.complex64)
    x = np.zeros(b - a, np.complex64)
    x[lo - a:lo - a + len(raw)] = raw
    X = _spectra(x, n, hop)
    r = (X.real ** 2 + X.imag ** 2) / floor[None, :].astype(np.float32)
    m = r > np.float32(10 ** (threshold_db / 10.0)) * _level(r)
    m = m | np.roll(m, 1, axis=1) | np.roll(m, -1, axis=1)
    X[m] = 0.0
    from scipy import fft as sfft
    y = sfft.ifft(X, axis=1, overwrite_x=True) * (_hann(n) / np.float32(1.5))[None, :]
    fcount = y.shape[0]
    out = np.zeros(b - a, np.complex64)
    yq = y.reshape(fcount, 4, hop)
    for q in range(4):
        out[q * hop:q * hop + fcount * hop].reshape(fcount, hop)[:] += yq[:, q, :]
    hits = int(np.count_nonzero(m.any(axis=1)))
    return out[s0 - a:s0 - a + count].astype(np.complex64), hits, fcount
