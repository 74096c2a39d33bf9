"""The short acquisition over candidate formats, sample rates and IFs that tells which reading of a file
finds satellites (``gnssrx probe``).

Every candidate (format from the byte statistics, receiver/probe/stats.py; rate; IF) is brought to one
common form: the first ``BLOCK_MS`` ms at the candidate rate are Fourier transformed and the band
IF +/- 1.024 MHz is cut out and transformed back at 2.048 MS/s (mixing, filtering and resampling in one
step, for any rate, also one that is not a whole number of samples per ms).  The acquisition module's
``search`` then looks for GPS L1 C/A PRNs in it (2-ms coherent x 5), ``verify`` confirms each detection on
the next, independent block.  Candidates are tried most likely first (a SigMF / PocketSDR metadata file,
the rate written in the file name, ``--rate``, then common front-end rates), first over a spread subset
of PRNs, and the search stops at the first candidate with two confirmed satellites (or one very strong).
The winner is then searched over all PRNs, and the sign of the spectrum (I/Q swapped or Q inverted, a
high-side LO on a real IF) is read from the code phase drift of the satellites found against their
carrier Doppler over up to 2 s of the file: a satellite's code drifts by Doppler / 1540 chips per second
in the same sense as its carrier; on an inverted spectrum the measured Doppler has the opposite sign.
"""
from __future__ import annotations

import os
import re
import time
from dataclasses import dataclass, field

import numpy as np

from ..acquisition import reject_cross_correlations, search, verify
from ..errors import UserError
from ..gnss.signals import CA_CHIP_RATE, L1_HZ, ca_code, sample_code
from ..source.io import FORMATS, SampleReader
from ..suggest import looks_binary
from .stats import Candidate, Stats, byte_stats, component_stats, spectrum_centre

BB_FS = 2.048e6                 # the common baseband rate of every candidate
BLOCK_MS = 10                   # searched block (and as long again for the verification)
COHERENT_MS = 2
DOPPLER_MAX_HZ = 8000.0         # first passes; then +/- 20 kHz (front-end LO offsets)
WIDE_DOPPLER_HZ = 20000.0
PFA = 1e-3
BLANK = 10.0                    # spectral bins this far over the median power are zeroed (tones, DC)
THRESHOLD = 1.25                # the receiver's default factor on the Pfa threshold
STRONG_METRIC = 3.0             # one detection this far over the threshold is enough on its own
#: common front-end sample rates (Hz), the most frequent first
RATES = (4.0e6, 2.048e6, 2.6e6, 16.368e6, 8.0e6, 5.0e6, 2.0e6, 10.0e6, 4.092e6, 8.184e6, 2.4e6, 2.5e6,
         12.0e6, 16.0e6, 20.0e6, 24.0e6, 3.0e6, 6.0e6, 10.23e6, 16.3676e6, 2.046e6, 10.4e6, 5.456e6,
         6.5e6, 25.0e6, 26.0e6, 30.69e6, 32.736e6, 40.0e6, 50.0e6)
#: IFs of common real-sampling front ends (Hz), tried after rate / 4 when they lie in the occupied band
COMMON_IFS = (4.092e6, 4.1304e6, 1.023e6, 1.25e6, 1.405e6, 2.0e6, 3.0e6, 6.0e6, 4.348e6, 9.548e6)
#: the first pass searches these PRNs, then the others
FIRST_PRNS = (1, 4, 7, 10, 13, 16, 19, 22, 25, 28, 31, 2)


@dataclass
class Trial:
    """One reading tried (format, rate, IF) and the satellites it found."""

    cand: Candidate
    fs: float
    if_hz: float
    found: list = field(default_factory=list)       # AcqResult, detected and confirmed
    prns: tuple = ()
    confirmed: bool = True                          # False: no independent block to confirm on

    @property
    def score(self) -> float:
        """Sum of the detection metrics (each capped at 10)."""
        return sum(min(r.metric, 10.0) for r in self.found)

    def confident(self) -> bool:
        """Two confirmed satellites, or one far above the threshold (short files: 1.5x each)."""
        if not self.found:
            return False
        best = max(r.metric for r in self.found)
        if self.confirmed:
            return len(self.found) >= 2 or best >= STRONG_METRIC
        return sum(r.metric >= 1.5 for r in self.found) >= 2 or best >= STRONG_METRIC


