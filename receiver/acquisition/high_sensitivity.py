"""High-sensitivity acquisition: the second, slower pass run when the fast search finds too few satellites.

The fast search (:mod:`receiver.acquisition`, 4 ms x 10 by default) detects about 33 dB-Hz.  This pass
searches the satellites it missed with

* **10 ms coherent blocks**, K of them summed non-coherently (default 40: 400 ms);
* **data-bit transitions handled by alternate half-bit blocks**: the 10-ms blocks lie on a 20-ms periodic
  grid, so every bit edge of a satellite falls into blocks of the same parity (all even or all odd).
  Three statistics are formed per cell -- the sum over all blocks, over the even blocks only and over the
  odd blocks only (one of the two is free of transitions) -- each normalised by its own row noise floor
  and tested against its own Pfa threshold (Bonferroni: pfa / 3 each);
* **code Doppler compensated**: over 400 ms the code of a satellite at 4.5 kHz Doppler slides by 1.2
  chips; block k of Doppler row d is shifted by the code drift k T d / f_carrier before the sum;
* **the Doppler range narrowed by what the fast pass found**: every satellite's Doppler is its own
  line-of-sight Doppler (within +/- ``sat_doppler_hz``) plus the receiver's common oscillator offset, so
  the satellites already found bound the offset to [max(d) - f, min(d) + f] and the missing ones lie in
  [max(d) - 2f, min(d) + 2f] (intersected with the fast pass's range).

Detections are confirmed by a verification dwell on the next independent block (same statistics, 3
Doppler bins x +/- 1.5 chips) and rejected when they are cross-correlation images of a satellite found by
the fast pass (C/N0 estimates compared, :func:`reject_images`).  The sensitivity of both passes is
measured by ``scripts/bench/acq_sensitivity.py`` (table in the README).
"""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft

from ..estimation.stats import gamma_isf, gamma_median, median_last_axis
from .code_search import (AcqResult, _Spectra, _add_power_shifted, _gather, cross_correlation_image,
                          verify_columns)
from ..gnss.signals import GPS_L1CA, sample_code
from ..threads import map_ordered, threads

N_STATS = 3         # all blocks, even blocks, odd blocks


def doppler_window(found_hz, centre_hz: float, half_hz: float, sat_doppler_hz: float):
    """(centre, half range) of the Doppler search for the missing satellites given the Dopplers
    ``found_hz`` of the satellites found (receiver oscillator offset common to all), intersected with
    centre_hz +/- half_hz.  No satellite found: the given range."""
    lo, hi = centre_hz - half_hz, centre_hz + half_hz
    d = np.asarray(list(found_hz), float)
    if d.size:
        lo = max(lo, float(d.max()) - 2.0 * sat_doppler_hz)
        hi = min(hi, float(d.min()) + 2.0 * sat_doppler_hz)
        if hi <= lo:                       # inconsistent (a false detection?): keep the full range
            lo, hi = centre_hz - half_hz, centre_hz + half_hz
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


class _BlockSpectra(_Spectra):
    """FFTs of K blocks of m ms for the distinct fractional Doppler offsets of a Doppler grid (the fast
    search's shared spectra), summed per block parity by :meth:`powers`."""

    def __init__(self, samples, fs, if_hz, dopplers, m, k):
        super().__init__(samples, fs, if_hz, dopplers, m, k)
        self.m, self.dopplers = m, dopplers

    def powers(self, cf, fs, carrier_hz, groups, workers=-1):
        """Per group of rows (an index array into the Doppler grid): the (even, odd) block sums of the
        correlation power, (2, n_rows, n1), with each block shifted back by its code drift.  ``workers``:
        threads of the inverse FFTs (-1: all cores)."""
        n1, T = self.n1, self.m * 1e-3
        out = []
        for sel in groups:
            acc = np.zeros((2, sel.size, n1), np.float32)
            # the peak of block k sits k T d / f_c x fs samples earlier than in block 0 (code Doppler)
            drift = np.outer(np.arange(self.k) * T * fs, self.dopplers[sel] / carrier_hz)   # (K, rows)
            for r in np.unique(self.frac[sel]):
                rows = np.flatnonzero(self.frac[sel] == r)
                spec = self.spectra[r]
                ix = self.idx[sel[rows]]
                prod = np.empty((rows.size, n1), np.complex64)
                for k in range(self.k):
                    _gather(spec[k], ix, prod)                       # spec[k][ix]
                    np.multiply(prod, cf[None, :], out=prod)
                    corr = sfft.ifft(prod, axis=1, workers=workers, overwrite_x=True)
                    sh = np.rint(drift[k, rows]).astype(np.int64)
                    # acc[k & 1, rows] += |corr|^2 with each row moved back by its drift (compiled: the
                    # same float32 sums as numpy's square, take_along_axis and add)
                    _add_power_shifted(corr, rows, sh, acc[k & 1])
            out.append(acc)
        return out


