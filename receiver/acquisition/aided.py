"""Acquisition of a second-frequency signal (GPS L5) of a satellite, aided by its L1 channel, and its own
search when no aiding is at hand.

Aiding: the L1 C/A and L5 codes of a satellite both start at whole milliseconds of its clock, so the L1
channel's code phase at a receiver instant gives the L5 code phase at the same instant (the transmit time
modulo 1 ms, times the L5 chip rate) up to the ionospheric and hardware group-delay difference (tens of
metres: a few L5 chips); its Doppler, oscillator error included (one reference oscillator for both
front-end channels), scales by f_L5 / f_L1.  The aided search tests a few chips and Doppler bins around that
prediction; the unaided one every code phase and the full Doppler range.

Both search the same statistic: 1-ms coherent correlations (the Q5 pilot's NH20 may flip the sign every
millisecond) summed non-coherently over ``n_ms``, FFT over the code, normalised by the noise power of the
whole code axis; a cell is detected when it exceeds the Gamma(n_ms) quantile of the false-alarm probability
``pfa`` shared among the cells tested.  Fewer cells, a lower threshold: that is the aiding's sensitivity gain.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..gnss.signals import sample_code
from ..estimation.stats import gamma_isf, gamma_median


@dataclass
class AidedResult:
    """One search: ``detected``, ``code_phase_chips`` at the block's first sample, ``doppler_hz``, the peak's
    normalised statistic ``metric`` and the ``threshold`` it had to pass, the number of ``cells`` tested."""
    prn: int
    detected: bool
    code_phase_chips: float
    doppler_hz: float
    metric: float
    threshold: float
    cells: int


def predict_from_l1(code_phase_l1: float, doppler_l1: float, signal, l1_chip_rate: float = 1.023e6,
                    l1_carrier_hz: float = 1575.42e6, l1_code_len: int = 1023):
    """(code phase in ``signal`` chips, Doppler in Hz) of the second-frequency signal at the instant where the
    L1 channel's code phase is ``code_phase_l1`` chips and its Doppler ``doppler_l1`` Hz."""
    frac_s = (code_phase_l1 % l1_code_len) / l1_chip_rate               # transmit time mod 1 ms
    code = (frac_s * signal.chip_rate) % signal.code_len
    return code, doppler_l1 * signal.carrier_hz / l1_carrier_hz


def search(samples, fs: float, if_hz: float, signal, prn: int, doppler_hz: float, doppler_half_hz: float,
           code_phase_chips: float | None = None, code_half_chips: float = 5.0, n_ms: int = 10,
           doppler_step_hz: float = 250.0, pfa: float = 1e-3) -> AidedResult:
    """Search ``samples`` (complex, ``n_ms`` ms used; aided: from the predicted code-period start, so up to
    ``n_ms + 1`` ms) for ``signal``/``prn`` around ``doppler_hz`` +/- ``doppler_half_hz``; with
    ``code_phase_chips`` (the predicted code phase at the first sample) only code phases within
    ``code_half_chips`` of it are tested (aided), else all (unaided: the blocks are not aligned to the code
    periods, and a secondary-code sign change inside a block costs correlation).  The result's code phase is
    at the first sample."""
    n1 = int(round(fs * signal.code_len / signal.chip_rate))
    # aided: the 1-ms blocks start at the predicted code-period start (no secondary-code sign change inside)
    k0 = 0 if code_phase_chips is None else \
        int(round(((signal.code_len - code_phase_chips) % signal.code_len) * fs / signal.chip_rate)) % n1
    if len(samples) < k0 + n1 * n_ms:
        raise ValueError(f"search needs {n_ms} ms of samples (+ 1 ms aided), got {len(samples)}")
    x = np.asarray(samples[k0:k0 + n1 * n_ms], np.complex64).reshape(n_ms, n1)
    shift = k0 * signal.chip_rate / fs                   # chips from the first sample to the block start
    if code_phase_chips is not None:
        code_phase_chips = (code_phase_chips + shift) % signal.code_len
    rep = np.conj(np.fft.fft(sample_code(signal.code(prn), signal.chip_rate, fs, n1)))
    t = np.arange(n1 * n_ms).reshape(n_ms, n1) / fs
    dops = doppler_hz + np.arange(-doppler_half_hz, doppler_half_hz + 1e-9, doppler_step_hz)
    # lag L (samples) matches a signal whose code phase at the first sample is -L chip_rate / fs
    lag_chips = (-np.arange(n1) * signal.chip_rate / fs) % signal.code_len
    if code_phase_chips is None:
        mask = np.ones(n1, bool)
    else:
        d = (lag_chips - code_phase_chips + signal.code_len / 2) % signal.code_len - signal.code_len / 2
        mask = np.abs(d) <= code_half_chips
    best = (-1.0, 0, 0)
    for k, f in enumerate(dops):
        y = x * np.exp(-2j * np.pi * (if_hz + f) * t).astype(np.complex64)
        corr = np.fft.ifft(np.fft.fft(y, axis=1) * rep[None, :], axis=1)
        p = np.sum(np.abs(corr) ** 2, axis=0)
        noise = np.median(p) / _gamma_median(n_ms)          # mean power per 1-ms cell, noise only
        stat = p / noise
        i = int(np.argmax(np.where(mask, stat, -1.0)))
        if stat[i] > best[0]:
            best = (float(stat[i]), i, k)
    cells = int(mask.sum()) * len(dops)
    thr = float(gamma_isf(pfa / cells, n_ms) * n_ms)      # upper quantile of Gamma(n_ms, 1)
    metric, i, k = best
    code = (lag_chips[i] - shift) % signal.code_len        # at the first sample of ``samples``
    return AidedResult(prn, metric > thr, float(code), float(dops[k]), metric, thr, cells)


def _gamma_median(k: int) -> float:
    """Median of Gamma(k, 1) (the non-coherent sum of k unit-mean exponential cells)."""
    return float(gamma_median(k) * k)