@dataclass
class ProbeResult:
    """The outcome of :func:`probe`: statistics, the winning reading, the spectrum's sign, notes."""

    path: str
    stats: Stats
    best: Trial | None
    tried: int = 0
    elapsed_s: float = 0.0
    iq_swap: bool | None = None          # None: not determined
    swap_note: str = ""
    offset_hz: float = 0.0               # median Doppler of the satellites found
    notes: list = field(default_factory=list)
    duration_s: float = 0.0
    header_bytes: int = 0

    def config(self) -> dict:
        """The input keys to use (empty when nothing was found)."""
        if self.best is None:
            return {}
        b = self.best
        keys = dict(b.cand.keys())
        if self.header_bytes:
            keys["header_bytes"] = self.header_bytes
        keys["sample_rate_hz"] = b.fs
        if_hz = b.if_hz
        if self.iq_swap and not FORMATS[b.cand.fmt].complex:
            if_hz = b.fs / 2 - b.if_hz                  # (-1)^n moves the real IF to fs/2 - IF
        keys["if_hz"] = if_hz
        if self.iq_swap:
            keys["iq_swap"] = True
        return keys


def rate_hints(path) -> list[float]:
    """Sample rates written in a file name: ``4MHz``, ``12MHz``, ``4Msps``, ``2.6MSps``, ``16.368M``."""
    name = os.path.basename(os.fspath(path))
    out = []
    for m in re.finditer(r"(?<![0-9.])(\d+(?:[.p]\d+)?)\s*(mhz|msps|ms/s|msa|m)(?![a-z])", name, re.I):
        if m.group(2) in ("ms",):
            continue
        v = float(m.group(1).replace("p", ".")) * 1e6
        if 0.5e6 <= v <= 100e6:
            out.append(v)
    return out


def iq_hint(path) -> str | None:
    """'iq' or 'real' when the file name says so (``_IQ``, ``cf32``, ``_I.bin``, ``real``)."""
    name = os.path.basename(os.fspath(path)).lower()
    if re.search(r"(^|[_.\-])(iq|cf32|ci16|ci8|cu8|cs16|cs8|complex)([_.\-]|$)", name):
        return "iq"
    if re.search(r"(^|[_.\-])(i|real|rf32|ri16|ri8)([_.\-]|$)", name):
        return "real"
    return None


def baseband(x: np.ndarray, fs: float, if_hz: float, real: bool, blank: bool = True) -> np.ndarray:
    """The block ``x`` (taken at ``fs``) as complex baseband at BB_FS: its spectrum from IF - 1.024 MHz to
    IF + 1.024 MHz moved to 0 Hz (bins outside the sampled band set to zero)."""
    n = len(x)
    T = n / fs
    m = int(round(BB_FS * T))
    X = np.fft.fft(x)
    f_out = np.fft.fftfreq(m, 1.0 / BB_FS)
    f_in = if_hz + f_out
    lo, hi = (0.0, fs / 2) if real else (-fs / 2, fs / 2)
    keep = (f_in > lo) & (f_in < hi)
    idx = np.round(f_in * T).astype(np.int64) % n
    Y = np.where(keep, X[idx], 0)
    # blank CW tones, DC and their leakage: bins 10x over the median power (the GPS signals are far below
    # the noise in every bin)
    p = np.abs(Y) ** 2
    if blank and keep.any():
        Y[p > BLANK * np.median(p[keep])] = 0
    return (np.fft.ifft(Y) * (m / n)).astype(np.complex64)


