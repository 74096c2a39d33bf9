"""The decimating input stage: any file -> complex baseband near 4 MS/s before acquisition and tracking.

High-rate front ends (MAX2769/MAX2771/NT1065 at 16-24 MS/s real IF, SDRs at 10-40 MS/s I/Q) sample far
more bandwidth than GPS L1 C/A needs (main lobe +/-1.023 MHz).  Acquisition and tracking cost grows with the
sample rate, so this stage brings the samples down first (``input.decimate``):

1. **Mix** the IF to 0 Hz: ``x[n] exp(-j 2 pi IF n / fs_in)``.  The mixer's phase is a pure function of the
   absolute file index n (a 64-bit phase accumulator ``n * step mod 2^64``, step = IF / fs_in * 2^64, the
   top 12 bits index a cos/sin table): no state between blocks, frequency error below fs_in / 2^64.
2. **Anti-alias filter and resample** by a rational factor L / M (integer decimation: L = 1, M = N): output
   sample k is the band-limited value of the mixed input at the exact file position ``k M / L``, i.e. at
   time ``k / fs_out`` with ``fs_out = fs_in L / M``.  The interpolation kernel is a symmetric
   Kaiser-window low-pass designed at ``L fs_in`` and split into L phases of J taps (polyphase); its
   delay is compensated by centring, so time tags, ``sample_index`` and ``time_s`` stay exact relative to
   the file.  Pass band to 0.45 fs_out (at least the chip rate + 50 kHz for Doppler and LO offset), stop
   band from ``fs_out`` minus (chip rate + 50 kHz) -- what would fold onto the main lobe -- 40 dB down; the
   transition band folds only onto the outer part of the band, where the signal is weak.  The signal's
   power outside +/-0.45 fs_out is lost (GPS C/A at 4 MS/s: ~5 %, 0.2 dB); measured against processing a
   16.368 MS/s 2-bit file at full rate: 0.5 dB of C/N0.

Real input (the common high-rate case: MAX2769-style 2-bit real IF) takes a cheaper route to the same
output: the mixer is moved behind the filter.  ``sum_j h[j] x[n-j] e^{-j w (n-j)} = e^{-j w n} sum_j
(h[j] e^{j w j}) x[n-j]``: the taps become complex (each polyphase row times the mixer's phase ramp over
its J taps, computed once), the real samples are never mixed, and the mixer's phase is applied once per
*output* (from the same 64-bit phase accumulator, two 4096-entry tables: phase error below 2 pi / 2^24).
Packed real formats are unpacked straight from the file's bytes into a float32 scratch inside the same
compiled call (a 256-entry byte table, no complex64 intermediate); ``iq_swap`` (spectral inversion,
(-1)^n) becomes a mixer offset of fs_in / 2.  Reads are split into pieces of ``PIECE`` outputs run on the
receiver's thread pool (:mod:`receiver.threads`): each output is computed by the same operations whatever
the split, so the samples are identical for any thread count.

The stage keeps no state between reads (the pipeline's read-ahead, ``receiver.source.prefetch.PrefetchingReader``,
relies on that to resample the next chunk on a background thread).

Every output sample depends only on the J input samples around its position, so a read at any position
reads that margin on each side and gives exactly the samples a whole-file pass would: block edges leave
no trace and memory is bounded by the block (processed in pieces of ``PIECE`` outputs).

Bookkeeping after the stage: sample rate ``fs_out``, IF 0 (the carrier NCO runs at the Doppler only),
index k of the stream = time ``k / fs_out`` since the first sample of the file.  Carrier phase: the stage
removed ``IF t`` exactly, which is what the receiver removes from its NCO phase anyway
(``carrier_phase_cycles - if_hz * time_s``), so carrier phase, Doppler and pseudorange mean what they mean
at full rate.  The run file records ``sample_rate_hz`` (fs_out), ``if_hz`` (0), ``input_sample_rate_hz``,
``input_if_hz`` and ``resample`` ("L/M").

Why not plain integer decimation to "about 4 MS/s": acquisition needs a whole number of samples per
millisecond, and a replica sampled on a grid commensurate with the chip rate only takes a few distinct
alignments: fs / f_chip = p / q in lowest terms gives p distinct sample phases per chip, and the code
delay moves in steps of 1/p chip between the dithering that code Doppler provides.  16.368 MS/s / 4 =
4.092 MS/s has p = 4 (73 m steps); / 5 is not a whole number of samples per ms.  ``auto`` therefore
resamples to ``AUTO_CHIPS`` chip rates rounded up to a whole MS/s (4 MS/s for GPS L1 C/A: 4000 samples
per ms, p = 4000) whenever the input is at least 1.5 times that rate (:func:`plan`).
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from numba import njit

from ..errors import UserError
from ..threads import map_ordered, threads

PIECE = 1 << 16              # outputs per compiled call (bounded scratch memory)
LUT_BITS = 12
_LUT = np.exp(-2j * np.pi * np.arange(1 << LUT_BITS) / (1 << LUT_BITS)).astype(np.complex64)
# fine table: the next 12 bits of the phase accumulator (bin centres: truncation error mean zero)
_LUT_FINE = np.exp(-2j * np.pi * (np.arange(1 << LUT_BITS) + 0.5) / (1 << (2 * LUT_BITS))).astype(np.complex64)
AUTO_CHIPS = 3.9             # auto: output rate >= this many chip rates, rounded up to whole MS/s
AUTO_MIN_RATIO = 1.5         # ... when the input is at least this much faster (else no stage)
MAX_L = 4096                 # largest interpolation factor of a rational resampling
EDGE_HZ = 50e3               # pass band beyond the chip rate: Doppler + LO offset
STOP_DB = 40.0
PASS_FRACTION = 0.45         # pass band to 0.45 fs_out (1.8 MHz at 4 MS/s): the C/A side lobes' power kept


def phase_grid(fs: float, chip_rate: float, max_den: int = 100000) -> int:
    """p: distinct code alignments per chip of a replica sampled at fs (fs / chip_rate = p / q)."""
    return Fraction(fs / chip_rate).limit_denominator(max_den).numerator


def _whole_ms(fs: float) -> bool:
    """fs is a whole number of samples per millisecond (what acquisition needs: it folds code periods)."""
    return abs(fs * 1e-3 - round(fs * 1e-3)) <= 1e-6


def _whole_ms_ratio(fs_in: float, k_lo: int, k_hi: int):
    """(L, M), both <= MAX_L, taking fs_in exactly to the lowest rate of k_lo..k_hi whole samples per
    millisecond (k kHz); None when there is none.  A rate like 16.3676 MS/s (16367.6 samples per ms) reaches
    no round rate with small integers but e.g. 4.233 MS/s = 15/58 of it."""
    f_in = Fraction(repr(float(fs_in)))
    for k in range(max(1, k_lo), k_hi + 1):
        f = Fraction(1000 * k) / f_in
        if f.numerator <= MAX_L and f.denominator <= MAX_L:
            return f.numerator, f.denominator
    return None


def plan(setting, fs_in: float, chip_rate: float):
    """``input.decimate`` ('auto' or an integer N >= 1) -> (L, M): the stream runs at fs_in L / M;
    (1, 1) = no stage.  UserError when N would cut into the signal's band, or when the stream's rate would
    not be a whole number of samples per millisecond (acquisition folds whole code periods): ``auto``
    resamples such a rate to a whole one (the lowest it reaches with L, M <= MAX_L)."""
    edge = chip_rate + EDGE_HZ
    if setting in (None, "auto"):
        target = math.ceil(AUTO_CHIPS * chip_rate / 1e6) * 1e6
        if fs_in >= AUTO_MIN_RATIO * target:
            k = round(target * 1e-3)
            lm = _whole_ms_ratio(fs_in, k, k)              # exactly the target
            if lm is not None:
                return lm
            # no exact ratio: the largest integer decimation that fits
            n = max(1, int(fs_in // target))
            while n > 1 and not _whole_ms(fs_in / n):
                n -= 1
            if n > 1:
                return 1, n
            # none either: the lowest whole rate from the target up that a ratio of small integers reaches
            lm = _whole_ms_ratio(fs_in, math.ceil(target * 1e-3), math.ceil(1.5 * target * 1e-3))
            if lm is not None:
                return lm
        if _whole_ms(fs_in):
            return 1, 1
        # a low rate that is not a whole number of samples per millisecond: resampled (slightly up) to a
        # whole one, the signal's band kept
        lm = _whole_ms_ratio(fs_in, math.ceil(fs_in * 1e-3), math.ceil(1.25 * fs_in * 1e-3))
        if lm is None:
            raise UserError(f"input sample rate {fs_in:g} Hz is not a whole number of samples per millisecond "
                            f"(acquisition needs that) and no resampling ratio with integers <= {MAX_L} "
                            f"reaches one within +25 %: resample the recording")
        return lm
    n = setting
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise UserError(f"config key 'input.decimate' must be auto or an integer >= 1, got {setting!r}")
    if n == 1 and not _whole_ms(fs_in):
        raise UserError(f"config key 'input.decimate' = 1: the input's {fs_in / 1e6:g} MS/s is not a whole "
                        f"number of samples per millisecond, which acquisition needs (use auto: it resamples)")
    if n > 1 and fs_in / n < 2.1 * edge:
        raise UserError(f"config key 'input.decimate' = {n}: {fs_in / n / 1e6:g} MS/s cannot hold the signal's "
                        f"+/-{edge / 1e6:g} MHz (largest factor {max(1, int(fs_in // (2.1 * edge)))})")
    if n > 1 and not _whole_ms(fs_in / n):
        raise UserError(f"config key 'input.decimate' = {n}: {fs_in / n / 1e6:g} MS/s is not a whole number of "
                        f"samples per millisecond, which acquisition needs (use auto)")
    return 1, n


def design(fs_in: float, l: int, m: int, chip_rate: float, stop_db: float = STOP_DB) -> np.ndarray:
    """Polyphase taps (L, J) of the interpolation low-pass for resampling by L / M: row r holds
    g[r + (J-1) L], ..., g[r + L], g[r] of the symmetric kernel g (odd length, designed at L fs_in, gain L),
    and the kernel's centre c (in units of 1 / (L fs_in))."""
    fs_out = fs_in * l / m
    edge = chip_rate + EDGE_HZ
    fstop = min(max(fs_out - edge, edge * 1.05), fs_in / 2)     # folds onto |f| > edge only
    fp = min(max(edge, PASS_FRACTION * fs_out), 0.5 * (edge + fstop) + 0.4 * (fstop - edge))
    if fp >= 0.95 * fstop:
        # a recording narrower than the signal's band (e.g. 2.0461 MS/s I/Q resampled to a whole rate):
        # keep 90 % of what it holds
        fp = 0.9 * fstop
    width = (fstop - fp) / (fs_in / 2)
    # Kaiser's design formulas (no scipy.signal import: ~1 s of start-up): length for the attenuation and
    # transition width, window shape beta, windowed-sinc low-pass cut at the middle of the transition
    j = int(math.ceil((stop_db - 7.95) / (2.285 * math.pi * width) + 1.0))    # taps at the input rate
    j = max(j, 2)
    n = l * j
    if n % 2 == 0:
        n -= 1                                        # odd: a centre tap, exact delay compensation
    if stop_db > 50.0:
        beta = 0.1102 * (stop_db - 8.7)
    elif stop_db > 21.0:
        beta = 0.5842 * (stop_db - 21.0) ** 0.4 + 0.07886 * (stop_db - 21.0)
    else:
        beta = 0.0
    fc = (fp + fstop) / 2 / (fs_in * l)               # cut-off in cycles per sample at L fs_in
    g = 2.0 * fc * np.sinc(2.0 * fc * (np.arange(n) - (n - 1) / 2)) * np.kaiser(n, beta)
    g = np.concatenate([g / g.sum() * l, np.zeros(l * j - n)])
    return np.ascontiguousarray(g.reshape(j, l).T[:, ::-1].astype(np.float32)), (n - 1) // 2