def _floor(p, k):
    med = median_last_axis(p) if p.shape[-1] < 20000 else median_last_axis(p[..., ::4])
    return np.maximum(med / gamma_median(k), 1e-30)


def _stats(acc, k_even, k_odd):
    """The three normalised statistics (all, even, odd) of a (2, rows, n1) accumulator and their K."""
    out = []
    for p, k in ((acc[0] + acc[1], k_even + k_odd), (acc[0], k_even), (acc[1], k_odd)):
        out.append((p / _floor(p, k)[:, None], k))
    return out


def _thr(pfa, n_cells, k):
    return gamma_isf(pfa / (N_STATS * n_cells), k)


def _code_fft(sig, prn, fs, n1):
    code = sample_code(sig.code(prn), sig.chip_rate, fs, n1).astype(np.complex64)
    return np.conj(sfft.fft(code)).astype(np.complex64)


def _side_excess(row, si, spc):
    n1 = row.size
    d = np.arange(int(np.ceil(2 * spc)), int(np.floor(4 * spc)) + 1)
    cells = np.concatenate([row[(si + d) % n1], row[(si - d) % n1]])
    return float(cells.mean()) - 1.0


def search_hs(samples: np.ndarray, start_index: int, fs: float, if_hz: float, prns, coherent_ms: int = 10,
              noncoherent: int = 40, doppler_center_hz: float = 0.0, doppler_max_hz: float = 10000.0,
              pfa: float = 1e-3, threshold: float = 1.0, width_ratio: float = 0.3, signal=None,
              verify_samples: np.ndarray | None = None, fine: bool = True) -> list[AcqResult]:
    """Search ``prns`` in ``samples`` (first sample = file index ``start_index``) with coherent_ms blocks
    (<= 10 ms: a 20-ms bit holds two), ``noncoherent`` of them, over doppler_center_hz +/- doppler_max_hz in
    bins of 1/(2 T).  ``verify_samples``: the next independent block (same length) for the verification
    dwell (None: not run).  Returns one AcqResult per PRN (``metric``: best statistic over its threshold;
    ``cn0_dbhz_est`` from the peak of the all-blocks statistic)."""
    sig = signal if signal is not None else GPS_L1CA
    if coherent_ms > 10 or 20 % coherent_ms:
        raise ValueError("high-sensitivity acquisition: coherent_ms must divide 20 and be <= 10")
    n1 = int(round(fs * 1e-3))
    m, K = coherent_ms, noncoherent
    need = n1 * m * K
    if len(samples) < need:
        raise ValueError(f"high-sensitivity acquisition needs {need} samples, got {len(samples)}")
    T = m * 1e-3
    step = 1.0 / (2.0 * T)
    dopplers = doppler_center_hz + np.arange(-doppler_max_hz, doppler_max_hz + step / 2, step)
    sp = _BlockSpectra(samples, fs, if_hz, dopplers, m, K)
    k_even, k_odd = (K + 1) // 2, K // 2
    n_cells = len(dopplers) * n1
    thrs = [_thr(pfa, n_cells, k) for k in (K, k_even, k_odd)]
    spc = fs / sig.chip_rate
    allrows = np.arange(len(dopplers))
    # the PRNs are independent: on several threads each searches its own PRNs with 1-thread FFTs (the
    # same numbers as one thread searching them all with all-core FFTs)
    parallel = threads() > 1 and len(prns) > 1

    def one(prn):
        cf = _code_fft(sig, prn, fs, n1)
        acc = sp.powers(cf, fs, sig.carrier_hz, [allrows], workers=1 if parallel else -1)[0]
        stats = _stats(acc, k_even, k_odd)
        best = None                       # (metric, stat index, row, col)
        reason = "threshold"
        for s_i, ((pn, _k), thr) in enumerate(zip(stats, thrs)):
            row_max = pn.max(axis=1)
            for cand in np.argsort(-row_max)[:8]:
                if row_max[cand] < thr * threshold:
                    break
                col = int(np.argmax(pn[cand]))
                if _side_excess(pn[cand], col, spc) <= width_ratio * (row_max[cand] - 1.0):
                    met = float(row_max[cand] / thr / threshold)
                    if best is None or met > best[0]:
                        best = (met, s_i, int(cand), col)
                    break
                reason = "width" if best is None else reason
        pn_all = stats[0][0]
        if best is None:
            di = int(np.argmax(pn_all.max(axis=1)))
            col = int(np.argmax(pn_all[di]))
            metric = float(pn_all[di, col] / thrs[0] / threshold)
        else:
            metric, _s, di, col = best
            reason = ""
        ptm = float(pn_all[di, col])
        code_phase = (-col * sig.chip_rate / fs) % sig.code_len
        dop = float(dopplers[di])
        # the all-blocks statistic: peak - 1 ~ coherent SNR (the transition blocks lose ~1/6 on average)
        cn0 = 10 * np.log10(max(ptm - 1.0, 1e-3) / T)
        res = AcqResult(prn, reason == "", dop, float(code_phase), start_index, metric, ptm, float(cn0), reason)
        if res.detected and verify_samples is not None and len(verify_samples) >= need:
            ok = verify_hs(verify_samples, start_index + need, fs, if_hz, res, m, K, pfa, threshold, sig)
            res.verified = int(ok)
            if not ok:
                res.detected, res.reason = False, "verify"
        if res.detected and fine:
            res.doppler_hz = refine_doppler_hs(samples[:need], fs, if_hz, prn, res.code_phase_chips, dop,
                                               step, m, sig)
        return res

    return map_ordered(one, list(prns)) if parallel else [one(p) for p in prns]


