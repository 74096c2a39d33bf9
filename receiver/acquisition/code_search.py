"""Acquisition: FFT parallel code-phase search, non-coherent integration, fine Doppler refinement, and
the integrity checks that keep spurs and strong signals from opening channels.

Detection statistic: every cell of the (non-coherently summed) correlation power grid is divided by the
robust noise floor of its Doppler row (median / median of Gamma(K, 1/K)).  Under noise only each cell is
then Gamma(K, 1/K) distributed (K non-coherent sums of exponential cells), so the threshold for a given
probability of false alarm over the whole grid ``pfa`` is ``gamma.isf(pfa / n_cells, K, scale=1/K)``.
The row floor makes the test hold when a CW tone or a strong signal raises whole rows.  The reported
``metric`` is the peak-to-floor ratio divided by that threshold; a detection also needs a narrow peak
(``width_ratio``).  Use ``acquisition.threshold`` to scale the threshold (default 1.25).

Then (receiver/pipeline.py ``acquire``): a verification dwell on the next independent block
(:func:`verify`) and the rejection of cross-correlation images of stronger satellites at the same
Doppler or at whole-kHz offsets (:func:`reject_cross_correlations`).

Why this module is long: search, verification dwell and fine Doppler refinement stay in one module; they
share the code spectra, the compiled power kernels and the detection statistic's helpers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from ..estimation.stats import gamma_isf, gamma_median, median_last_axis

from ..gnss.signals import GPS_L1CA, sample_code
from ..runfile.record import ACQ_REASONS
from ..threads import map_ordered, threads


@dataclass
class AcqResult:
    """Outcome of the search for one PRN: detected or not, carrier Doppler (Hz), code phase (chips) of the signal
    at file sample ``sample_index`` (the searched block's first), detection metrics, C/N0 estimate (dB-Hz),
    why a peak was rejected and the verification dwell's result."""
    prn: int
    detected: bool
    doppler_hz: float          # carrier Doppler (fine if detected)
    code_phase_chips: float    # code phase of the signal at the first sample of the searched block
    sample_index: int          # file index of that first sample
    metric: float              # peak-to-floor / threshold (>= 1: above the threshold)
    peak_to_mean: float        # peak over the noise floor of its Doppler row
    cn0_dbhz_est: float
    reason: str = ""           # why not detected: threshold, width, xcorr, verify ("" if detected)
    verified: int = -1         # verification dwell: 1 passed, 0 failed, -1 not run


#: codes of AcqResult.reason in the run file (/acquisition/reason)
REASONS = ACQ_REASONS


def _threshold(pfa: float, n_cells: int, k: int) -> float:
    return float(gamma_isf(pfa / n_cells, k))


def _has_energy(x: np.ndarray) -> bool:
    """False when the block is constant (all zero or pure DC): no correlation peak can be a signal."""
    return bool(np.any(x != x[0])) if len(x) else False
def _gamma_median(k: int) -> float:
    return float(gamma_median(k))


class _Spectra:
    """FFTs of the K coherent blocks of ``samples`` for a set of Doppler bins (shared by all PRNs)."""

    def __init__(self, samples, fs, if_hz, dopplers, m, k):
        n1 = int(round(fs * 1e-3))
        n = n1 * m
        T = m * 1e-3
        pos = (if_hz + dopplers) * T
        shift = np.floor(pos + 1e-9).astype(np.int64)
        self.frac = np.round(pos - shift, 6)
        self.fracs = np.unique(self.frac)
        t = np.arange(n) / fs
        blocks = samples[:n * k].reshape(k, n)
        self.spectra = {}
        for r in self.fracs:
            mix = np.exp(-2j * np.pi * (r / T) * t).astype(np.complex64)
            self.spectra[r] = np.fft.fft(blocks * mix[None, :], axis=1)       # (K, n)
        j = np.arange(n1)
        # bin index of decimated line j for Doppler d: (m * j + shift_d) mod n
        self.idx = (m * j[None, :] + shift[:, None]) % n                               # (n_dopp, n1)
        self.n1, self.k, self.n_dopp, self.m = n1, k, len(dopplers), m
        # the same lines as m ((j + q_d) mod n1) + rho_d: line q of residue rho (lines 1 kHz apart)
        self.q, self.rho = shift // m, shift % m
        self._residues = {}

    def _residue_spectra(self, r):
        """(K, m, n1): block k's spectrum for fraction r, line m q + rho at [k, rho, q]."""
        if r not in self._residues:
            s = self.spectra[r].reshape(self.k, self.n1, self.m)
            self._residues[r] = np.ascontiguousarray(s.transpose(0, 2, 1))
        return self._residues[r]

    def power(self, cf):
        """Non-coherently summed correlation power (n_dopp, n1) for the conjugate code spectrum cf.

        Doppler bin d multiplies the lines (j + q_d) mod n1 of its residue's spectrum by cf[j].  |IFFT|
        does not change when that product is shifted circularly, so line j' of the spectrum meets
        cf[(j' - q_d) mod n1] instead: the code spectrum is shifted once per PRN and Doppler (the same
        pairs of numbers multiplied as before; no gather of the block spectra per block)."""
        n1 = self.n1
        power = np.zeros((self.n_dopp, n1), np.float32)
        code = np.empty((self.n_dopp, n1), np.complex64)
        _roll_rows(cf, self.q, code)                                                  # cf[(j - q_d) mod n1]
        for r in self.fracs:
            sel = np.flatnonzero(self.frac == r)
            spec = self._residue_spectra(r)
            rho = self.rho[sel]
            code_r = np.ascontiguousarray(code[sel])
            prod = np.empty((len(sel), n1), np.complex64)
            for k in range(self.k):
                _mul_rows(spec[k].view(np.float32), rho, code_r.view(np.float32), prod.view(np.float32))
                corr = np.fft.ifft(prod, axis=1, out=prod)
                _add_power(corr, sel, power)                     # power[sel] += |corr|^2
        return power


@njit(cache=True, nogil=True)
def _mul_rows(spec, rho, code, out):
    """out[i, j] = spec[rho[i], j] * code[i, j] for complex64 arrays seen as float32 (re, im) pairs: the
    products numpy's complex multiply forms (re = a c - b d, im = a d + b c)."""
    for i in range(out.shape[0]):
        s = spec[rho[i]]
        c = code[i]
        o = out[i]
        for j in range(out.shape[1] // 2):
            a, b, cr, ci = s[2 * j], s[2 * j + 1], c[2 * j], c[2 * j + 1]
            o[2 * j] = a * cr - b * ci
            o[2 * j + 1] = a * ci + b * cr


@njit(cache=True, nogil=True)
def _roll_rows(cf, shifts, out):
    """out[i, j] = cf[(j - shifts[i]) mod n]: the code spectrum shifted circularly per Doppler row."""
    n = cf.shape[0]
    for i in range(out.shape[0]):
        s = shifts[i] % n
        for j in range(n):
            k = j - s
            if k < 0:
                k += n
            out[i, j] = cf[k]


@njit(cache=True, nogil=True)
def _gather(spec, idx, out):
    """out[i, j] = spec[idx[i, j]]: the Doppler rows (circular shifts) of one block's spectrum."""
    for i in range(idx.shape[0]):
        for j in range(idx.shape[1]):
            out[i, j] = spec[idx[i, j]]


@njit(cache=True, nogil=True)
def _add_power(corr, rows, power):
    """power[rows[i]] += |corr[i]|^2 (real^2 + imag^2, float32, in numpy's order)."""
    for i in range(corr.shape[0]):
        r = rows[i]
        for j in range(corr.shape[1]):
            c = corr[i, j]
            power[r, j] += c.real * c.real + c.imag * c.imag


@njit(cache=True, nogil=True)
def _add_power_shifted(corr, rows, shifts, acc):
    """acc[rows[i], j] += |corr[i, (j - shifts[i]) mod n1]|^2 (real^2 + imag^2 in float32, as numpy forms
    it): the high-sensitivity pass's power of one block, each row moved back by its code drift."""
    n1 = corr.shape[1]
    for i in range(corr.shape[0]):
        r = rows[i]
        s = shifts[i] % n1
        for j in range(n1):
            jj = j - s
            if jj < 0:
                jj += n1
            c = corr[i, jj]
            acc[r, j] += c.real * c.real + c.imag * c.imag


@njit(cache=True, nogil=True)
def _code_wipe(x, code, phase, ratio):
    """x * sample_code(code, ratio * fs, fs, len(x), phase): the same chip index (floor of phase + i ratio,
    modulo the code length) and the same products as numpy's."""
    out = np.empty(x.shape[0], x.dtype)
    n_code = code.shape[0]
    if phase < 0.0 or ratio < 0.0 or ratio >= n_code:
        for i in range(x.shape[0]):
            out[i] = x[i] * code[np.int64(np.floor(phase + i * ratio)) % n_code]
        return out
    # phase + i ratio >= 0 and grows by less than a code length per sample: the truncation is the floor,
    # and the modulo a running multiple of the code length (half the time of floor and modulo per sample)
    base = 0
    for i in range(x.shape[0]):
        k = np.int64(phase + i * ratio) - base
        if k >= n_code:
            base += n_code
            k -= n_code
        out[i] = x[i] * code[k]
    return out


def _code_fft(sig, prn, fs, n1):
    code = sample_code(sig.code(prn), sig.chip_rate, fs, n1).astype(np.complex64)
    return np.conj(np.fft.fft(code)).astype(np.complex64)


def _row_floor(power, k):
    """Robust noise floor of each Doppler row: median / median of Gamma(K, 1/K).  A tone or a strong
    signal raising whole rows (all code phases) raises their floor with them."""
    med = median_last_axis(power) if power.shape[1] < 20000 else median_last_axis(power[:, ::4])
    return np.maximum(med / _gamma_median(k), 1e-30)


def _side_excess(row, si, spc):
    """Mean normalised power 2..4 chips on both sides of the peak, minus 1 (the floor)."""
    n1 = row.size
    d = np.arange(int(np.ceil(2 * spc)), int(np.floor(4 * spc)) + 1)
    if d.size == 0:
        d = np.array([2, 3, 4])
    cells = np.concatenate([row[(si + d) % n1], row[(si - d) % n1]])
    return float(cells.mean()) - 1.0


def search(samples: np.ndarray, start_index: int, fs: float, if_hz: float, prns, coherent_ms: int = 4,
           noncoherent: int = 10, doppler_max_hz: float = 10000.0, doppler_step_hz: float | None = None,
           pfa: float = 1e-3, threshold: float = 1.0, fine: bool = True, signal=None,
           doppler_center_hz: float = 0.0, width_ratio: float = 0.3) -> list[AcqResult]:
    """Search `prns` in `samples` (complex64, first sample = file index start_index).

    Each coherent block of T = coherent_ms is Fourier transformed once per distinct fractional Doppler
    offset (in units of 1/T); a Doppler bin is then a circular shift of that spectrum.  The replica of
    coherent_ms code periods has spectral lines only on every coherent_ms-th bin, so the correlation
    over all code phases of one period is an inverse FFT of one period's length.
    ``signal``: a :class:`receiver.signals.SignalDef` (default GPS L1 C/A); its code period must be 1 ms.

    Detection (integrity against spurs and strong signals): every cell is divided by the robust noise
    floor of its Doppler row (:func:`_row_floor`); the largest normalised cell is tested against the
    Pfa-derived threshold; a peak must also be narrow -- the mean power 2-4 chips on either side, above
    the floor, below ``width_ratio`` times the peak's (a correlation peak is 2 chips wide; a CW tone
    beating with the code's spectral lines gives maxima hundreds of chips wide).  The best few Doppler
    rows are tried in turn.  ``doppler_center_hz``: centre of the Doppler search range.
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
    dopplers = doppler_center_hz + np.arange(-doppler_max_hz, doppler_max_hz + step / 2, step)
    sp = _Spectra(samples, fs, if_hz, dopplers, m, noncoherent)
    n_cells = len(dopplers) * n1
    thr = _threshold(pfa, n_cells, noncoherent)
    spc = fs / sig.chip_rate
    # the PRNs are independent: on several threads each searches its own PRNs (the same numbers as one
    # thread searching them all; numpy's FFTs release the GIL)
    parallel = threads() > 1 and len(prns) > 1

    def one(prn):
        power = sp.power(_code_fft(sig, prn, fs, n1))
        pn = power / _row_floor(power, noncoherent)[:, None]
        row_max = pn.max(axis=1)
        order = np.argsort(-row_max)
        di = int(order[0])
        reason = "threshold"
        for cand in order[:8]:
            if row_max[cand] < thr * threshold:
                break
            s = int(np.argmax(pn[cand]))
            if _side_excess(pn[cand], s, spc) <= width_ratio * (row_max[cand] - 1.0):
                di, reason = int(cand), ""
                break
            reason = "width"
        si = int(np.argmax(pn[di]))
        ptm = float(pn[di, si])
        metric = ptm / thr / threshold
        # the replica starts at sample si: the signal's code phase at sample 0 is -si samples
        code_phase = (-si * sig.chip_rate / fs) % sig.code_len
        dop = float(dopplers[di])
        # peak-to-floor - 1 ~ coherent SNR = C/N0 * T_coh (before straddle losses)
        cn0 = 10 * np.log10(max(ptm - 1.0, 1e-3) / T)
        res = AcqResult(prn, reason == "", dop, float(code_phase), start_index, float(metric), ptm,
                        float(cn0), reason)
        if res.detected and fine:
            # symbols shorter than 10 ms (NH overlay, D2): refine over 1 ms blocks
            short = sig.short_symbols(prn)
            res.doppler_hz = refine_doppler(samples, fs, if_hz, prn, res.code_phase_chips, dop, step,
                                            block_ms=1 if short else 10, n_blocks=40 if short else 20,
                                            signal=sig)
            if short:
                res.doppler_hz = refine_doppler_squared(samples, fs, if_hz, prn, res.code_phase_chips,
                                                        res.doppler_hz, signal=sig)
        return res

    return map_ordered(one, list(prns)) if parallel else [one(p) for p in prns]


def _folded_power(samples, fs, if_hz, dopplers, m, k, cf):
    """The power grid of :meth:`_Spectra.power` for a few Doppler bins: each coherent block of m code periods,
    carrier wiped off at the bin's frequency, folded onto one period (the sum of its m periods: the same
    as taking every m-th line of the block's spectrum), then one FFT of one period."""
    n1 = int(round(fs * 1e-3))
    n = n1 * m
    t = np.arange(n) / fs
    blocks = samples[:n * k].reshape(k, n)
    power = np.zeros((len(dopplers), n1), np.float32)
    for i, d in enumerate(dopplers):
        mix = np.exp(-2j * np.pi * (if_hz + d) * t).astype(np.complex64)
        folded = (blocks * mix[None, :]).reshape(k, m, n1).sum(axis=1)
        corr = np.fft.ifft(np.fft.fft(folded, axis=1) * cf[None, :], axis=1)
        power[i] = (corr.real ** 2 + corr.imag ** 2).sum(axis=0)
    return power


def verify(samples: np.ndarray, start_index: int, fs: float, if_hz: float, res: AcqResult,
           coherent_ms: int, noncoherent: int, doppler_step_hz: float | None = None, pfa: float = 1e-3,
           threshold: float = 1.0, signal=None, window_chips: float = 1.5) -> bool:
    """Verification dwell: search ``res`` again in an independent block ``samples`` (first sample =
    file index ``start_index``) over 3 Doppler bins around its Doppler and +/- ``window_chips`` around its
    code phase carried forward at the code rate.  Passes when the largest cell of that small window,
    over its row's noise floor, exceeds the Pfa threshold for the window's cell count -- or when the largest
    cell of the three rows at any code phase exceeds the Pfa threshold for all their cells: a front end
    that drops samples (a USB buffer overrun) moves every code phase between the two blocks, the
    satellite's Doppler stays; the second test has the same false-alarm probability as the first."""
    sig = signal if signal is not None else GPS_L1CA
    n1 = int(round(fs * 1e-3))
    step = doppler_step_hz or 1.0 / (2.0 * coherent_ms * 1e-3)
    dopplers = res.doppler_hz + step * np.array([-1.0, 0.0, 1.0])
    power = _folded_power(samples, fs, if_hz, dopplers, coherent_ms, noncoherent, _code_fft(sig, res.prn, fs, n1))
    pn = power / _row_floor(power, noncoherent)[:, None]
    cols = verify_columns(res, start_index, fs, sig, window_chips)
    thr = _threshold(pfa, 3 * cols.size, noncoherent)
    if pn[:, cols].max() >= thr * threshold:
        return True
    return bool(pn.max() >= _threshold(pfa, pn.size, noncoherent) * threshold)


def verify_columns(res, start_index: int, fs: float, sig, window_chips: float) -> np.ndarray:
    """Code-phase columns (samples of the 1-ms correlation) within +/- window_chips of the code phase of
    detection ``res`` carried forward at the code rate to file index ``start_index``."""
    n1 = int(round(fs * 1e-3))
    dt = (start_index - res.sample_index) / fs
    phase = (res.code_phase_chips + dt * sig.chip_rate * (1.0 + res.doppler_hz / sig.carrier_hz)) \
        % sig.code_len
    spc = fs / sig.chip_rate
    si0 = int(round(-phase * spc)) % n1
    w = int(np.ceil(window_chips * spc))
    return (si0 + np.arange(-w, w + 1)) % n1


def refine_doppler(samples: np.ndarray, fs: float, if_hz: float, prn: int, code_phase_chips: float,
                   coarse_hz: float, bin_hz: float, block_ms: int = 10, n_blocks: int = 4,
                   signal=None) -> float:
    """Fine Doppler: wipe the code off `n_blocks` x `block_ms` blocks, zero-padded FFTs summed
    non-coherently around the coarse bin, peak interpolated.  Accuracy ~ a few Hz at 40 dB-Hz."""
    n1 = int(round(1e-3 * fs))
    block_ms = max(1, min(block_ms, len(samples) // n1))     # short files: what is available
    n = int(round(block_ms * 1e-3 * fs))
    total = min(n * n_blocks, len(samples))
    n_blocks = max(1, total // n)
    sig = signal if signal is not None else GPS_L1CA
    # the code Doppler matters over 200 ms (1.8 chips/s at 2.8 kHz): follow it (the samples times
    # sample_code(code, chip rate with Doppler, fs, ...), in one compiled pass)
    y = _code_wipe(samples[:n * n_blocks], sig.code(prn), float(code_phase_chips),
                   sig.chip_rate * (1.0 + coarse_hz / sig.carrier_hz) / fs).reshape(n_blocks, n)
    nfft = 1 << int(np.ceil(np.log2(n * 8)))
    # Power of the nfft-point zero-padded spectrum of each block after the carrier wipe-off at the coarse
    # Doppler, summed over the blocks.  Only the lines within +/- 1.5 bins of the coarse Doppler (and one
    # either side for the interpolation) are needed (:func:`_line_powers`; the wipe-off phase at a block's
    # first sample is a unit factor per block, gone in |.|^2), instead of n_blocks FFTs of nfft points.
    kmax = int(np.floor(1.5 * bin_hz * nfft / fs))
    ks = np.arange(-kmax - 1, kmax + 2)
    spec_k = _line_powers(y, (if_hz + coarse_hz) / fs, ks, nfft)   # power at the lines ks
    inner = slice(1, len(ks) - 1)                                  # |f| <= 1.5 bins
    # FFT order of the lines (0..kmax, then -kmax..-1) so that a tie resolves as np.argmax over the FFT did
    order = np.concatenate([np.flatnonzero(ks[inner] >= 0), np.flatnonzero(ks[inner] < 0)]) + 1
    j = int(order[np.argmax(spec_k[order])])
    k = int(ks[j])
    i = k % nfft
    # parabolic interpolation (not at FFT index 0 or nfft - 1, as before)
    if 0 < i < nfft - 1:
        a, b, c = spec_k[j - 1], spec_k[j], spec_k[j + 1]
        den = a - 2 * b + c
        d = 0.5 * (a - c) / den if den != 0 else 0.0
    else:
        d = 0.0
    return float(coarse_hz + k * fs / nfft + d * fs / nfft)


#: squared-block refinement (:func:`refine_doppler_squared`): search range around the 1-ms estimate (Hz; the
#: squared blocks, 1 kHz apart, see 2 x this unambiguously: +/-250 Hz, then +/-500 Hz decided by the 1-ms
#: power), line spacing, and the significance
#: the peak of the squared blocks' spectrum needs over its mean (else the 1-ms estimate is kept)
SQ_RANGE_HZ = 250.0
SQ_STEP_HZ = 0.5
SQ_MIN_PEAK = 8.0


def refine_doppler_squared(samples: np.ndarray, fs: float, if_hz: float, prn: int, code_phase_chips: float,
                           doppler_hz: float, n_blocks: int = 200, signal=None) -> float:
    """Fine Doppler of a signal whose symbols are too short for long coherent blocks (B1I: NH code x D1 bits
    every 1 ms, D2 symbols every 2 ms): the 1-ms estimate (:func:`refine_doppler` over 1-ms blocks, its
    lines ~76-122 Hz apart on a 1-kHz-wide lobe: errors of 40-130 Hz measured at 45 dB-Hz) refined by
    squaring.  Each 1-ms block's correlation z_b (code and carrier at ``doppler_hz`` wiped) carries the
    symbol sign +/-1 (the blocks are aligned to the code periods); z_b^2 loses the sign and
    rotates at twice the residual frequency, so its spectrum over all blocks (up to 200 ms coherently)
    peaks at 2 df within a line of a few Hz (2 df modulo 1 kHz: df, df - 500 and df + 500 Hz are told apart by
    the 1-ms blocks' power).  The residual is searched within +/-SQ_RANGE_HZ; without a peak
    SQ_MIN_PEAK times the spectrum's mean (weak signal) the 1-ms estimate is returned unchanged."""
    sig = signal if signal is not None else GPS_L1CA
    n = int(round(1e-3 * fs))
    rate = sig.chip_rate * (1.0 + doppler_hz / sig.carrier_hz) / fs    # chips per sample
    # the blocks start at a code period's first chip: each holds one symbol (a block straddling a sign
    # change loses amplitude, half the time at the NH rate; up to 4 dB of the squares' SNR)
    s0 = sig.samples_to_period_start(code_phase_chips, rate)
    nb = min(n_blocks, (len(samples) - s0) // n)
    if nb < 20:
        return doppler_hz
    y = _code_wipe(samples[s0:s0 + nb * n], sig.code(prn), (float(code_phase_chips) + s0 * rate) % sig.code_len,
                   rate).reshape(nb, n)
    f0 = (if_hz + doppler_hz) / fs                                    # cycles per sample
    m = np.arange(n)
    # the carrier wipe-off within a block (one row of exponentials), then the block's own start phase
    z = (y @ np.exp(-2j * np.pi * f0 * m)) * np.exp(-2j * np.pi * ((f0 * (s0 + n * np.arange(nb))) % 1.0))
    w = z * z                                                         # sign-free, at 2 x the residual
    df = np.arange(-SQ_RANGE_HZ, SQ_RANGE_HZ, SQ_STEP_HZ)
    tb = np.arange(nb) * (n / fs)                                     # block start times
    spec = np.abs(np.exp(-2j * np.pi * np.outer(2.0 * df, tb)) @ w) ** 2
    j = int(np.argmax(spec))
    if spec[j] < SQ_MIN_PEAK * np.mean(spec):
        return doppler_hz
    d = 0.0
    if 0 < j < len(spec) - 1:
        a, b, c = spec[j - 1], spec[j], spec[j + 1]
        den = a - 2 * b + c
        d = 0.5 * (a - c) / den if den != 0 else 0.0
    res = df[j] + d * SQ_STEP_HZ
    # z^2 of 1-ms blocks cannot tell df from df +/- 500 Hz: the 1-ms blocks' own power decides (at a 500 Hz
    # error it is down to sinc^2(1/2) = -3.9 dB; a weak detection's 1-ms estimate can be that far off)
    cands = [res - 500.0, res, res + 500.0]
    pw = [float(np.sum(np.abs(y @ np.exp(-2j * np.pi * (f0 + c_ / fs) * m)) ** 2)) for c_ in cands]
    return float(doppler_hz + cands[int(np.argmax(pw))])


def _line_powers_direct(y: np.ndarray, f0: float, ks: np.ndarray, nfft: int) -> np.ndarray:
    """sum_b |sum_m y[b, m] exp(-2 pi i m (f0 + k / nfft))|^2 for k in ks (consecutive): the direct DFT at
    those lines, one row of exponentials per line (the reference for :func:`_line_powers`)."""
    n = y.shape[1]
    m = np.arange(n)
    dft = np.empty((len(ks), n), np.complex128)                   # exp(-2 pi i m (f0 + k / nfft))
    dft[0] = np.exp(-2j * np.pi * m * (f0 + ks[0] / nfft))
    w = np.exp(-2j * np.pi * m / nfft)
    for j in range(1, len(ks)):
        dft[j] = dft[j - 1] * w
    return (np.abs(np.dot(dft, y.T)) ** 2).sum(axis=1)


#: terms of the Taylor series of exp(-2 pi i r k / nfft) within a segment (|argument| <= _SEG_ARG: the
#: first term left out is below 1e-18 of the sum)
_TAYLOR_TERMS = 8
_SEG_ARG = 0.02


def _line_powers(y: np.ndarray, f0: float, ks: np.ndarray, nfft: int) -> np.ndarray:
    """:func:`_line_powers_direct` with ~1/3 of the arithmetic, all of it in BLAS: the samples (carrier
    wiped off at f0) in segments of D, m = q D + r; exp(-2 pi i m k / nfft) = exp(-2 pi i q D k / nfft)
    x exp(-2 pi i r k / nfft), the second factor as its Taylor series in r / D (D such that the argument
    stays within 0.02 rad: 8 terms are exact to rounding).  Per block the moments M_p[q] = sum_r z[qD + r]
    (r / D)^p (one matrix product), then X_k = sum_p (-2 pi i k D / nfft)^p / p! sum_q exp(-2 pi i q D k /
    nfft) M_p[q] (a second).  The same values to ~1e-15 relative (tests/unit/acquisition/test_acquisition_cost.py).  Few
    lines or short segments (wide bins, short blocks): the direct DFT, which is then as cheap."""
    b, n = y.shape
    kk = max(1, int(np.max(np.abs(ks))))
    d = max(1, int(_SEG_ARG * nfft / (2.0 * np.pi * kk)))
    if d < 20 or len(ks) < 3 * _TAYLOR_TERMS:
        return _line_powers_direct(y, f0, ks, nfft)
    q = -(-n // d)
    p = np.arange(_TAYLOR_TERMS)
    powers = (np.arange(d) / d)[None, :] ** p[:, None]              # (P, D): (r / D)^p
    mom = _segment_moments(y, np.exp(-2j * np.pi * np.arange(n) * f0), d, powers).reshape(b * len(p), q)
    qd = (np.outer(np.arange(q) * d, ks) % nfft) / nfft             # q D k / nfft, reduced exactly
    v = np.exp(-2j * np.pi * qd)                                    # (Q, K)
    t = (mom @ v).reshape(b, len(p), len(ks))                       # (B, P, K), one matrix product
    fact = np.cumprod(np.concatenate([[1.0], np.arange(1, len(p))]))
    coef = (-2j * np.pi * ks[None, :] * d / nfft) ** p[:, None] / fact[:, None]     # (P, K)
    x = (t * coef[None, :, :]).sum(axis=1)                          # (B, K)
    return (x.real ** 2 + x.imag ** 2).sum(axis=0)


@njit(cache=True, nogil=True, fastmath=True)
def _segment_moments(y, ramp, d, powers):
    """mom[b, p, q] = sum_r z[b, q d + r] powers[p, r] with z = y x ramp (the carrier wiped off; rows of y
    are blocks, the last segment may be short): one pass over the samples, no complex128 copy of y."""
    nb, n = y.shape
    P = powers.shape[0]
    nq = (n + d - 1) // d
    mom = np.zeros((nb, P, nq), np.complex128)
    zr = np.empty(d)
    zi = np.empty(d)
    for b in range(nb):
        for q in range(nq):
            m0 = q * d
            cnt = min(d, n - m0)
            for r in range(cnt):
                w = np.complex128(y[b, m0 + r]) * ramp[m0 + r]
                zr[r] = w.real
                zi[r] = w.imag
            for p in range(P):
                sr = 0.0
                si = 0.0
                for r in range(cnt):
                    sr += zr[r] * powers[p, r]
                    si += zi[r] * powers[p, r]
                mom[b, p, q] = complex(sr, si)
    return mom


def cross_correlation_image(strong: AcqResult, weak: AcqResult, fs: float, coherent_ms: int,
                            signal=None) -> float:
    """|R|^2: power of the image of the signal ``strong`` in ``weak``'s replica at ``weak``'s code phase and
    Doppler, relative to ``strong``'s own correlation peak (1 for the same code at the same phase).

    Computed from the sampled codes over ``coherent_ms`` (the product of two C/A codes is 1 ms periodic,
    with spectral lines every 1 kHz: a Doppler difference of k x 1 kHz lets a line through); the largest
    over +/- half a sample of ``weak``'s code phase (its resolution)."""
    sig = signal if signal is not None else GPS_L1CA
    n = int(round(fs * 1e-3)) * coherent_ms
    t = np.arange(n) / fs
    dd = strong.doppler_hz - weak.doppler_hz
    s = sample_code(sig.code(strong.prn), sig.chip_rate, fs, n, strong.code_phase_chips) \
        * np.exp(2j * np.pi * dd * t)
    best = 0.0
    for off in (-0.5, 0.0, 0.5):
        r = sample_code(sig.code(weak.prn), sig.chip_rate, fs, n, weak.code_phase_chips
                        + off * sig.chip_rate / fs)
        best = max(best, abs(np.sum(s * r)) / n)
    return best ** 2


def reject_cross_correlations(results: list[AcqResult], coherent_ms: int, min_ratio_db: float = 15.0,
                              fs: float | None = None, signal=None, max_k: int = 60,
                              image_fraction: float = 0.25) -> list[AcqResult]:
    """Un-detect weak peaks that are cross-correlation images of a much stronger detected signal.

    Same Doppler: Gold-code cross-correlation sidelobes reach -24 dB; a detection whose coherent SNR is
    more than ``min_ratio_db`` below another detection's within half a Doppler bin (1/(2 T_coh)) is
    flagged as not detected.
    Whole-kHz offsets (needs ``fs``): a detection whose Doppler differs from a stronger detection's by
    k x 1 kHz (0 < |k| <= max_k, within half a bin) is flagged when the image of the stronger signal
    predicted at the weak one's code phase (:func:`cross_correlation_image`, from the two codes) is at
    least ``image_fraction`` of the weak peak's power: the code phase is consistent with
    cross-correlation.  A real satellite at such an offset but another code phase is kept.
    """
    half_bin = 1.0 / (2.0 * coherent_ms * 1e-3)
    strong = sorted([r for r in results if r.detected], key=lambda r: -r.peak_to_mean)
    for r in strong:
        for s in strong:
            if s is r or not s.detected or s.peak_to_mean <= r.peak_to_mean:
                continue
            ratio = 10 * np.log10(max(s.peak_to_mean - 1, 1e-9) / max(r.peak_to_mean - 1, 1e-9))
            dd = s.doppler_hz - r.doppler_hz
            if abs(dd) <= half_bin and ratio > min_ratio_db:
                r.detected, r.reason = False, "xcorr"
                break
            k = round(dd / 1000.0)
            if fs is None or k == 0 or abs(k) > max_k or abs(dd - 1000.0 * k) > half_bin:
                continue
            image = (s.peak_to_mean - 1) * cross_correlation_image(s, r, fs, coherent_ms, signal)
            if image >= image_fraction * (r.peak_to_mean - 1):
                r.detected, r.reason = False, "xcorr"
                break
    return results