@njit(cache=True, nogil=True, fastmath=True)
def _resample(x, lo, step, lut, shift, hp, inv, c, l, m, k0, real, out):
    """out[i] = sum_j h[r, j] xm[nmax - j] for stream index k = k0 + i, where top = k m + c,
    nmax = top // l, r = top - nmax l, xm = x mixed by exp(-j 2 pi IF n / fs_in) (n = file index;
    x[0] is file index lo).  ``hp``: the polyphase rows h in visiting order (:func:`visit_order`, ``inv``)."""
    J = hp.shape[1]
    n_in = x.size
    xv = x.view(np.float32)
    re = np.empty(n_in, np.float32)
    im = np.empty(n_in, np.float32)
    if step == 0:
        for i in range(n_in):
            re[i] = xv[2 * i]
            im[i] = xv[2 * i + 1]
    else:
        ph = np.uint64(lo) * step
        for i in range(n_in):
            cs = lut[ph >> shift]
            ph += step
            a = xv[2 * i]
            if real:
                re[i] = a * cs.real
                im[i] = a * cs.imag
            else:
                b = xv[2 * i + 1]
                re[i] = a * cs.real - b * cs.imag
                im[i] = a * cs.imag + b * cs.real
    ov = out.view(np.float32)
    top = k0 * m + c
    nmax = top // l
    r = top - nmax * l
    q, rr = m // l, m % l
    t = (r * inv) % l                          # row of phase r in visiting order
    for i in range(out.size):
        b = nmax - lo - J + 1                  # hp rows are stored reversed: a forward dot product
        h = hp[t]
        x1 = re[b:b + J]                       # (1-D views: numba vectorises these, not hp[r, j])
        x2 = im[b:b + J]
        ar = np.float32(0.0)
        ai = np.float32(0.0)
        for j in range(J):
            ar += h[j] * x1[j]
            ai += h[j] * x2[j]
        ov[2 * i] = ar
        ov[2 * i + 1] = ai
        nmax += q
        r += rr
        if r >= l:
            r -= l
            nmax += 1
        t += 1
        if t == l:
            t = 0
    return out


