"""Narrow-window (hot / warm start) re-acquisition of one satellite around a predicted Doppler and code phase.

A satellite whose channel lost the signal is searched again in a small window: a few Doppler bins around
the predicted Doppler and a code-phase window around the predicted code phase.  The correlation over all
code phases of one code period is one FFT per coherent block and Doppler bin (circular correlation); only
the cells inside the window can be detected, so the detection threshold (false-alarm probability over the
window's cells) is lower than a full-grid search's and a false peak elsewhere in the code is impossible.
A detected peak is refined: the code phase by a triangle through the peak and its neighbours, the Doppler
from the phase advance of 1-ms prompt correlations at that code phase over the whole search block (data-bit
flips cost 1 product in 20).

``narrow_search(...) -> HotResult | None``; conventions as receiver.acquisition.code_search (carrier wipe-off
exp(-j 2 pi (IF + Doppler) t), code phase of the signal at the block's first sample, chips).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ..estimation.stats import gamma_isf, gamma_median

from ..gnss.signals import GPS_L1CA, sample_code


@dataclass
class HotResult:
    """A detection of :func:`narrow_search`: Doppler (Hz) and code phase (chips) of the signal at file sample
    ``sample_index``, the metric (peak / noise mean over the threshold, >= 1) and a C/N0 estimate (dB-Hz)."""
    prn: int
    doppler_hz: float
    code_phase_chips: float     # at sample_index
    sample_index: int
    metric: float               # peak / noise mean, over the detection threshold (>= 1 detected)
    cn0_dbhz_est: float


def window_cells(code_half_chips: float, code_len: float, n1: int) -> np.ndarray:
    """Boolean mask of the lags (samples) of one code period inside +/- code_half_chips of lag 0."""
    chips = np.arange(n1) * (code_len / n1)
    d = np.minimum(chips, code_len - chips)
    return d <= code_half_chips


def narrow_search(samples: np.ndarray, start_index: int, fs: float, if_hz: float, prn: int,
                  doppler_hz: float, doppler_half_hz: float, code_phase_chips: float,
                  code_half_chips: float, coherent_ms: int = 2, noncoherent: int = 10,
                  pfa: float = 1e-4, signal=None) -> HotResult | None:
    """Search prn in samples (file index start_index) within doppler_hz +/- doppler_half_hz and
    code_phase_chips +/- code_half_chips (the signal's code phase at start_index).  None: not detected."""
    sig = signal if signal is not None else GPS_L1CA
    n1f = fs * 1e-3
    if abs(n1f - round(n1f)) > 1e-6:
        raise ValueError("the narrow search needs an integer number of samples per millisecond")
    n1 = int(round(n1f))
    m = int(coherent_ms)
    n = n1 * m
    K = int(noncoherent)
    if len(samples) < n * K:
        return None
    T = m * 1e-3
    step = 1.0 / (2.0 * T)
    nb = int(math.ceil(max(doppler_half_hz, 0.0) / step))
    dopplers = doppler_hz + step * np.arange(-nb, nb + 1)
    code_len = sig.code_len
    code_half = min(float(code_half_chips), code_len / 2.0)
    # lag L (samples) matches a signal whose code phase at the block start is -L chip_rate/fs: the
    # replica is shifted by the predicted code phase so that lag 0 is the prediction
    rep = sample_code(sig.code(prn), sig.chip_rate, fs, n1, code_phase_chips % code_len)
    rep = np.tile(rep, m).astype(np.complex64)
    cf = np.conj(np.fft.fft(rep))
    mask = window_cells(code_half, code_len, n1)
    t = np.arange(n) / fs
    blocks = samples[:n * K].reshape(K, n).astype(np.complex64)
    power = np.zeros((len(dopplers), n1))
    for i, d in enumerate(dopplers):
        mix = np.exp(-2j * np.pi * (if_hz + d) * t).astype(np.complex64)
        spec = np.fft.fft(blocks * mix[None, :], axis=1)
        corr = np.fft.ifft(spec * cf[None, :], axis=1)
        p = corr.real ** 2 + corr.imag ** 2                # (K, n): lags repeat every n1 samples
        power[i] = p.reshape(K, m, n1)[:, 0, :].sum(axis=0)
    noise = float(np.median(power)) / gamma_median(K)   # robust mean of the noise cells
    if noise <= 0:
        return None
    win = power[:, mask]
    di, wi = np.unravel_index(int(np.argmax(win)), win.shape)
    lags = np.flatnonzero(mask)
    li = int(lags[wi])
    ptm = float(power[di, li]) / noise
    n_cells = win.size
    thr = float(gamma_isf(pfa / n_cells, K))
    if ptm < thr:
        return None
    # code phase: a triangle (the code's correlation function) through the peak and its neighbours, in
    # amplitude; exact for an unfiltered signal sampled at least twice per chip
    y0, y1, y2 = (math.sqrt(max(power[di, (li + k) % n1], 0.0)) for k in (-1, 0, 1))
    den = 2.0 * (y1 - min(y0, y2))
    frac = (y2 - y0) / den if den > 0 else 0.0
    lag = li + max(-0.5, min(0.5, frac))
    code_phase = (code_phase_chips - lag * sig.chip_rate / fs) % code_len
    dop = refine(samples[:n * K], fs, if_hz, prn, code_phase, float(dopplers[di]), sig, doppler_hz)
    cn0 = 10 * np.log10(max(ptm - 1.0, 1e-3) / T)
    return HotResult(prn, dop, float(code_phase), int(start_index), ptm / thr, float(cn0))


def refine(samples, fs, if_hz, prn, code_phase_chips, coarse_hz, sig, centre_hz=None) -> float:
    """Doppler from the phase advance of consecutive 1-ms prompts (range +/- 500 Hz around coarse_hz).
    Signals whose sign can change every code period (``sig.short_symbols``: B1I's NH code, D2 symbols) use
    the squared prompts, free of the sign, whose phase advances at twice the residual (range +/- 250 Hz,
    twice the half step of the narrow search's grid): a sign change between two prompts would otherwise
    read as a 500 Hz jump (B1I hot searches were measured 40-350 Hz off at 38-45 dB-Hz).  The squares give
    the Doppler modulo 500 Hz: the value nearest ``centre_hz`` (the searched window's centre, the
    prediction) is taken, since a 2-ms coherent block of a sign-changing signal also peaks 250 Hz off."""
    n1 = int(round(fs * 1e-3))
    rate = sig.chip_rate * (1.0 + coarse_hz / sig.carrier_hz)
    short = sig.short_symbols(prn)
    # sign-changing signals: the 1-ms blocks start at a code period's first chip, so that each holds one
    # symbol (a block straddling a sign change loses its amplitude, half the time at B1I's NH rate)
    s0 = sig.samples_to_period_start(code_phase_chips, rate / fs) if short else 0
    k = (len(samples) - s0) // n1
    if k < 3:
        return coarse_hz
    n = k * n1
    code = sample_code(sig.code(prn), rate, fs, n, (code_phase_chips + s0 * rate / fs) % sig.code_len)
    t = np.arange(s0, s0 + n) / fs
    z = (samples[s0:s0 + n] * code * np.exp(-2j * np.pi * (if_hz + coarse_hz) * t)).reshape(k, n1).sum(axis=1)
    # (GPS: the code-phase prediction may straddle a period boundary of the 1-ms blocks: harmless)
    if short:
        w = z * z
        acc = np.sum(w[1:] * np.conj(w[:-1]))
        if acc == 0:
            return coarse_hz
        f = coarse_hz + np.angle(acc) / (4 * np.pi * 1e-3)
        if centre_hz is not None:
            f += 500.0 * round((centre_hz - f) / 500.0)
        return float(f)
    acc = np.sum(z[1:] * np.conj(z[:-1]))
    if acc == 0:
        return coarse_hz
    return float(coarse_hz + np.angle(acc) / (2 * np.pi * 1e-3))
