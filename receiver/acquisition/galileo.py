"""Acquisition of Galileo E1 OS (``gal_e1``): FFT parallel code-phase search over the 4-ms BOC(1,1) codes.

Each 4-ms block (one primary-code period) is correlated coherently with the BOC(1,1) replicas of E1-B and
E1-C; the sign of both changes from period to period (the I/NAV symbol, the CS25 chip), so the periods are
summed non-coherently, and so are the two components (``|X B*|^2 + |X C*|^2``: 2 K exponential cells per code
phase and Doppler, Gamma(2K, 1/2K) once divided by the row's noise floor).  Doppler bins are 1/(2 x 4 ms) =
125 Hz apart; each bin's carrier is wiped off the samples once for all PRNs.  The detection statistic and the
threshold are those of :mod:`receiver.acquisition` (row floor by the median, Pfa over the whole grid).

BOC side peaks: the BOC(1,1) auto-correlation has side peaks of -1/2 at +/-1/2 chip (a quarter of the main
peak's power).  The grid's largest cell is taken, and then the power is re-evaluated with the replica at exact
fractional phases from -3/4 to +3/4 chip around it in 1/16-chip steps, over all blocks: the largest is the
main peak (:func:`resolve_side_peak`), so a side peak that won the grid by noise, or a grid peak that the
sampling of the narrow BOC peak left between the main and a side peak, is corrected before tracking starts
(the DLL's pull-in range is about +/-1/3 chip).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..estimation.stats import gamma_isf, gamma_median
from ..gnss.gal_codes import E1_CHIP_RATE, E1_CODE_LEN, E1_PERIOD_S
from ..gnss.registry import get_signal


@dataclass
class GalAcqResult:
    """One PRN's Galileo E1 search result: detection, Doppler (Hz), code phase (chips of the 4-ms code) and
    the detection statistic."""

    prn: int
    detected: bool
    doppler_hz: float
    code_phase_chips: float     # E1 primary-code phase (0..4092) at the block's first sample
    sample_index: int
    metric: float               # peak-to-floor / threshold
    cn0_dbhz_est: float
    side_peak_fixed: bool = False
    reason: str = ""            # why not detected (receiver.runfile.record.ACQ_REASONS)
    verified: int = -1          # no verification dwell


def _replica_fft(prn: int, fs: float, n: int, component: str) -> np.ndarray:
    rep = get_signal("gal_e1").sample_replica(prn, fs, n, 0.0, component)
    return np.conj(np.fft.fft(rep.astype(np.complex64)))


def block_power(samples, fs, if_hz, prn, code_phase_chips, doppler_hz, k) -> float:
    """Non-coherent E1-B + E1-C power of k 4-ms blocks with the replica at the exact code phase (chips at the
    first sample) and Doppler (the code Doppler included)."""
    sig = get_signal("gal_e1")
    n4 = int(round(fs * E1_PERIOD_S))
    t = np.arange(n4 * k) / fs
    x = samples[:n4 * k] * np.exp(-2j * np.pi * (if_hz + doppler_hz) * t)
    rate = E1_CHIP_RATE * (1.0 + doppler_hz / sig.carrier_hz)
    total = 0.0
    for comp in ("B", "C"):
        rep = sig.replica(prn, comp)
        idx = np.floor(2.0 * (code_phase_chips + t * rate)).astype(np.int64) % rep.size
        prod = (x * rep[idx]).reshape(k, n4).sum(axis=1)
        total += float(np.sum(np.abs(prod) ** 2))
    return total


def resolve_side_peak(samples, fs, if_hz, prn, code_phase_chips, doppler_hz, k, step: float = 0.0625):
    """(code phase, moved): the exact-phase power (:func:`block_power`) over the grid peak +/- 3/4 chip in steps
    of ``step`` chips; its maximum is the main peak (a side peak at +/-1/2 chip has a quarter of its power, and
    the grid's sample spacing - 1/4 chip at 4 MS/s - can leave the grid peak between the main and a side peak
    at low C/N0).  ``moved``: the maximum is more than 1/4 chip from the grid peak (a side peak was taken)."""
    offsets = np.arange(-0.75, 0.75 + step / 2, step)
    p = [block_power(samples, fs, if_hz, prn, (code_phase_chips + o) % E1_CODE_LEN, doppler_hz, k)
         for o in offsets]
    best = float(offsets[int(np.argmax(p))])
    return (code_phase_chips + best) % E1_CODE_LEN, abs(best) > 0.25


def search(samples: np.ndarray, start_index: int, fs: float, if_hz: float, prns, noncoherent: int = 5,
           doppler_max_hz: float = 6000.0, doppler_center_hz: float = 0.0, pfa: float = 1e-3,
           threshold: float = 1.25) -> list[GalAcqResult]:
    """Search Galileo E1 ``prns`` in ``samples`` (complex, first sample = file index ``start_index``):
    ``noncoherent`` 4-ms blocks, Doppler ``doppler_center_hz`` +/- ``doppler_max_hz``."""
    n4f = fs * E1_PERIOD_S
    if abs(n4f - round(n4f)) > 1e-6:
        raise ValueError("Galileo acquisition needs a whole number of samples per 4-ms code period")
    n4 = int(round(n4f))
    k = int(noncoherent)
    if len(samples) < n4 * k:
        raise ValueError(f"Galileo acquisition needs {n4 * k} samples, got {len(samples)}")
    x = np.asarray(samples[:n4 * k], np.complex64)
    step = 1.0 / (2.0 * E1_PERIOD_S)
    dopplers = doppler_center_hz + np.arange(-doppler_max_hz, doppler_max_hz + step / 2, step)
    t = (np.arange(n4 * k) / fs).astype(np.float64)
    # spectra of every block for every Doppler bin (shared by the PRNs)
    spec = np.empty((len(dopplers), k, n4), np.complex64)
    for i, d in enumerate(dopplers):
        y = x * np.exp(-2j * np.pi * (if_hz + d) * t).astype(np.complex64)
        spec[i] = np.fft.fft(y.reshape(k, n4), axis=1)
    shape = 2 * k                                         # exponential cells summed per grid cell
    thr = float(gamma_isf(pfa / (len(dopplers) * n4), shape)) * threshold
    out = []
    for prn in prns:
        power = np.zeros((len(dopplers), n4))
        for comp in ("B", "C"):
            r = _replica_fft(prn, fs, n4, comp)
            power += (np.abs(np.fft.ifft(spec * r[None, None, :], axis=2)) ** 2).sum(axis=1)
        floor = np.median(power, axis=1) / float(gamma_median(shape))
        pn = power / np.maximum(floor, 1e-30)[:, None]
        di, si = np.unravel_index(int(np.argmax(pn)), pn.shape)
        ptm = float(pn[di, si])
        detected = ptm >= thr
        # the replica starting at sample si matches: the signal's code phase at sample 0 lies within one sample
        # after -si samples; the middle of that sample (the BOC(1,1) peak is only ~2/3 chip wide at its base)
        code_phase = ((-si + 0.5) * E1_CHIP_RATE / fs) % E1_CODE_LEN
        dop = float(dopplers[di])
        fixed = False
        if detected:
            code_phase, fixed = resolve_side_peak(x, fs, if_hz, prn, code_phase, dop, k)
        # peak-to-floor - 1 ~ coherent SNR of one component's 4 ms: C/N0 = that / 4 ms, x 2 (two components)
        cn0 = float(10 * np.log10(max(ptm - 1.0, 1e-3) * 2.0 / E1_PERIOD_S))
        out.append(GalAcqResult(int(prn), bool(detected), dop, float(code_phase), int(start_index),
                                ptm / thr, cn0, fixed))
    return out


def refine_pilot(samples, fs, if_hz, prn, code_phase_chips, doppler_hz, n_periods: int = 50,
                 span_hz: float = 75.0, step_hz: float = 1.0):
    """(Doppler, CS25 offset) from ``n_periods`` E1-C prompts at the acquired code phase: for each of the 25
    alignments of CS25 (period k of the block carries chip (k + offset) mod 25) the pilot prompts with the
    secondary code wiped are summed coherently over the Doppler grid ``doppler_hz`` +/- ``span_hz``; the
    largest sum gives both (the block's first sample is sample 0 of ``samples``)."""
    from ..gnss.gal_codes import cs25_signs
    sig = get_signal("gal_e1")
    n4 = int(round(fs * E1_PERIOD_S))
    t = np.arange(n4 * n_periods) / fs
    x = np.asarray(samples[:n4 * n_periods]) * np.exp(-2j * np.pi * (if_hz + doppler_hz) * t)
    rate = E1_CHIP_RATE * (1.0 + doppler_hz / sig.carrier_hz)
    ch = code_phase_chips + t * rate
    rep = sig.replica(prn, "C")
    v = x * rep[np.floor(2.0 * ch).astype(np.int64) % rep.size]
    per = np.floor(ch / E1_CODE_LEN).astype(np.int64)            # period of the block each sample is in
    k = per - per[0]
    prompts = np.bincount(k, v.real) + 1j * np.bincount(k, v.imag)
    t_per = np.bincount(k, t) / np.maximum(np.bincount(k), 1)       # mean time of each period's samples
    cs = cs25_signs()
    df = np.arange(-span_hz, span_hz + step_hz / 2, step_hz)
    rot = np.exp(-2j * np.pi * df[:, None] * t_per[None, :])       # (n_f, n_per)
    best = (-1.0, 0.0, 0)
    for off in range(25):
        s = cs[(np.arange(len(prompts)) + per[0] + off) % 25]
        z = np.abs(rot @ (prompts * s))
        i = int(np.argmax(z))
        if z[i] > best[0]:
            best = (float(z[i]), float(df[i]), off)
    return doppler_hz + best[1], best[2]