@njit(cache=True, nogil=True, fastmath=True)
def _filter_real(x, lo, step, lut, lut_fine, hr, hi, inv, c, l, m, k0, out):
    """Real input x (x[0] is file index lo): out[i] = e^{-j w nmax} sum_j (hr + j hi)[r, j] x[nmax - J + 1 + j]
    for stream index k = k0 + i (top = k m + c, nmax = top // l, r = top - nmax l); the complex taps carry
    the mixer's phase over the window (module docstring), e^{-j w nmax} comes from the phase accumulator
    nmax * step (top 12 bits: ``lut``, next 12: ``lut_fine``).  ``hr``, ``hi``: rows in visiting order
    (:func:`visit_order`, ``inv``)."""
    J = hr.shape[1]
    ov = out.view(np.float32)
    top = k0 * m + c
    nmax = top // l
    r = top - nmax * l
    q, rr = m // l, m % l
    s1 = np.uint64(64 - LUT_BITS)
    s2 = np.uint64(64 - 2 * LUT_BITS)
    mask = np.uint64((1 << LUT_BITS) - 1)
    t = (r * inv) % l
    for i in range(out.size):
        b = nmax - lo - J + 1
        h1 = hr[t]
        h2 = hi[t]
        xx = x[b:b + J]
        ar = np.float32(0.0)
        ai = np.float32(0.0)
        for j in range(J):
            ar += h1[j] * xx[j]
            ai += h2[j] * xx[j]
        ph = np.uint64(nmax) * step
        cs = lut[ph >> s1] * lut_fine[(ph >> s2) & mask]
        ov[2 * i] = ar * cs.real - ai * cs.imag
        ov[2 * i + 1] = ar * cs.imag + ai * cs.real
        nmax += q
        r += rr
        if r >= l:
            r -= l
            nmax += 1
        t += 1
        if t == l:
            t = 0
    return out


