"""Acquisition: FFT parallel code-phase search, non-coherent integration, fine Doppler refinement.

Detection statistic: the peak of the (non-coherently summed) correlation power divided by the mean
power over the whole search grid of that PRN.  Under noise only each cell is Gamma(K, 1/K) distributed
(K non-coherent sums of exponential cells, normalised to mean 1), so the threshold for a given
probability of false alarm over the whole grid ``pfa`` is ``gamma.isf(pfa / n_cells, K, scale=1/K)``.
The reported ``metric`` is the peak-to-mean ratio divided by that threshold: ``metric >= 1`` means
detected.  Use ``acquisition.threshold`` to scale it (default 1.0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
from scipy.stats import gamma

from .gnss.signals import GPS_L1CA, sample_code


@dataclass
class AcqResult:
    prn: int
    detected: bool
    doppler_hz: float          # carrier Doppler (fine if detected)
    code_phase_chips: float    # code phase of the signal at the first sample of the searched block
    sample_index: int          # file index of that first sample
    metric: float              # peak-to-mean / threshold (>= 1: detected)
    peak_to_mean: float
    cn0_dbhz_est: float


def _threshold(pfa: float, n_cells: int, k: int) -> float:
    return float(gamma.isf(pfa / n_cells, k, scale=1.0 / k))


def _has_energy(x: np.ndarray) -> bool:
    """False when the block is constant (all zero or pure DC): no correlation peak can be a signal."""
    return bool(np.any(x != x[0])) if len(x) else False


def search(samples: np.ndarray, start_index: int, fs: float, if_hz: float, prns, coherent_ms: int = 4,
           noncoherent: int = 10, doppler_max_hz: float = 10000.0, doppler_step_hz: float | None = None,
           pfa: float = 1e-3, threshold: float = 1.0, fine: bool = True, signal=None) -> list[AcqResult]:
    """Search `prns` in `samples` (complex64, first sample = file index start_index).

    Each coherent block of T = coherent_ms is Fourier transformed once per distinct fractional Doppler
    offset (in units of 1/T); a Doppler bin is then a circular shift of that spectrum.  The replica of
    coherent_ms code periods has spectral lines only on every coherent_ms-th bin, so the correlation
    over all code phases of one period is an inverse FFT of one period's length.
    ``signal``: a :class:`receiver.signals.SignalDef` (default GPS L1 C/A); its code period must be 1 ms.
    """
    sig = signal if signal is not None else GPS_L1CA
    n1 = fs * 1e-3
    if abs(n1 - round(n1)) > 1e-6:
        raise ValueError("acquisition needs an integer number of samples per millisecond")
    n1 = int(round(n1))
    m = coherent_ms
    n = n1 * m
    need = n * noncoherent
    if len(samples) < need:
        raise ValueError(f"acquisition needs {need} samples, got {len(samples)}")
    T = m * 1e-3
    if not _has_energy(samples[:need]):
        # all-zero or constant input: no signal energy once the mean is removed -> nothing detected
        cn0_floor = float(10 * np.log10(1e-3 / T))
        return [AcqResult(prn, False, 0.0, 0.0, start_index, 0.0, 0.0, cn0_floor) for prn in prns]
    step = doppler_step_hz or 1.0 / (2.0 * T)
    dopplers = np.arange(-doppler_max_hz, doppler_max_hz + step / 2, step)
    # carrier offsets in FFT bins (1/T): integer shift + one of a few fractional parts
    pos = (if_hz + dopplers) * T
    shift = np.floor(pos + 1e-9).astype(np.int64)
    frac = np.round(pos - shift, 6)
    fracs = np.unique(frac)
    t = np.arange(n) / fs
    blocks = samples[:need].reshape(noncoherent, n)
    spectra = {}
    for r in fracs:
        mix = np.exp(-2j * np.pi * (r / T) * t).astype(np.complex64)
        spectra[r] = sfft.fft(blocks * mix[None, :], axis=1, workers=-1)       # (K, n)
    # bin index of decimated line j for Doppler d: (m * j + shift_d) mod n
    j = np.arange(n1)
    idx = (m * j[None, :] + shift[:, None]) % n                                  # (n_dopp, n1)
    n_cells = len(dopplers) * n1
    thr = _threshold(pfa, n_cells, noncoherent)
    out = []
    for prn in prns:
        code = sample_code(sig.code(prn), sig.chip_rate, fs, n1).astype(np.complex64)
        cf = np.conj(sfft.fft(code)).astype(np.complex64)
        power = np.zeros((len(dopplers), n1), np.float32)
        for r in fracs:
            sel = np.flatnonzero(frac == r)
            for k in range(noncoherent):
                prod = spectra[r][k][idx[sel]] * cf[None, :]
                corr = sfft.ifft(prod, axis=1, workers=-1)
                power[sel] += corr.real ** 2 + corr.imag ** 2
        mean = float(power.mean())
        di, si = np.unravel_index(int(np.argmax(power)), power.shape)
        ptm = float(power[di, si]) / mean if mean > 0 and np.isfinite(mean) else 0.0
        metric = ptm / thr / threshold
        # the replica starts at sample si: the signal's code phase at sample 0 is -si samples
        code_phase = (-si * sig.chip_rate / fs) % sig.code_len
        dop = float(dopplers[di])
        # peak-to-mean - 1 ~ coherent SNR = C/N0 * T_coh (before straddle losses)
        cn0 = 10 * np.log10(max(ptm - 1.0, 1e-3) / T)
        res = AcqResult(prn, metric >= 1.0, dop, float(code_phase), start_index, float(metric), ptm,
                        float(cn0))
        if res.detected and fine:
            # symbols shorter than 10 ms (NH overlay, D2): refine over 1 ms blocks
            short = sig.secondary(prn) is not None or sig.bit_ms(prn) < 10
            res.doppler_hz = refine_doppler(samples, fs, if_hz, prn, res.code_phase_chips, dop, step,
                                            block_ms=1 if short else 10, n_blocks=40 if short else 20,
                                            signal=sig)
        out.append(res)
    return out


def refine_doppler(samples: np.ndarray, fs: float, if_hz: float, prn: int, code_phase_chips: float,
                   coarse_hz: float, bin_hz: float, block_ms: int = 10, n_blocks: int = 4,
                   signal=None) -> float:
    """Fine Doppler: wipe the code off `n_blocks` x `block_ms` blocks, zero-padded FFTs summed
    non-coherently around the coarse bin, peak interpolated.  Accuracy ~ a few Hz at 40 dB-Hz."""
    n = int(round(block_ms * 1e-3 * fs))
    total = min(n * n_blocks, len(samples))
    n_blocks = max(1, total // n)
    sig = signal if signal is not None else GPS_L1CA
    # the code Doppler matters over 200 ms (1.8 chips/s at 2.8 kHz): follow it
    code = sample_code(sig.code(prn), sig.chip_rate * (1.0 + coarse_hz / sig.carrier_hz), fs,
                       n * n_blocks, code_phase_chips)
    t = np.arange(n * n_blocks) / fs
    x = samples[:n * n_blocks] * code * np.exp(-2j * np.pi * (if_hz + coarse_hz) * t)
    nfft = 1 << int(np.ceil(np.log2(n * 8)))
    spec = np.zeros(nfft)
    for k in range(n_blocks):
        s = np.fft.fft(x[k * n:(k + 1) * n], nfft)
        spec += np.abs(s) ** 2
    freqs = np.fft.fftfreq(nfft, 1.0 / fs)
    sel = np.abs(freqs) <= 1.5 * bin_hz
    idx = np.flatnonzero(sel)
    i = idx[np.argmax(spec[idx])]
    # parabolic interpolation
    if 0 < i < nfft - 1:
        a, b, c = spec[i - 1], spec[i], spec[(i + 1) % nfft]
        den = a - 2 * b + c
        d = 0.5 * (a - c) / den if den != 0 else 0.0
    else:
        d = 0.0
    return float(coarse_hz + freqs[i] + d * fs / nfft)


def reject_cross_correlations(results: list[AcqResult], coherent_ms: int,
                              min_ratio_db: float = 15.0) -> list[AcqResult]:
    """Un-detect weak peaks that are cross-correlation images of a much stronger detected signal.

    Gold-code cross-correlation sidelobes reach -24 dB; they show up at the strong signal's Doppler
    (within one bin).  A detection whose coherent SNR is more than ``min_ratio_db`` below another
    detection's within half a Doppler bin (1/(2 T_coh)) is flagged as not detected.
    """
    half_bin = 1.0 / (2.0 * coherent_ms * 1e-3)
    strong = [r for r in results if r.detected]
    for r in strong:
        for s in strong:
            if s is r or not s.detected:
                continue
            ratio = 10 * np.log10(max(s.peak_to_mean - 1, 1e-9) / max(r.peak_to_mean - 1, 1e-9))
            if abs(s.doppler_hz - r.doppler_hz) <= half_bin and ratio > min_ratio_db:
                r.detected = False
                break
    return results