def refine_doppler_hs(samples, fs, if_hz, prn, code_phase_chips, coarse_hz, bin_hz, block_ms=10,
                      signal=None, dump_hz: float = 10000.0) -> float:
    """Fine Doppler of a weak detection: code and carrier wiped off all of ``samples``, integrated and
    dumped at ``dump_hz``, then the zero-padded spectra of the block_ms blocks summed non-coherently
    within +/- 1.5 bins of the coarse Doppler, parabolic peak interpolation (resolution ~5 Hz)."""
    sig = signal if signal is not None else GPS_L1CA
    n = len(samples)
    code = sample_code(sig.code(prn), sig.chip_rate * (1.0 + coarse_hz / sig.carrier_hz), fs, n,
                       code_phase_chips)
    t = np.arange(n) / fs
    x = samples * code * np.exp(-2j * np.pi * (if_hz + coarse_hz) * t).astype(np.complex64)
    d = max(1, int(round(fs / dump_hz)))
    y = x[:n // d * d].reshape(-1, d).sum(axis=1)
    fd = fs / d
    nb = max(1, int(round(block_ms * 1e-3 * fd)))
    blocks = y[:y.size // nb * nb].reshape(-1, nb)
    nfft = 2048
    spec = (np.abs(np.fft.fft(blocks, nfft, axis=1)) ** 2).sum(axis=0)
    freqs = np.fft.fftfreq(nfft, 1.0 / fd)
    idx = np.flatnonzero(np.abs(freqs) <= 1.5 * bin_hz)
    i = idx[np.argmax(spec[idx])]
    a, b, c = spec[(i - 1) % nfft], spec[i], spec[(i + 1) % nfft]
    den = a - 2 * b + c
    dlt = 0.5 * (a - c) / den if den != 0 else 0.0
    f1 = float(freqs[i] + dlt * fd / nfft)
    # second stage: phase advance between consecutive 5-ms sums, squared (a data-bit flip turns the product
    # by 180 deg; squaring removes it): unambiguous over +/- 50 Hz, a few Hz at 28 dB-Hz over 200 ms
    m5 = max(1, int(round(5e-3 * fd)))
    tt = np.arange(y.size) / fd
    z = (y * np.exp(-2j * np.pi * f1 * tt))[:y.size // m5 * m5].reshape(-1, m5).sum(axis=1)
    if z.size >= 4:
        prod = (z[1:] * np.conj(z[:-1])) ** 2
        f1 += float(np.angle(prod.sum())) / (2.0 * 2.0 * np.pi * m5 / fd)
    return float(coarse_hz + f1)


def verify_hs(samples, start_index, fs, if_hz, res: AcqResult, coherent_ms, noncoherent, pfa=1e-3,
              threshold=1.0, signal=None, window_chips: float = 1.5) -> bool:
    """Verification dwell of a high-sensitivity detection on an independent block: 3 Doppler bins around
    its Doppler, +/- window_chips around its code phase carried forward; any of the three statistics above
    its threshold for that small window."""
    sig = signal if signal is not None else GPS_L1CA
    n1 = int(round(fs * 1e-3))
    step = 1.0 / (2.0 * coherent_ms * 1e-3)
    dopplers = res.doppler_hz + step * np.array([-1.0, 0.0, 1.0])
    sp = _BlockSpectra(samples, fs, if_hz, dopplers, coherent_ms, noncoherent)
    acc = sp.powers(_code_fft(sig, res.prn, fs, n1), fs, sig.carrier_hz, [np.arange(3)])[0]
    K = noncoherent
    stats = _stats(acc, (K + 1) // 2, K // 2)
    cols = verify_columns(res, start_index, fs, sig, window_chips)
    for (pn, k) in stats:
        if pn[:, cols].max() >= _thr(pfa, 3 * cols.size, k) * threshold:
            return True
    return False


def reject_images(weak: list[AcqResult], strong: list[AcqResult], fs: float, coherent_ms: int,
                  signal=None, min_ratio_db: float = 15.0, image_db: float = -6.0,
                  max_k: int = 60) -> list[AcqResult]:
    """Un-detect high-sensitivity detections that are cross-correlation images of a satellite ``strong``
    (detected by the fast pass): at the same Doppler (within 1/(2 T)) and more than min_ratio_db weaker,
    or at a k x 1 kHz offset where the image predicted from the two codes at the detection's code phase
    (:func:`receiver.acquisition.cross_correlation_image`) is within image_db of the detection's C/N0."""
    half_bin = 1.0 / (2.0 * coherent_ms * 1e-3)
    for r in weak:
        if not r.detected:
            continue
        for s in strong:
            if not s.detected or s.prn == r.prn or s.cn0_dbhz_est <= r.cn0_dbhz_est:
                continue
            dd = s.doppler_hz - r.doppler_hz
            if abs(dd) <= half_bin and s.cn0_dbhz_est - r.cn0_dbhz_est > min_ratio_db:
                r.detected, r.reason = False, "xcorr"
                break
            k = round(dd / 1000.0)
            if abs(k) > max_k or abs(dd - 1000.0 * k) > half_bin:
                continue
            img = s.cn0_dbhz_est + 10 * np.log10(max(cross_correlation_image(s, r, fs, coherent_ms, signal),
                                                     1e-12))
            if img >= r.cn0_dbhz_est + image_db:
                r.detected, r.reason = False, "xcorr"
                break
    return weak


def second_pass(a, reader, start: int, if_hz: float, results: list[AcqResult], sig, known_hz=(),
                centre_hz: float = 0.0) -> tuple[list[AcqResult], str]:
    """The high-sensitivity pass over the PRNs of ``results`` not detected (acquisition config section
    ``a``; samples from ``reader`` at file index ``start``).  The Doppler range is narrowed by the Dopplers
    of the detected results and ``known_hz`` (satellites tracked).  Returns the merged results and a line
    for the user ("" when the pass could not run: file too short)."""
    hs = a.high_sensitivity
    fs = reader.fs
    n = int(round(hs.coherent_ms * hs.noncoherent * 1e-3 * fs))
    block = reader.read(start, 2 * n)
    if len(block) < 2 * n:
        return results, ""
    strong = [r for r in results if r.detected]
    missing = [r.prn for r in results if not r.detected]
    if not missing:
        return results, ""
    found_hz = [r.doppler_hz for r in strong] + list(known_hz)
    c, half = doppler_window(found_hz, centre_hz, max(a.doppler_max_hz, 1.0), hs.sat_doppler_hz)
    weak = search_hs(block[:n], start, fs, if_hz, missing, hs.coherent_ms, hs.noncoherent, c, half, hs.pfa,
                     1.0, a.width_ratio, sig, verify_samples=block[n:2 * n])
    reject_images(weak, strong, fs, hs.coherent_ms, sig)
    by = {r.prn: r for r in weak}
    merged = [by.get(r.prn, r) for r in results]
    new = sorted(r.prn for r in weak if r.detected)
    line = (f"acquisition     {len(strong)} satellite(s) found by the fast search: high-sensitivity pass "
            f"({hs.coherent_ms} ms x {hs.noncoherent}, Doppler {c / 1e3:+.2f} +/- {half / 1e3:.2f} kHz) "
            f"over {len(missing)} PRNs found {len(new)} more" + (": " + " ".join(f"G{p:02d}" for p in new)
                                                                  if new else ""))
    return merged, line


def search_predicted(samples: np.ndarray, start_index: int, fs: float, if_hz: float, prn: int, doppler_hz: float,
                     doppler_half_hz: float, code_phase_chips: float, window_chips: float, coherent_ms: int = 10,
                     noncoherent: int = 50, pfa: float = 1e-4, signal=None) -> AcqResult:
    """A satellite predicted from the ephemeris and the fix (code phase ``code_phase_chips`` at file index
    ``start_index``, the first of ``samples``; Doppler ``doppler_hz``), searched within ``window_chips`` and
    ``doppler_half_hz`` of the prediction with the high-sensitivity statistics (``coherent_ms`` blocks, each
    moved back by its code drift, ``noncoherent`` of them, alternate half-bit sums): the threshold is set by
    ``pfa`` over those few cells only, so weaker satellites pass than a search of the whole grid finds (the
    aiding gain).  The detection's Doppler is refined (:func:`refine_doppler_hs`)."""
    sig = signal if signal is not None else GPS_L1CA
    if coherent_ms > 10 or 20 % coherent_ms:
        raise ValueError("predicted search: coherent_ms must divide 20 and be <= 10")
    n1 = int(round(fs * 1e-3))
    m, K = int(coherent_ms), int(noncoherent)
    need = n1 * m * K
    if len(samples) < need:
        raise ValueError(f"predicted search needs {need} samples, got {len(samples)}")
    step = 1.0 / (2.0 * m * 1e-3)
    nb = int(np.ceil(max(doppler_half_hz, 0.0) / step))
    dopplers = doppler_hz + step * np.arange(-nb, nb + 1)
    sp = _BlockSpectra(samples[:need], fs, if_hz, dopplers, m, K)
    acc = sp.powers(_code_fft(sig, prn, fs, n1), fs, sig.carrier_hz, [np.arange(len(dopplers))], workers=1)[0]
    stats = _stats(acc, (K + 1) // 2, K // 2)
    spc = fs / sig.chip_rate
    si0 = int(round(-(code_phase_chips % sig.code_len) * spc)) % n1
    w = int(np.ceil(window_chips * spc))
    cols = (si0 + np.arange(-w, w + 1)) % n1
    n_cells = len(dopplers) * cols.size
    best = None                                  # (statistic / threshold, row, column)
    for pn, k in stats:
        win = pn[:, cols]
        di, ci = np.unravel_index(int(np.argmax(win)), win.shape)
        met = float(win[di, ci]) / _thr(pfa, n_cells, k)
        if best is None or met > best[0]:
            best = (met, int(di), int(cols[ci]))
    met, di, col = best
    ptm = float(stats[0][0][di, col])
    cn0 = 10 * np.log10(max(ptm - 1.0, 1e-3) / (m * 1e-3))
    detected = met >= 1.0
    res = AcqResult(prn, detected, float(dopplers[di]), float((-col / spc) % sig.code_len), int(start_index), met,
                    ptm, float(cn0), "" if detected else "threshold")
    if detected:
        res.doppler_hz = refine_doppler_hs(samples[:need], fs, if_hz, prn, res.code_phase_chips, res.doppler_hz,
                                           step, m, sig)
    return res