@njit(cache=True, nogil=True)
def _unpack_real(raw, table, first_field, x, off, n):
    """x[off:off+n] = the n fields of the bytes ``raw`` from field ``first_field`` of raw[0] on
    (``table``: (256, fields per byte) values)."""
    k = table.shape[1]
    i = 0
    fi = first_field
    bi = 0
    while fi < k and i < n:                        # the first, partial byte
        x[off + i] = table[raw[0], fi]
        fi += 1
        i += 1
    bi = 1
    if k == 4:                                     # whole bytes, 2-bit fields: four 32-bit copies
        xv = x.view(np.uint32)
        tv = table.view(np.uint32).ravel()         # (the table is C-contiguous float32 (256, 4))
        while i + 4 <= n:
            v = 4 * np.int64(raw[bi])
            o = off + i
            xv[o] = tv[v]
            xv[o + 1] = tv[v + 1]
            xv[o + 2] = tv[v + 2]
            xv[o + 3] = tv[v + 3]
            i += 4
            bi += 1
    while i + k <= n:                              # whole bytes (other field counts)
        row = table[raw[bi]]
        for t in range(k):
            x[off + i + t] = row[t]
        i += k
        bi += 1
    fi = 0
    while i < n:                                   # the last, partial byte
        x[off + i] = table[raw[bi], fi]
        fi += 1
        i += 1