def code_phase_fine(y: np.ndarray, prn: int, doppler_hz: float, ms: int) -> tuple[float, float]:
    """(code phase in chips at the first sample, peak over mean) of ``prn`` in baseband ``y`` at
    ``doppler_hz``: 1-ms correlations summed non-coherently over ``ms`` ms, the peak interpolated by a
    parabola."""
    n1 = int(round(BB_FS * 1e-3))
    t = np.arange(n1 * ms) / BB_FS
    z = (y[:n1 * ms] * np.exp(-2j * np.pi * doppler_hz * t)).reshape(ms, n1)
    c = np.conj(np.fft.fft(sample_code(ca_code(prn), CA_CHIP_RATE, BB_FS, n1)))
    p = (np.abs(np.fft.ifft(np.fft.fft(z, axis=1) * c[None, :], axis=1)) ** 2).sum(axis=0)
    k = int(np.argmax(p))
    a, b, cc = p[(k - 1) % n1], p[k], p[(k + 1) % n1]
    den = a - 2 * b + cc
    d = 0.5 * (a - cc) / den if den != 0 else 0.0
    return float((-(k + d) * CA_CHIP_RATE / BB_FS) % 1023), float(b / p.mean())


class _Source:
    """Decoded samples of one candidate reading (format, bit order, encoding), read once."""

    def __init__(self, path, cand: Candidate, header_bytes: int, max_samples: int):
        self.reader = SampleReader(path, cand.fmt, 1e6, header_bytes=header_bytes, bit_order=cand.bit_order,
                                   encoding=cand.encoding)
        self.n_file = self.reader.n_file
        self.head = self.reader.read(0, min(max_samples, self.n_file))
        self.real = not FORMATS[cand.fmt].complex
        self.centre = None

    def block(self, fs: float, start_s: float, ms: float) -> np.ndarray | None:
        a, n = int(round(start_s * fs)), int(round(fs * ms * 1e-3))
        if a + n <= len(self.head):
            return self.head[a:a + n]
        if a + n <= self.n_file:
            return self.reader.read(a, n)
        return None


def _ifs(src: _Source, fs: float, primary: bool = True) -> list[float]:
    """IFs to try at rate fs: 0 for I/Q; fs / 4 for real samples (``primary``), else the common IFs near the
    centre of the occupied band."""
    if not src.real:
        return [0.0] if primary else []
    if primary:
        return [fs / 4]
    if src.centre is None:
        src.centre, _ = spectrum_centre(src.head[:1 << 17])
    band = src.centre * fs
    near = sorted((abs(f - band), f) for f in COMMON_IFS if 0.5e6 < f < fs / 2 - 0.5e6)
    return [f for d, f in near if d < 0.05 * fs and abs(f - fs / 4) > 5e3]


def _try(src: _Source, cand: Candidate, fs: float, if_hz: float, prns, doppler_max: float,
         centres=(0.0,)) -> Trial | None:
    trial = Trial(cand, fs, if_hz, prns=tuple(prns))
    x = src.block(fs, 0.0, BLOCK_MS)
    ms = BLOCK_MS
    if x is None:                       # a short file: all of it
        ms = int(src.n_file / fs * 1e3)
        if ms < 2:
            return None
        x = src.block(fs, 0.0, ms)
    y = baseband(x, fs, if_hz, src.real)
    coh = COHERENT_MS if ms >= 2 * COHERENT_MS else 1
    k = ms // coh
    x2 = src.block(fs, ms * 1e-3, ms)
    y2 = baseband(x2, fs, if_hz, src.real) if x2 is not None else None
    trial.confirmed = y2 is not None
    found = {}
    for c in centres:
        for r in search(y, 0, BB_FS, 0.0, list(prns), coherent_ms=coh, noncoherent=k,
                        doppler_max_hz=doppler_max, doppler_center_hz=c, pfa=PFA, threshold=THRESHOLD,
                        fine=False):
            if not r.detected or (r.prn in found and found[r.prn].metric >= r.metric):
                continue
            if y2 is not None and not verify(y2, len(y), BB_FS, 0.0, r, coh, k, pfa=PFA, threshold=1.0):
                continue
            found[r.prn] = r
    trial.found = sorted(found.values(), key=lambda r: -r.metric)
    return trial


