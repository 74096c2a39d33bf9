"""Snapshot acquisition: detection tuned to the snapshot length, then the fine code phase (sub-sample
interpolation of the correlation peak) and the fine Doppler over the whole snapshot.

Detection calls the receiver's FFT search (receiver/acquisition.py ``search``) with a coherent /
non-coherent split chosen from the length (:func:`dwell_plan`): coherent blocks of at most 10 ms (half a
data bit: of two consecutive blocks at most one holds a bit transition) and at least two non-coherent
sums where the length allows, so that a transition costs at most part of one block.

Fine code phase: the snapshot is cut into 1-ms blocks (carrier wiped at the detected Doppler); the
correlation of each block with the code is evaluated at fractional lags through its spectrum
(band-limited interpolation of the sampled correlation), each block's lag moved by the code Doppler;
the powers are summed over the blocks.  The code phase is the centre of symmetry of that peak: the lag
where the power ``d_chips`` earlier equals the power ``d_chips`` later (a non-coherent early-late
discriminator at zero, found on a 0.02-chip grid and interpolated).

Fine Doppler: the prompt 1-ms correlations z_b at that code phase; for each of the 20 possible positions
of the data-bit edges the blocks are summed coherently over the whole snapshot, each bit with the sign
that aligns it with the sum so far (the data-bit transitions handled explicitly), as a function of the
residual frequency; the largest over edges and frequencies, refined on a finer grid.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..acquisition import search
from ..gnss.signals import GPS_L1CA, sample_code


@dataclass
class SnapAcq:
    """Acquisition of one PRN in a snapshot: detection, code phase (chips) at its first sample, Doppler (Hz),
    C/N0 (dB-Hz), detection metric and what the bit edge search found."""
    prn: int
    detected: bool
    code_phase_chips: float        # at the first sample of the snapshot
    doppler_hz: float
    cn0_dbhz: float
    metric: float
    coarse_doppler_hz: float = float("nan")
    bit_edge_ms: int = -1          # data-bit edge position (ms into the snapshot, modulo 20), -1 unknown
    edge_s: float = float("nan")   # a data-bit transition: its time after the first sample (s), NaN if none seen


def dwell_plan(length_ms: int, max_dwell_ms: int = 20) -> tuple[int, int]:
    """(coherent_ms, noncoherent) for the detection of a snapshot of ``length_ms`` whole milliseconds:
    coherent half the length, at most 10 ms, two or more non-coherent sums, at most ``max_dwell_ms``
    in all (the fine stage uses the whole snapshot)."""
    n = int(length_ms)
    if n < 1:
        raise ValueError("a snapshot needs at least 1 ms")
    if n == 1:
        return 1, 1
    t = max(1, min(10, n // 2))
    k = max(1, min(n, max_dwell_ms) // t)
    return t, k


def _block_spectra(x, fs, if_hz, doppler_hz, n1, nb):
    """FFTs (nb, n1) of the 1-ms blocks after the carrier wipe-off at ``doppler_hz``."""
    t = np.arange(n1 * nb) / fs
    y = x[:n1 * nb] * np.exp(-2j * np.pi * (if_hz + doppler_hz) * t)
    return np.fft.fft(y.reshape(nb, n1), axis=1)


_GRID_CACHE: dict = {}


def _offset_grid(n1: int, offs: np.ndarray) -> np.ndarray:
    """exp(2 pi i f o) for the signed line frequencies f (cycles / sample) and the lag offsets o (samples):
    (n1, n_offs), cached per (n1, offsets)."""
    key = (n1, len(offs), float(offs[0]), float(offs[-1]))
    g = _GRID_CACHE.get(key)
    if g is None:
        if len(_GRID_CACHE) > 8:
            _GRID_CACHE.clear()
        g = np.exp(2j * np.pi * np.outer(np.fft.fftfreq(n1), offs)) / n1
        _GRID_CACHE[key] = g
    return g


def _doppler_ramp(spec_code, dlag):
    """spec_code (nb, n1) with each block's lag moved by b dlag samples (the code Doppler): the ramp is
    lag-independent, applied once per satellite (then :func:`_lag_power` costs one matrix product)."""
    nb, n1 = spec_code.shape
    return spec_code * np.exp(2j * np.pi * np.outer(np.arange(nb) * dlag, np.fft.fftfreq(n1)))


def _lag_power(spec_ramped, lag0, offs):
    """Correlations r_b at the fractional lags lag0 + offs (samples) of block 0 (each block's lag moved by
    the code Doppler: ``spec_ramped`` from :func:`_doppler_ramp`) and their power summed over the blocks:
    (power (n_offs,), r (nb, n_offs)).  spec_ramped (nb, n1): block spectrum times the conjugate code
    spectrum (band-limited interpolation of the sampled correlation)."""
    n1 = spec_ramped.shape[1]
    shift = np.exp(2j * np.pi * lag0 * np.fft.fftfreq(n1))
    r = spec_ramped @ (shift[:, None] * _offset_grid(n1, offs))
    return (r.real ** 2 + r.imag ** 2).sum(axis=0), r


def fine_code_phase(x, fs, if_hz, prn, code_phase_chips, doppler_hz, d_chips: float = 0.2, signal=None,
                    n_ms: int | None = None, method: str = "replica", el_chips: float = 0.1):
    """Code phase (chips, at the first sample) refined to a fraction of a sample around the coarse
    ``code_phase_chips``; also returns the prompt 1-ms correlations (complex, one per block) and the C/N0
    (dB-Hz: their power over the power far from the peak).  ``method``: "fit" (the correlation power at
    whole-sample lags fitted with the squared triangle, :func:`_triangle_fit`), "replica" (that fit, then a
    narrow early-late discriminator, spacing ``el_chips``, on replicas sampled at fractional code phases,
    :func:`_replica_centre`)
    or "symmetry" (the centre of symmetry of the band-limited interpolated peak, :func:`_symmetry_centre`)."""
    sig = signal if signal is not None else GPS_L1CA
    n1 = int(round(fs * 1e-3))
    nb = max(1, min(len(x) // n1, n_ms or 10 ** 9))
    spc = fs / sig.chip_rate
    spec = _block_spectra(x, fs, if_hz, doppler_hz, n1, nb)
    code = sample_code(sig.code(prn), sig.chip_rate, fs, n1).astype(np.complex128)
    # lag (samples) of the peak in block 0: the code's chip 0 sits at sample lag of the block
    lag0 = (-code_phase_chips * spc) % n1
    # the code phase grows by code_len (1 + fd / f_carrier) per block: the lag falls by the excess
    dlag = -sig.code_len * doppler_hz / sig.carrier_hz * spc
    sc = _doppler_ramp(spec * np.conj(np.fft.fft(code))[None, :], dlag)
    # noise floor: the correlation far from the peak (32 lags spread over the rest of the code period)
    pn, _ = _lag_power(sc, lag0, n1 * np.linspace(0.05, 0.95, 32))
    floor = float(np.mean(pn))
    if method in ("fit", "replica"):
        centre = _triangle_fit(sc, lag0, spc, floor)
    else:
        centre = _symmetry_centre(sc, lag0, spc, d_chips)
    lag = lag0 + centre
    if method == "replica":
        ph = _replica_centre(x[:nb * n1], fs, if_hz, sig.code(prn), (-lag / spc) % sig.code_len, doppler_hz, sig,
                             n1, el_chips)
        lag = -ph * spc
    _, r = _lag_power(sc, lag, np.zeros(1))
    phase = (-lag / spc) % sig.code_len
    noise = floor / nb
    sp = float(np.mean(np.abs(r[:, 0]) ** 2)) - noise
    cn0 = float(10 * np.log10(max(sp / max(noise, 1e-30), 1e-6) / 1e-3))
    return float(phase), r[:, 0], cn0


def _triangle_fit(sc, lag0, spc, floor):
    """Offset (samples) from lag0 of the peak: the non-coherent power at whole-sample lags (minus the noise
    floor) within 1.2 chips of its maximum, least-squares fitted with A tri((lag - centre) / spc)^2 (the
    correlation of a sampled code with its replica at a rate incommensurate with the chip rate), centre on a
    0.01-sample grid refined by a parabola through the fit residuals."""
    k = int(np.ceil(1.5 * spc))
    base = float(np.round(lag0))
    io = np.arange(-k, k + 1, dtype=float)
    p, _ = _lag_power(sc, base, io)
    q = p - floor
    km = int(np.argmax(q))
    sel = np.abs(io - io[km]) <= np.ceil(1.2 * spc)
    ks, qs = io[sel], q[sel]
    cand = io[km] + np.arange(-1.0, 1.0 + 1e-9, 0.01)
    m = np.maximum(0.0, 1.0 - np.abs(ks[None, :] - cand[:, None]) / spc) ** 2
    a = (m @ qs) / np.maximum((m * m).sum(axis=1), 1e-30)
    res = ((qs[None, :] - a[:, None] * m) ** 2).sum(axis=1)
    j = int(np.argmin(res))
    d = 0.0
    if 0 < j < len(res) - 1:
        den = res[j - 1] - 2 * res[j] + res[j + 1]
        d = 0.5 * (res[j - 1] - res[j + 1]) / den if den > 0 else 0.0
    return base - lag0 + float(cand[j]) + 0.01 * d


def _replica_centre(x, fs, if_hz, code, phase0, doppler_hz, sig, n1, d_chips, h_chips=0.02, k_max=15):
    """Code phase (chips at the first sample) where a non-coherent early-late discriminator with spacing
    ``d_chips`` is zero: the received samples (carrier wiped) correlated per 1-ms block with code replicas
    sampled at the code phases phase0 + j h_chips (the code rate moved by the Doppler), the powers summed
    over the blocks; P(phi + d/2) - P(phi - d/2) falls through zero at the peak's centre (the crossing
    nearest phase0, interpolated).  No interpolation of the sampled correlation: exact at any sample rate
    incommensurate with the chip rate, and with a narrow spacing about half the noise of a fit over the
    whole triangle.  phase0 when no crossing is found within k_max steps."""
    n = len(x)
    nb = n // n1
    rate = sig.chip_rate * (1.0 + doppler_hz / sig.carrier_hz)
    y = (x * np.exp(-2j * np.pi * (if_hz + doppler_hz) * np.arange(n) / fs)).astype(np.complex64)
    m = max(1, int(round(0.5 * d_chips / h_chips)))
    base = np.arange(n) * (rate / fs)
    code = np.asarray(code, np.float32)
    memo = {}

    def power(j):                        # power summed over the blocks at the code phase phase0 + j h_chips
        if j not in memo:
            rep = code[np.floor(phase0 + j * h_chips + base).astype(np.int64) % len(code)]
            zb = (y * rep).reshape(nb, n1).sum(axis=1)
            memo[j] = float(np.sum(zb.real ** 2 + zb.imag ** 2))
        return memo[j]

    def s(k):                            # P(phi + d/2) - P(phi - d/2) at phi = phase0 + k h
        return power(k + m) - power(k - m)

    # the downward zero crossing nearest phase0: walk from 0 towards it (a few replicas, not the whole range)
    step = 1 if s(0) > 0 else -1
    k = 0
    while abs(k + step) <= k_max:
        k += step
        if (s(k) <= 0) if step > 0 else (s(k) > 0):
            c = k - 1 if step > 0 else k
            frac = s(c) / (s(c) - s(c + 1))
            return float((phase0 + (c + frac) * h_chips) % len(code))
    return float(phase0)


def _symmetry_centre(sc, lag0, spc, d_chips):
    """Offset (samples) from lag0 where the band-limited interpolated power d_chips earlier equals the power
    d_chips later (0.02-chip grid, interpolated)."""
    step = 0.02 * spc
    offs = np.arange(-60, 61) * step                                # +/- 1.2 chips
    p, _ = _lag_power(sc, lag0, offs)
    k = int(np.argmax(p))
    dk = int(round(d_chips * spc / step))
    lo, hi = max(dk, k - dk), min(len(offs) - dk - 1, k + dk)
    js = np.arange(lo, hi + 1)
    s = p[js - dk] - p[js + dk]
    centre = float(offs[k])
    # S rises through zero at the centre: the crossing nearest to the maximum
    cross = np.flatnonzero((s[:-1] <= 0) & (s[1:] > 0))
    if cross.size:
        c = cross[np.argmin(np.abs(js[cross] - k))]
        frac = s[c] / (s[c] - s[c + 1])
        centre = float(offs[js[c]] + frac * step)
    return centre


def fine_doppler(z, coarse_hz: float, half_range_hz: float, bit_ms: int = 20):
    """Residual frequency of the prompt 1-ms correlations z (one per ms, carrier wiped at coarse_hz): for
    every position of the data-bit edges the bits (segments) are summed coherently over the whole snapshot
    with their signs decided one after the other (each bit's sign the one that aligns it with the sum so
    far), so that every hypothesis is a full-length coherent sum and the best (edge, frequency) is the
    likeliest.  (Summing the bits non-coherently instead lets a single-segment hypothesis at a frequency
    ~0.4 / bit off beat the true one when a transition sits mid-snapshot.)  Searched over 1.5 x
    ``half_range_hz`` (a bit transition inside a search block can put the search's peak a bin off); the
    best grid point refined on a grid 20 times finer with the signs kept.  Returns (doppler_hz,
    bit_edge_ms)."""
    nb = len(z)
    t = np.arange(nb) * 1e-3
    step = 1.0 / (8.0 * nb * 1e-3)
    half_range_hz = max(1.5 * half_range_hz, 2 * step)
    f = np.arange(-half_range_hz, half_range_hz + step / 2, step)
    best_p, best_e, best_edges = None, -1, None
    c = _cumulative(z, t, f)
    for e in range(min(bit_ms, nb) if nb > 1 else 1):
        edges = sorted({0, nb, *range(e, nb, bit_ms)})
        p, _ = _signed_power(c, edges)
        if best_p is None or p.max() > best_p.max():
            best_p, best_e, best_edges = p, e, edges
    j = int(np.argmax(best_p))
    _, signs = _signed_power(c[j:j + 1], best_edges)
    ff = f[j] + np.linspace(-step, step, 41)
    pf, _ = _signed_power(_cumulative(z, t, ff), best_edges, signs[0])
    k = int(np.argmax(pf))
    d = 0.0
    if 0 < k < len(ff) - 1:
        y0, y1, y2 = pf[k - 1], pf[k], pf[k + 1]
        den = y0 - 2 * y1 + y2
        d = 0.5 * (y0 - y2) / den if den != 0 else 0.0
    return float(coarse_hz + ff[k] + d * (ff[1] - ff[0])), (best_e if nb > bit_ms else -1)


def _cumulative(z, t, f):
    """Cumulative sums (n_f, nb + 1) of z wiped at each frequency f (Hz; t the times of z, s)."""
    a = np.exp(-2j * np.pi * np.outer(f, t)) * z[None, :]
    return np.concatenate([np.zeros((len(f), 1), complex), np.cumsum(a, axis=1)], axis=1)


def _signed_power(c, edges, signs=None):
    """Power at each frequency of the cumulative sums c (n_f, nb + 1) summed coherently over the segments
    [edges[i], edges[i+1]) with a sign per segment: ``signs`` (n_seg,) or, when None, each decided in turn
    to align its segment with the sum so far.  Returns (power (n_f,), signs (n_f, n_seg))."""
    seg = c[:, edges[1:]] - c[:, edges[:-1]]
    if signs is not None:
        acc = seg @ np.asarray(signs, float)
        return acc.real ** 2 + acc.imag ** 2, np.tile(signs, (len(c), 1))
    acc = seg[:, 0].copy()
    sg = np.ones(seg.shape, float)
    for k in range(1, seg.shape[1]):
        s = np.where(np.real(seg[:, k] * np.conj(acc)) >= 0, 1.0, -1.0)
        sg[:, k] = s
        acc += s * seg[:, k]
    return acc.real ** 2 + acc.imag ** 2, sg


def bit_transition(x, fs, if_hz, prn, code_phase_chips, doppler_hz, signal=None, min_snr: float = 15.0):
    """Time (s after the first sample) of a data-bit transition seen in the snapshot, or NaN.

    The prompt correlations over code periods (blocks starting at the code epochs, carrier wiped at
    ``doppler_hz``); a transition at epoch m when the coherent sums A of up to 10 periods before it and B
    after it have opposite signs (Re A B* < 0, |A B*| over their noise level, each of A and B at least
    ``min_snr`` in power SNR) -- of the epochs on the 20-ms grid the one with the strongest evidence.
    A transition's transmit time is a multiple of 20 ms: it fixes the time of the first sample modulo 20 ms
    (receiver.navigation.snapshot_time.refine_time)."""
    sig = signal if signal is not None else GPS_L1CA
    rate = sig.chip_rate * (1.0 + doppler_hz / sig.carrier_hz)
    n1 = int(round(fs * 1e-3))
    t_c = ((sig.code_len - code_phase_chips) % sig.code_len) / rate         # first code epoch
    s0 = int(np.ceil(t_c * fs))
    nb = (len(x) - s0) // n1
    if nb < 2:
        return float("nan")
    n = nb * n1
    t = (s0 + np.arange(n)) / fs
    ph0 = (code_phase_chips + s0 * rate / fs) % sig.code_len                # just past chip 0
    rep = sample_code(sig.code(prn), rate, fs, n, ph0) * np.exp(-2j * np.pi * (if_hz + doppler_hz) * t)
    z = (x[s0:s0 + n] * rep).reshape(nb, n1).sum(axis=1)                   # one per code period
    dz = np.diff(z)
    noise = float(np.median(np.abs(dz) ** 2)) / (2.0 * np.log(2.0))      # |n1 - n2|^2: exponential, mean 2 var
    noise = max(noise, 1e-30)
    best, best_m = 0.0, -1
    for e in range(min(20, nb)):
        for m in range(e, nb, 20):
            if m < 1 or nb - m < 1:
                continue
            w = min(10, m, nb - m)
            a, b = z[m - w:m].sum(), z[m:m + w].sum()
            snr_a, snr_b = abs(a) ** 2 / (w * noise), abs(b) ** 2 / (w * noise)
            stat = -float(np.real(a * np.conj(b))) / (w * noise)
            if snr_a >= min_snr and snr_b >= min_snr and stat > best and \
                    -np.real(a * np.conj(b)) > 0.8 * abs(a) * abs(b):
                best, best_m = stat, m
    if best_m < 0:
        return float("nan")
    return float(t_c + best_m * sig.code_len / rate)                      # that epoch's time


def snapshot_acquire(x: np.ndarray, fs: float, if_hz: float, prns, doppler_max_hz: float = 10000.0,
                     doppler_center_hz: float = 0.0, pfa: float = 1e-3, threshold: float = 1.25,
                     width_ratio: float = 0.3, max_dwell_ms: int = 20, signal=None, coarse=None,
                     search_out: list | None = None) -> list[SnapAcq]:
    """Detect ``prns`` in the snapshot ``x`` (complex64 from its first sample) and refine the code phase and
    Doppler of every detection over the whole snapshot.  ``coarse``: the search's results (AcqResult) of
    the same first samples (from a shorter snapshot of the same dwell), reused instead of searching;
    ``search_out``: a list that receives the search's results."""
    sig = signal if signal is not None else GPS_L1CA
    n1 = fs * 1e-3
    if abs(n1 - round(n1)) > 1e-6:
        raise ValueError("snapshot acquisition needs a whole number of samples per millisecond")
    n1 = int(round(n1))
    length_ms = len(x) // n1
    t_coh, k = dwell_plan(length_ms, max_dwell_ms)
    if coarse is not None:
        res = coarse
    else:
        res = search(x, 0, fs, if_hz, list(prns), coherent_ms=t_coh, noncoherent=k, doppler_max_hz=doppler_max_hz,
                     pfa=pfa, threshold=threshold, fine=False, signal=sig, doppler_center_hz=doppler_center_hz,
                     width_ratio=width_ratio)
    out = []
    if search_out is not None:
        search_out.extend(res)
    bin_hz = 1.0 / (2.0 * t_coh * 1e-3)
    for r in res:
        if not r.detected:
            out.append(SnapAcq(r.prn, False, r.code_phase_chips, r.doppler_hz, r.cn0_dbhz_est, r.metric))
            continue
        phase, z, cn0 = fine_code_phase(x, fs, if_hz, r.prn, r.code_phase_chips, r.doppler_hz, signal=sig)
        dop, edge = fine_doppler(z, r.doppler_hz, bin_hz)
        edge_s = bit_transition(x, fs, if_hz, r.prn, phase, dop, signal=sig)
        out.append(SnapAcq(r.prn, True, phase, dop, cn0, r.metric, r.doppler_hz, edge, edge_s))
    return out