@njit(cache=True, nogil=True, fastmath=True)
def _resample_packed_real(raw, table, first_field, a, e, lo, hi_, step, lut, lut_fine, hr, hi, inv, c, l, m,
                          k0, out):
    """Unpack file samples [a, e) of a packed real format (``raw`` from the byte holding sample a;
    zeros for the rest of [lo, hi_)) into a float32 scratch and filter it (:func:`_filter_real`)."""
    x = np.empty(hi_ - lo, np.float32)
    for i in range(0, a - lo):
        x[i] = 0.0
    for i in range(e - lo, hi_ - lo):
        x[i] = 0.0
    if e > a:
        _unpack_real(raw, table, first_field, x, a - lo, e - a)
    return _filter_real(x, lo, step, lut, lut_fine, hr, hi, inv, c, l, m, k0, out)


def visit_order(l: int, m: int) -> tuple:
    """(perm, inv): the polyphase rows in the order consecutive outputs use them.  Output k uses phase
    r = (k m + c) mod l, which advances by m mod l per output; m / l in lowest terms makes that step
    invertible mod l (``inv``), so row t of the permuted table (phase perm[t] = t (m mod l) mod l) serves
    output k0 + i at t = (r0 inv + i) mod l: the kernels walk the table row after row instead of jumping
    m mod l rows per output (the same taps, the same samples)."""
    if l == 1:
        return np.zeros(1, np.int64), 0
    rr = m % l
    return (np.arange(l) * rr) % l, pow(rr, -1, l)


def complex_taps(hp: np.ndarray, step) -> tuple:
    """(real, imaginary) float32 taps: polyphase row r, tap j times e^{-j w (j - (J - 1))}, w the mixer's
    angular step per input sample (``step`` / 2^64 cycles)."""
    J = hp.shape[1]
    w = 2 * np.pi * (int(step) / 2.0 ** 64)
    rot = np.exp(-1j * w * (np.arange(J) - (J - 1)))
    hc = hp.astype(np.float64) * rot[None, :]
    return (np.ascontiguousarray(hc.real.astype(np.float32)), np.ascontiguousarray(hc.imag.astype(np.float32)))