def _swap_test(src: _Source, best: Trial, result: ProbeResult):
    """iq_swap from the code drift of the satellites found against their Doppler (module docstring)."""
    fs = best.fs
    dur = src.n_file / fs
    delta = min(2.0, dur - 2 * BLOCK_MS * 1e-3)
    delta = np.floor(delta * 1e3) / 1e3                       # whole ms: the nominal code advance is 0
    sats = [r for r in best.found][:8]
    if delta < 0.2 or len(sats) < 2:
        result.swap_note = ("the spectrum's sign (iq_swap) could not be told: "
                            + ("the file is too short" if delta < 0.2 else "one satellite only"))
        return
    ya = baseband(src.block(fs, 0.0, BLOCK_MS), fs, best.if_hz, src.real)
    yb = baseband(src.block(fs, delta, BLOCK_MS), fs, best.if_hz, src.real)
    dop, drift = [], []
    for r in sats:
        pa, qa = code_phase_fine(ya, r.prn, r.doppler_hz, BLOCK_MS)
        pb, qb = code_phase_fine(yb, r.prn, r.doppler_hz, BLOCK_MS)
        if min(qa, qb) < 8:
            continue
        d = (pb - pa + 511.5) % 1023 - 511.5
        dop.append(r.doppler_hz)
        drift.append(d)
    dop, drift = np.array(dop), np.array(drift)
    if len(dop) < 2 or np.ptp(dop) < 1500:
        result.swap_note = "the spectrum's sign (iq_swap) could not be told: too few satellites or Dopplers too alike"
        return
    A = np.column_stack([dop, np.ones_like(dop)]) if len(dop) >= 3 else dop[:, None]
    sol, *_ = np.linalg.lstsq(A, drift, rcond=None)
    slope = sol[0] * 1540.0 / delta                 # +1: normal, -1: inverted
    if 0.5 < abs(slope) < 1.5:
        result.iq_swap = bool(slope < 0)
        result.swap_note = (f"the code of the satellites drifts {'against' if slope < 0 else 'with'} their "
                            f"measured carrier Doppler over {delta:.1f} s (slope {slope:+.2f}; +1 normal, -1 "
                            f"inverted): {'inverted spectrum' if slope < 0 else 'spectrum not inverted'}")
    else:
        result.swap_note = f"the spectrum's sign (iq_swap) could not be told (code drift slope {slope:+.2f})"


def probe(path, rate: float | None = None, header_bytes: int = 0, max_s: float = 30.0,
          log=None) -> ProbeResult:
    """Name the format, sample rate and IF that find satellites in ``path`` (module docstring)."""
    t0 = time.perf_counter()
    path = os.fspath(path)
    _check_input(path, header_bytes)
    st = byte_stats(path, header_bytes)
    result = ProbeResult(path, st, None, header_bytes=header_bytes)
    meta = {}
    try:
        from ..source.metadata import read_metadata
        meta, _ = read_metadata(path, L1_HZ)
    except UserError:
        meta = {}
    rates, n_hinted = _rates(path, rate, meta)
    run = _Search(path, header_bytes, rates, t0, max_s, result, log)
    run.order_candidates(st, meta)
    best = run.search(n_hinted)
    if best is None:
        weak = [t for t in run.found.values() if t.found]
        if weak:
            best_weak = max(weak, key=lambda t: t.score)
            result.notes.append(f"weak hint: {best_weak.cand.label()} at {best_weak.fs / 1e6:g} MS/s found "
                                f"{' '.join(str(r.prn) for r in best_weak.found)} without confirmation")
        result.elapsed_s = time.perf_counter() - t0
        return result
    best = run.refine(best)
    src = run.src_of(best.cand)
    coh = COHERENT_MS if best.confirmed or src.n_file / best.fs >= 2 * COHERENT_MS * 1e-3 else 1
    best.found = [r for r in reject_cross_correlations(best.found, coh, fs=BB_FS) if r.detected]
    result.best = best
    result.offset_hz = float(np.median([r.doppler_hz for r in best.found]))
    result.duration_s = src.n_file / best.fs
    _swap_test(src, best, result)
    result.notes += component_stats(src.head[:1 << 18], not src.real)
    result.elapsed_s = time.perf_counter() - t0
    return result


def _check_input(path: str, header_bytes: int) -> None:
    """A clear UserError for a missing, empty or text file."""
    if not os.path.isfile(path):
        raise UserError(f"input file not found: {path}")
    if os.path.getsize(path) <= header_bytes:
        raise UserError(f"input file {path} holds no samples ({os.path.getsize(path)} bytes)")
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    if not looks_binary(head) and head.strip():
        raise UserError(f"{path} is text (a config?), not a recording of samples")


def _rates(path, rate, meta) -> tuple[list, int]:
    """(sample rates to try, most likely first; how many of them are hinted: --rate, the metadata file,
    the file name)."""
    if rate:
        return [float(rate)], 1
    rates = []
    if meta.get("sample_rate_hz"):
        rates.append(float(meta["sample_rate_hz"]))
    rates += rate_hints(path)
    hinted = len(rates)
    rates += [r for r in RATES if all(abs(r - q) > 1.0 for q in rates)]
    return rates, hinted


class _Search:
    """One probe's search: the candidate readings (format, bit order, encoding), their sample sources,
    the trials found so far, the time budget."""

    def __init__(self, path, header_bytes, rates, t0, max_s, result, log):
        self.path, self.header_bytes, self.rates = path, header_bytes, rates
        self.t0, self.max_s, self.result, self.log = t0, max_s, result, log
        self.max_rate = max(rates)
        self.sources = {}
        self.found: dict = {}
        self.cands = []

    def src_of(self, c):
        """The sample source of candidate c (one per format / bit order / encoding)."""
        key = (c.fmt, c.bit_order, c.encoding)
        if key not in self.sources:
            self.sources[key] = _Source(self.path, c, self.header_bytes,
                                        int(self.max_rate * 2 * BLOCK_MS * 1e-3) + 16)
        return self.sources[key]

    def order_candidates(self, st, meta):
        """The byte statistics' candidates, the metadata's format first, then I/Q or real as the spectrum
        (or the file name) suggests."""
        cands = list(st.candidates)
        if meta.get("format") in FORMATS:
            cands.sort(key=lambda c: c.fmt != meta["format"])
        hint = iq_hint(self.path)
        if hint is None and any(FORMATS[c.fmt].complex for c in cands) and \
                not all(FORMATS[c.fmt].complex for c in cands):
            # read as I/Q, a real IF recording puts its band at the edges of the spectrum (+/- fs/2)
            first_iq = next(c for c in cands if FORMATS[c.fmt].complex)
            _, width = spectrum_centre(self.src_of(first_iq).head[:1 << 17])
            hint = "real" if width > 0.6 else "iq"
            why = "> 0.6: the band sits at +/- fs/2, a real IF recording" if width > 0.6 else "a band about 0 Hz: I/Q"
            self.result.notes.append(f"read as I/Q the spectrum's spread is {width:.2f} of the sample rate ({why})")
        if hint:
            cands.sort(key=lambda c: FORMATS[c.fmt].complex != (hint == "iq"))
        self.cands = cands

    def _late(self) -> bool:
        return time.perf_counter() - self.t0 > self.max_s

    def search(self, n_hinted):
        """The stages (hinted rates; spread PRNs; the other PRNs; the wide Doppler pass; the secondary
        IFs) until a confident trial (returned) or the time budget ends (None)."""
        rates = self.rates
        rest = tuple(p for p in range(1, 33) if p not in FIRST_PRNS)
        stages = []
        if n_hinted:
            stages.append((rates[:n_hinted], tuple(range(1, 33)), DOPPLER_MAX_HZ, (0.0,)))
        stages += [(rates, FIRST_PRNS, DOPPLER_MAX_HZ, (0.0,)), (rates, rest, DOPPLER_MAX_HZ, (0.0,)),
                   (rates, tuple(range(1, 33)), 6000.0, (-14000.0, 14000.0)),
                   (rates, tuple(range(1, 33)), DOPPLER_MAX_HZ, (0.0,), False)]
        for stage in stages:
            best = self.run_stage(*stage)
            if best is not None:
                return best
            if self._late():
                self.result.notes.append(f"stopped after {self.max_s:.0f} s of searching (--max-seconds)")
                return None
        return None

    def run_stage(self, rlist, prns, dmax, centres, primary=True):
        """Try every candidate at the rates rlist and their IFs; the first confident trial, else None."""
        result, found, log = self.result, self.found, self.log
        for c in self.cands:
            src = self.src_of(c)
            if len(centres) > 1 and src.real:
                continue                       # the wide pass: complex files' oscillator offsets
            for fs in rlist:
                for if_hz in _ifs(src, fs, primary):
                    if self._late():
                        return None
                    key = (c.fmt, c.bit_order, c.encoding, fs, if_hz)
                    trial = _try(src, c, fs, if_hz, prns, dmax, centres)
                    result.tried += 1
                    if trial is None:
                        continue
                    prev = found.get(key)
                    if prev is not None:                      # later stages add the other PRNs
                        have = {r.prn for r in prev.found}
                        prev.found = sorted(prev.found + [r for r in trial.found if r.prn not in have],
                                            key=lambda r: -r.metric)
                        prev.prns = prev.prns + tuple(p for p in trial.prns if p not in prev.prns)
                        trial = prev
                    found[key] = trial
                    if log:
                        log(f"  {c.label()} {fs / 1e6:g} MS/s IF {if_hz / 1e6:g} MHz: "
                            f"{' '.join(str(r.prn) for r in trial.found) or '-'}")
                    if trial.confident():
                        return trial
        return None

    def refine(self, best):
        """The winner: the other PRNs, the other bit order of a packed format, then neighbouring rates
        (within 0.1 %: indistinguishable over 10 ms)."""
        result = self.result
        src = self.src_of(best.cand)
        missing = tuple(p for p in range(1, 33) if p not in best.prns)
        wide = WIDE_DOPPLER_HZ if abs(np.median([r.doppler_hz for r in best.found])) > 4000 else DOPPLER_MAX_HZ
        if missing:
            t = _try(src, best.cand, best.fs, best.if_hz, missing, wide)
            result.tried += 1
            if t is not None:
                best.found = sorted(best.found + t.found, key=lambda r: -r.metric)
                best.prns = tuple(range(1, 33))
        f = FORMATS[best.cand.fmt]
        if f.kind == "packed" and not f.integer:            # the other bit order: real samples in a wrong order
            other = Candidate(best.cand.fmt, "lsb_first" if best.cand.bit_order == "msb_first" else "msb_first",
                              best.cand.encoding)         # still correlate in part: keep the better one
            t = _try(self.src_of(other), other, best.fs, best.if_hz, range(1, 33), wide)
            result.tried += 1
            if t is not None and t.score > best.score:
                best, src = t, self.src_of(other)
        for fs in self.rates:
            if fs != best.fs and abs(fs / best.fs - 1) < 1e-3:
                t = _try(src, best.cand, fs, best.if_hz, range(1, 33), wide)
                result.tried += 1
                if t is not None and t.score > 1.3 * best.score:      # else the more common rate (listed first)
                    best = t
        return best