class DecimatingReader:
    """A sample reader at fs_in L / M, complex baseband (``if_hz`` 0), over a :class:`SampleReader` (or
    any reader with ``fs``, ``first``, ``end``, ``read``).  Index k of this reader is time k / fs_out
    (file position k M / L).  Every other attribute is the wrapped reader's."""

    def __init__(self, reader, l: int, m: int, if_hz: float, chip_rate: float):
        self._reader = reader
        self.l, self.m = int(l), int(m)
        self.decimation = self.m / self.l
        self.resample = f"{self.l}/{self.m}"
        self.input_fs, self.input_if_hz = float(reader.fs), float(if_hz)
        self.fs = self.input_fs * self.l / self.m
        self.if_hz = 0.0
        self.first = -(-reader.first * self.l // self.m)
        self.end = -(-reader.end * self.l // self.m)
        frac = (if_hz / self.input_fs) % 1.0
        self._step = np.uint64(int(round(frac * 2.0 ** 64)) % (1 << 64))
        self._shift = np.uint64(64 - LUT_BITS)
        fmt = getattr(reader, "format", None)
        self._real = bool(fmt is not None and not fmt.complex)
        # packed real SampleReader: unpacked inside the compiled call from the memory-mapped bytes, the
        # spectral inversion (iq_swap: (-1)^n) folded into the mixer as fs_in / 2
        self._packed = bool(self._real and getattr(fmt, "kind", "") == "packed"
                            and hasattr(reader, "_raw") and hasattr(reader, "_table"))
        real_step = self._step
        if self._packed and getattr(reader, "iq_swap", False):
            real_step = np.uint64((int(self._step) + (1 << 63)) % (1 << 64))
        self._real_step = real_step
        self._hp, self._c = design(self.input_fs, self.l, self.m, chip_rate)
        perm, self._inv = visit_order(self.l, self.m)
        self._hv = np.ascontiguousarray(self._hp[perm])              # rows in visiting order
        if self._real:
            hr, hi = complex_taps(self._hp, real_step)
            self._hr, self._hi = np.ascontiguousarray(hr[perm]), np.ascontiguousarray(hi[perm])
        # pieces may run on the thread pool unless the wrapped reader keeps state (NaN counting of float
        # formats) or is not a plain file reader
        self._parallel = self._packed or (fmt is not None and getattr(fmt, "kind", "") == "int"
                                          and hasattr(reader, "_raw"))

    def __getattr__(self, name):
        return getattr(self._reader, name)

    @property
    def n_samples(self) -> int:
        """Number of output samples in the span (``end - first``)."""
        return self.end - self.first

    @property
    def duration_s(self) -> float:
        """Length of the span (s)."""
        return self.n_samples / self.fs

    @property
    def taps(self) -> int:
        """Input samples per output sample (J)."""
        return self._hp.shape[1]

    def read(self, start: int, n: int) -> np.ndarray:
        """Stream samples [start, start+n) (clipped to the span) as complex64."""
        return self._compute(max(int(start), self.first), int(n))

    def _compute(self, start: int, n: int, n_thr: int | None = None) -> np.ndarray:
        stop = min(start + n, self.end)
        if stop <= start:
            return np.zeros(0, np.complex64)
        out = np.empty(stop - start, np.complex64)
        if n_thr is None:
            n_thr = threads() if self._parallel else 1
        piece = PIECE
        if n_thr > 1:                                     # at least one piece per thread
            piece = max(4096, min(PIECE, -(-(stop - start) // n_thr)))
        spans = [(k0, min(k0 + piece, stop)) for k0 in range(start, stop, piece)]
        if n_thr > 1 and len(spans) > 1:
            map_ordered(lambda s: self._piece(s[0], out[s[0] - start:s[1] - start]), spans)
        else:
            for k0, k1 in spans:
                self._piece(k0, out[k0 - start:k1 - start])
        return out

    def _piece(self, k0: int, out: np.ndarray):
        l, m, c, J = self.l, self.m, self._c, self._hp.shape[1]
        lo = (k0 * m + c) // l - J + 1                    # input span [lo, hi)
        hi = ((k0 + out.size - 1) * m + c) // l + 1
        a = max(lo, self._reader.first)                   # the wrapped reader clips to its span: zero-pad
        if self._packed:
            r = self._reader
            e = max(a, min(hi, r.end))
            k = r._table.shape[1]                         # fields per byte
            b0 = a // k
            r.release_before(a)                           # (resident memory flat along the file)
            raw = np.asarray(r._raw[b0:-(-e // k)]) if e > a else np.zeros(1, np.uint8)
            _resample_packed_real(raw, r._table, a - b0 * k, a, e, lo, hi, self._real_step, _LUT, _LUT_FINE,
                                  self._hr, self._hi, self._inv, c, l, m, k0, out)
            return
        raw = self._reader.read(a, hi - a)
        if self._real:
            x = np.zeros(hi - lo, np.float32)
            x[a - lo:a - lo + raw.size] = raw.real
            _filter_real(x, lo, self._step, _LUT, _LUT_FINE, self._hr, self._hi, self._inv, c, l, m, k0, out)
            return
        if a != lo or raw.size != hi - lo:
            x = np.zeros(hi - lo, np.complex64)
            x[a - lo:a - lo + raw.size] = raw
            raw = x
        _resample(raw, lo, self._step, _LUT, self._shift, self._hv, self._inv, c, l, m, k0, self._real, out)

    def describe(self) -> str:
        """One line for the run log: input rate (and IF) -> output rate, the ratio L/M and the filter length."""
        return (f"resampling      {self.input_fs / 1e6:g} MS/s" + (f" (IF {self.input_if_hz / 1e6:g} MHz)"
                if self.input_if_hz else "") + f" -> {self.fs / 1e6:g} MS/s complex baseband (x{self.resample}, "
                f"{self.taps} input samples per output)")
