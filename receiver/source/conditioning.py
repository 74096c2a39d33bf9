"""Input conditioning: DC removal, narrowband-interference (CW / spur) detection and cancellation, optional
pulse blanking -- one stage between the sample file and acquisition / tracking (``input.conditioning``).

The tone detector (:func:`detect_tones`: averaged periodogram, robust floor, Pfa-controlled threshold) is
receiver.source.tones.

Tone canceller (:func:`cancel`, numba)
    Per tone ``k`` a complex amplitude ``a_k`` is tracked by a one-pole LMS on the input mixed down by
    the tone's phasor, and ``a_k exp(j 2 pi f_k n / fs)`` is subtracted.  This is a notch filter of
    -3 dB width ``~ mu fs / pi`` Hz centred on the tone (``notch_bw_hz``, default 100 Hz): a few hundred
    Hz out of the ~2 MHz C/A main lobe, so the signal loses < 0.01 dB; the depth on a stable tone is
    > 60 dB.  DC removal is the same canceller at 0 Hz.  The filter is causal and keeps its state from
    one block to the next (:class:`ConditionedReader` continues the stream when consecutive reads
    overlap, as the pipeline's chunk reads do), so there are no block-edge discontinuities.

Pulsed interference (:mod:`receiver.source.pulses`, ``pulse_detection``): found in the detection span and at
every monitor check, blanked by an adaptive causal blanker while present (the static ``pulse_blanking``:
samples whose magnitude exceeds ``blank_sigma`` times the RMS of the conditioned detection span are set to
zero).  Moving narrowband interference (:mod:`receiver.source.excision`, ``tf_excision``): found the same way,
excised in short FFT frames of the raw samples before the notches.  Tone detection is in
:mod:`receiver.source.tones`.

Why this module is long: the reader's monitor is one state machine over the notches, the blanker and the
excision, and the canceller kernel carries the notches' state it switches.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit
from ..estimation.stats import gamma_median
from . import excision, pulses
from .io import SampleReader, _deinterleave
from .tones import ENBW_BH as _ENBW_BH
from .tones import Detection, Tone, detect_tones, refine_tone_frequency  # noqa: F401 (re-exported)

QUIET_CHECKS = 3        # monitor checks a notch's tone must stay below the detection level before it is removed


@njit(inline="always", fastmath=True)
def _dc_step(xr, xi, ar, ai, m, blank2):
    """One sample of the DC canceller: (out I, out Q, tracked DC I, Q) -- the sample less the DC, the DC
    moved toward the sample by m; the output zeroed when its power exceeds blank2 (> 0)."""
    yr = xr - ar
    yi = xi - ai
    ar += m * yr
    ai += m * yi
    if blank2 > 0.0 and yr * yr + yi * yi > blank2:
        yr = 0.0
        yi = 0.0
    return yr, yi, ar, ai


@njit(cache=True, fastmath=True, nogil=True)
def cancel(x, out, steps, rot, amp, mu, blank_level, dw, dr, res, g1, g2, g3, pfloor):
    """Subtract the tracked tones from ``x`` into ``out`` (complex64); the state arrays are updated.

    steps[k] = exp(j 2 pi f_k / fs) (complex128; 1 for DC: no rotation); rot[k] the tone phasor at the
    first sample, amp[k] the tracked complex amplitude (both left at the state after the last sample);
    mu[k] the LMS gain.  blank_level > 0: samples with |y| above it are zeroed after cancellation.
    Frequency tracking (g1[k] > 0): a 3rd-order phase-locked loop on the tone
    -- phase error Im(z conj(a)) / |a|^2 of the mixed-down input z against the tracked amplitude a, run
    while |a|^2 > pfloor[k] -- turns the extra frequency dw[k] (rad / sample, its rate dr[k]) and the phase
    of rot[k], so the notch follows a drifting or linearly swept tone without a steady phase lag.  res[k]
    is the input power |z|^2 smoothed over ~0.1 / mu samples (~|a|^2 + noise while the tone is there): a
    tone that has gone (or a pulse that ended) leaves it at the noise, and the loop holds its frequency while
    res is below |a|^2 / 2 (it would otherwise follow the noise while the amplitude decays); pfloor is
    twice the noise power per sample.
    Real arithmetic on local scalars (the LMS recursion is the dependency chain).
    """
    nt = steps.size
    blank2 = blank_level * blank_level
    if nt == 1 and steps[0] == 1.0:                  # DC removal only: the common case, kept lean
        ar, ai, m = amp[0].real, amp[0].imag, mu[0]
        for n in range(x.size):
            yr, yi, ar, ai = _dc_step(x[n].real, x[n].imag, ar, ai, m, blank2)
            out[n] = complex(yr, yi)
        amp[0] = complex(ar, ai)
        return out
    for n in range(x.size):
        vr = np.float64(x[n].real)
        vi = np.float64(x[n].imag)
        for k in range(nt):
            rr, ri = rot[k].real, rot[k].imag
            ar, ai = amp[k].real, amp[k].imag
            # z = v conj(r); a += mu (z - a); v -= a_old r
            zr = vr * rr + vi * ri
            zi = vi * rr - vr * ri
            vr -= ar * rr - ai * ri
            vi -= ar * ri + ai * rr
            amp[k] = complex(ar + mu[k] * (zr - ar), ai + mu[k] * (zi - ai))
            sr, si = steps[k].real, steps[k].imag
            if g1[k] > 0.0:
                p = ar * ar + ai * ai
                res[k] += 10.0 * mu[k] * (zr * zr + zi * zi - res[k])
                if p > pfloor[k] and res[k] > 0.5 * p:
                    e = (zi * ar - zr * ai) / p             # Im(z conj(a)) / |a|^2: phase error (rad)
                    dr[k] += g3[k] * e
                    dw[k] += g2[k] * e + dr[k]
                    th = g1[k] * e + dw[k]                  # this sample's extra rotation
                    cr = 1.0 - 0.5 * th * th
                    sr, si = sr * cr - si * th, sr * th + si * cr
            nr = rr * sr - ri * si
            ni = rr * si + ri * sr
            g = 1.5 - 0.5 * (nr * nr + ni * ni)         # keeps |rot| = 1 (same at every sample, so the
            rot[k] = complex(nr * g, ni * g)            # output does not depend on the block split)
        if blank2 > 0.0 and vr * vr + vi * vi > blank2:
            vr = 0.0
            vi = 0.0
        out[n] = complex(vr, vi)
    return out


@njit(cache=True, fastmath=True, nogil=True)
def cancel_dc_interleaved(raw, swap, offset, out, amp, mu, blank_level):
    """:func:`cancel`'s DC-removal-only path on interleaved integer I/Q (``complex(raw[2k], raw[2k+1]) -
    offset``, I and Q swapped when ``swap``: receiver.source.io's conversion) converted as it goes: the
    same values as converting first, without the intermediate array."""
    a, b = (1, 0) if swap else (0, 1)
    blank2 = blank_level * blank_level
    ar, ai, m = amp[0].real, amp[0].imag, mu[0]
    for n in range(out.size):
        yr, yi, ar, ai = _dc_step(np.float32(raw[2 * n + a]) - offset.real, np.float32(raw[2 * n + b]) - offset.imag,
                                  ar, ai, m, blank2)
        out[n] = complex(yr, yi)
    amp[0] = complex(ar, ai)
    return out


class Interleaved:
    """Interleaved integer I/Q samples not yet converted (receiver.source.io.SampleReader.interleaved): the
    conditioning stage's DC removal reads them directly; anything else converts them first."""

    __slots__ = ("raw", "swap", "offset")

    def __init__(self, raw, swap, offset):
        self.raw, self.swap, self.offset = raw, swap, offset

    def __len__(self):
        return len(self.raw) // 2

    def __getitem__(self, sl: slice) -> "Interleaved":
        i, j, _ = sl.indices(len(self))
        return Interleaved(self.raw[2 * i:2 * max(i, j)], self.swap, self.offset)

    def complex64(self) -> np.ndarray:
        """The samples converted (receiver.source.io's values)."""
        out = np.empty(len(self), np.complex64)
        _deinterleave(self.raw, self.swap, self.offset, out)
        return out


class Canceller:
    """State of the tone cancellers (DC first if enabled)."""

    def __init__(self, freqs_hz, fs: float, notch_bw_hz: float, dc_bw_hz: float | None, blank_level=0.0,
                 track_hz: float = 0.0, noise_power: float = 0.0):
        fl, mus = [], []
        if dc_bw_hz is not None:
            fl.append(0.0)
            mus.append(min(math.pi * dc_bw_hz / fs, 0.5))
        for f in freqs_hz:
            fl.append(float(f))
            mus.append(min(math.pi * notch_bw_hz / fs, 0.5))
        self.freqs = np.array(fl, np.float64)
        self.steps = np.exp(2j * np.pi * self.freqs / fs).astype(np.complex128)
        self.mu = np.array(mus, np.float64)
        self.fs = fs
        self.blank_level = float(blank_level)
        self.rot = np.ones(len(fl), np.complex128)
        self.amp = np.zeros(len(fl), np.complex128)

        self.has_dc = dc_bw_hz is not None
        self.quiet = np.zeros(len(fl), np.int64)      # consecutive monitor checks a notch's tone was absent
        # frequency tracking of the tone notches (not DC): loop natural frequency track_hz, damping 0.707;
        # the loop runs while the tone's power is above the noise power per sample
        # (3rd order, the usual coefficients 2.4, 1.1, 1 of w0 T, (w0 T)^2, (w0 T)^3)
        wn = 2.0 * math.pi * float(track_hz) / fs
        self.track = (2.4 * wn, 1.1 * wn * wn, wn ** 3)
        self.noise_power = float(noise_power)
        self.dw = np.zeros(len(fl), np.float64)
        self.dr = np.zeros(len(fl), np.float64)
        self.res = np.zeros(len(fl), np.float64)
        self._loop_arrays()
        # adaptive pulse blanker (receiver/source/pulses.py): off until pulses are seen
        self.pulse_on = False
        self.pst = np.zeros(pulses.N_STATE, np.float64)
        self.ppar = pulses.blanker_params(6.0)

    def start_blanking(self, floor: float, threshold_db: float):
        """Switch the adaptive pulse blanker on at the noise floor ``floor`` (mean power per sample)."""
        runs, blanked = self.pst[pulses.S_RUNS], self.pst[pulses.S_BLANKED]
        self.pst = pulses.blanker_state(floor)
        self.pst[pulses.S_RUNS], self.pst[pulses.S_BLANKED] = runs, blanked
        self.ppar = pulses.blanker_params(threshold_db)
        self.pulse_on = True

    def _loop_arrays(self):
        n = self.freqs.size
        on = np.ones(n, bool)
        if self.has_dc and n:
            on[0] = False
        self.g1 = np.where(on, self.track[0], 0.0)
        self.g2 = np.where(on, self.track[1], 0.0)
        self.g3 = np.where(on, self.track[2], 0.0)
        self.pfloor = np.full(n, max(2.0 * self.noise_power, 1e-30))

    def current_freqs(self) -> np.ndarray:
        """The notches' frequencies now (Hz): the nominal plus what the tracking loop has added."""
        return self.freqs + self.dw * self.fs / (2.0 * math.pi)

    @property
    def active(self) -> bool:
        """Whether the canceller changes the samples (a notch, or blanking)."""
        return self.freqs.size > 0 or self.blank_level > 0 or self.pulse_on

    def set_tones(self, freqs, rot, amp, mu, quiet, dw=None, dr=None, res=None):
        """Replace the tone set (new arrays: a forked copy of this canceller keeps its own)."""
        self.freqs = np.asarray(freqs, np.float64)
        self.dw = np.zeros(self.freqs.size) if dw is None else np.asarray(dw, np.float64)
        self.dr = np.zeros(self.freqs.size) if dr is None else np.asarray(dr, np.float64)
        self.res = np.zeros(self.freqs.size) if res is None else np.asarray(res, np.float64)
        self.steps = np.exp(2j * np.pi * self.freqs / self.fs).astype(np.complex128)
        if self.has_dc and self.freqs.size:
            self.steps[0] = 1.0
        self.rot = np.asarray(rot, np.complex128)
        self.amp = np.asarray(amp, np.complex128)
        self.mu = np.asarray(mu, np.float64)
        self.quiet = np.asarray(quiet, np.int64)
        self._loop_arrays()

    def reset(self, x):
        """Fresh state, amplitudes initialised from the first millisecond of ``x`` (complex64 or
        :class:`Interleaved`; no convergence transient at a stream start)."""
        m = max(1, min(len(x), int(self.fs * 1e-3)))
        n = np.arange(m)
        self.rot = np.ones(self.freqs.size, np.complex128)
        self.amp = np.zeros(self.freqs.size, np.complex128)
        self.res = np.zeros(self.freqs.size, np.float64)
        head = x[:m]
        resid = (head.complex64() if isinstance(head, Interleaved) else head).astype(np.complex128)
        for k, f in enumerate(self.current_freqs()):
            ph = np.exp(-2j * np.pi * f / self.fs * n)
            a = complex(np.mean(resid * ph))
            self.amp[k] = a
            resid = resid - a * np.conj(ph)
        pulses.restart(self.pst)

    def process(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The conditioned samples of ``x`` (into ``out``, complex64 of len(x), when given)."""
        if out is None:
            out = np.empty(len(x), np.complex64)
        if isinstance(x, Interleaved):
            if self.active and not self.pulse_on and self.steps.size == 1 and self.steps[0] == 1.0:
                return cancel_dc_interleaved(x.raw, x.swap, x.offset, out, self.amp, self.mu, self.blank_level)
            x = x.complex64()
        if not self.active:
            out[:] = x
            return out
        if self.pulse_on:
            return pulses.cancel_blank(np.ascontiguousarray(x, np.complex64), out, self.steps, self.rot, self.amp,
                                       self.mu, self.blank_level, self.dw, self.dr, self.res, self.g1, self.g2, self.g3,
                                       self.pfloor, self.pst, self.ppar, np.zeros(2 * self.steps.size))
        return cancel(np.ascontiguousarray(x, np.complex64), out, self.steps, self.rot, self.amp, self.mu,
                      self.blank_level, self.dw, self.dr, self.res, self.g1, self.g2, self.g3, self.pfloor)


class ConditionedReader:
    """A :class:`receiver.io.SampleReader` whose blocks pass through the conditioning stage.

    Reads that start inside the last block returned (or at its end) continue the filter stream, reusing
    the samples already filtered, so overlapping chunk reads see one continuous causal filter.  A read
    anywhere else restarts the stream there.  Every other attribute is the wrapped reader's.
    """

    def __init__(self, reader, cfg, detect_start: int | None = None, log=None, dc_hz: float = 0.0):
        self._reader = reader
        self.cfg = cfg
        fs = reader.fs
        # dc_hz: where the front end's DC offset / LO leakage lies in this stream.  An input stage that mixes
        # a nonzero IF down (receiver/source/decimate.py) moves it to -IF, out of the notch's reach and, for
        # a real IF, out of the band (what little its filter passes is a tone for the tone detector): the
        # DC canceller would only track noise there, so it is not run.
        self.dc_hz = float(dc_hz)
        self.dc_removal = bool(cfg.dc_removal) and abs(self.dc_hz) <= cfg.dc_bw_hz
        start = reader.first if detect_start is None else detect_start
        n = int(round(cfg.detect_ms * 1e-3 * fs))
        span = reader.read(start, n)
        # pulsed interference (receiver/source/pulses.py) first: a pulse train's spectral lines are no tones
        self._pdet = bool(cfg.pulse_detection) and not cfg.pulse_blanking   # (the static blanker instead)
        self.pulse_events = ()           # (sample, "on" | "off", noise floor, share of over blocks)
        pt = pulses.pulse_test(span, cfg.pulse_threshold_db, cfg.pulse_min_count) if self._pdet else None
        # moving narrowband interference (receiver/source/excision.py): excised before the tones are sought
        self._tf = bool(cfg.tf_excision)
        self._tf_n = excision.frame_size(fs, cfg.tf_frame_us)
        self._tf_on, self._tf_floor, self._tf_hits, self._tf_frames, self._tf_quiet = False, None, 0, 0, 0
        self.tf_events = ()              # (sample, "on" | "off", share of frames over the gate)
        self._first = reader.first
        tt = excision.tf_test(span, self._tf_n) if self._tf and len(span) else None
        if tt is not None and tt.moving:
            self._tf_on, self._tf_floor = True, tt.floor
            self.tf_events = ((int(start), "on", tt.frames),)
            span = self._excise(start, len(span))
        tone_span = span
        if pt is not None and pt.pulsed:
            tone_span = span.copy()
            tone_span[pulses.blank_mask(span, pt.floor, cfg.pulse_threshold_db)] = 0
        self.detection = detect_tones(tone_span, fs, cfg.fft_size, cfg.pfa, cfg.min_db, max(cfg.max_tones, 16)) \
            if cfg.tone_detection else Detection(dc=complex(np.mean(span)) if len(span) else 0j)
        cancel_f = []
        dc_bin = self.detection.bin_hz if self.detection.bin_hz else 0.0
        for t in self.detection.tones:                # strongest first
            t.dc = bool(self.dc_removal and abs(t.freq_hz) <= dc_bin)   # the DC canceller takes it
            if not t.dc and cfg.tone_excision and len(cancel_f) < cfg.max_tones:
                cancel_f.append(t.freq_hz)
            else:
                t.cancelled = False
        self._make = lambda level: Canceller(cancel_f, fs, cfg.notch_bw_hz,
                                             cfg.dc_bw_hz if self.dc_removal else None, level,
                                             cfg.notch_track_hz, self.detection.noise_power)
        self.canceller = self._make(0.0)
        self.blank_level = 0.0
        if pt is not None and pt.pulsed:
            self.canceller.start_blanking(pt.floor, cfg.pulse_threshold_db)
            self.pulse_events = ((int(start), "on", pt.floor, pt.fraction),)
        self._pruns, self._pquiet = 0.0, 0
        y = span                                      # (no tone, no DC canceller: the span as it is)
        if len(span) and self.canceller.active:       # one pass over the span: DC estimate, blanking RMS
            self.canceller.reset(span)
            y = self.canceller.process(span)
            if self.dc_removal:
                self.detection.dc = complex(self.canceller.amp[0])   # free of the tones
        if cfg.pulse_blanking and len(span):
            rms = math.sqrt(float(np.median(np.abs(y) ** 2)) / math.log(2.0))    # robust (complex Gaussian)
            self.blank_level = cfg.blank_sigma * rms
            self.canceller = self._make(self.blank_level)
            if pt is not None and pt.pulsed:
                self.canceller.start_blanking(pt.floor, cfg.pulse_threshold_db)
        self.blanked = 0
        self.processed = 0
        self.canceller.pst[pulses.S_BLANKED] = self.canceller.pst[pulses.S_RUNS] = 0.0   # (the span's pass)
        self._tail = np.zeros(0, np.complex64)
        self._tail_start = None
        # interference monitor (module doc): checks at every monitor_ms of the stream from the detection span on
        self._mon_step = int(round(cfg.monitor_ms * 1e-3 * fs)) \
            if ((cfg.tone_detection and cfg.tone_excision) or self._pdet or self._tf) and cfg.monitor_ms > 0 else 0
        self._tones_mon = bool(cfg.tone_detection and cfg.tone_excision)
        self._mon_len = int(cfg.fft_size) * int(cfg.monitor_segments)
        self._mon_next = start + n
        self._mon_buf = np.zeros(0, np.complex64)
        self.tone_events = ()            # (sample, "added" | "removed" | "retuned", freq Hz, power dB re noise)
        self.checks = 0

    def __getattr__(self, name):
        return getattr(self._reader, name)

    @property
    def active(self) -> bool:
        """A notch (or DC removal, blanking) runs on the samples."""
        return self.canceller.active

    def read(self, start: int, n: int) -> np.ndarray:
        """Samples [start, start + n) of the underlying reader (file sample index), conditioned (notches, DC
        removal, blanking; unchanged when none runs; a read continuing the previous one carries the filter on)."""
        if not self.canceller.active and not self._mon_step and not self._tf_on:
            return self._reader.read(start, n)
        start = max(start, self._reader.first)
        ts, tail = self._tail_start, self._tail
        if ts is not None and ts <= start <= ts + len(tail):
            have = tail[start - ts:]
            pos = ts + len(tail)
            need = start + n - pos
            if need <= 0:
                return have[:n].copy()
            raw = self._raw_read(pos, need)
            out = np.empty(len(have) + len(raw), np.complex64)
            out[:len(have)] = have
            self._filter(raw, out[len(have):], pos)    # (filtered in place: no concatenation copy)
        else:
            raw = self._raw_read(start, n)
            self.canceller.reset(raw)
            # a restarted stream: the monitor's span starts again (at the read when it is ahead)
            self._mon_buf = np.zeros(0, np.complex64)
            self._mon_next = max(self._mon_next, start)
            out = self._filter(raw, None, start)
        self._tail, self._tail_start = out, start
        return out

    def _raw_read(self, start, n):
        """The input samples [start, start + n): interleaved integers left for the DC removal to convert
        (:class:`Interleaved`) when the file reader offers them, else complex64."""
        got = self._reader.interleaved(start, n) if isinstance(self._reader, SampleReader) else None
        return Interleaved(*got) if got is not None else self._reader.read(start, n)

    def _filter(self, raw, out=None, start=None):
        """Condition raw (stream position start) into out, running the monitor checks that fall due: a check
        fires when the stream reaches the end of its span, on the last monitor span of conditioned samples
        (kept across reads), so where a read ends does not change the output."""
        if out is None:
            out = np.empty(len(raw), np.complex64)
        pos, n, L = 0, len(raw), self._mon_len
        if self._mon_step and start is not None:
            while True:
                k = self._mon_next + L - start          # the check's end, in this read
                if k > n:
                    break
                if k < pos:                             # (cannot happen: the restart rule in read)
                    self._mon_next = start + pos
                    continue
                self._process(self._excise(start + pos, k - pos) if self._tf_on else raw[pos:k], out[pos:k])
                self._push(out[pos:k])
                pos = k
                if len(self._mon_buf) == L:
                    self._check(self._mon_buf, start + k - L)
                self._mon_next += self._mon_step
        if pos < n:
            self._process(self._excise(start + pos, n - pos) if self._tf_on and start is not None else raw[pos:],
                          out[pos:])
            if self._mon_step and start is not None:
                self._push(out[pos:])
        return out

    def _push(self, y):
        """Keep the last monitor span of the conditioned stream (new arrays: a forked reader keeps its own)."""
        L = self._mon_len
        self._mon_buf = y[-L:].copy() if len(y) >= L else np.concatenate([self._mon_buf, y])[-L:]

    def _excise(self, s0, count):
        """Raw samples [s0, s0 + count) after time-frequency excision (receiver/source/excision.py)."""
        y, hits, frames = excision.tf_excise(self._reader.read, self._first, s0, count, self._tf_n,
                                             self._tf_floor, self.cfg.tf_threshold_db)
        self._tf_hits += hits
        self._tf_frames += frames
        return y

    def _process(self, raw, out):
        y = self.canceller.process(raw, out)
        if self.blank_level > 0:
            self.blanked += int(np.count_nonzero(y == 0))
        self.processed += len(y)
        return y

    def _check(self, y, s):
        """One monitor check on the conditioned span y (first sample s): a tone left in it gets a notch from
        the span's end on (amplitude and phase estimated from the span: no convergence transient), a notch
        within two bins of it is retuned; a notch whose tracked amplitude stayed below the detection level
        for QUIET_CHECKS checks is removed (its subtraction is then below the noise: no transient)."""
        cfg, c, fs = self.cfg, self.canceller, self._reader.fs
        self.checks += 1
        if self._pdet and self._check_pulses(y, s) or self._tf and self._check_tf(s, len(y)) \
                or not self._tones_mon:
            return                              # (pulses or a sweep just found: this span's lines are no tones)
        # the check's false-alarm probability from a rate per unit time: at pfa per check (10 checks a
        # second) a clean file got a false notch every ~100 s
        pfa = min(cfg.pfa, cfg.monitor_false_per_hour * cfg.monitor_ms / 3.6e6)
        # without a tone notch the floor is needed only when a bin may be over it (its noise power sets the
        # notches' loop floor, pfloor, which DC removal does not use): screened, a clean span costs its FFT
        k0 = 1 if c.has_dc else 0
        det = detect_tones(y, fs, cfg.fft_size, pfa, cfg.min_db, 16, screen=len(c.freqs) <= k0)
        if det is None or det.noise_power <= 0:
            return
        L = len(y)
        freqs, rot, amp = list(c.freqs), list(c.rot), list(c.amp)
        mu, quiet, dw, dr, res = list(c.mu), list(c.quiet), list(c.dw), list(c.dr), list(c.res)
        cur = list(c.current_freqs())
        c.noise_power = det.noise_power            # the tracking loops' floor follows the noise
        # the weakest tone the detector sees in a bin: thr x floor, floor = noise x ENBW / nfft
        p_min = 10 ** (det.threshold_db / 10) * det.noise_power * _ENBW_BH / det.fft_size
        changed = False
        t_mu = min(math.pi * cfg.notch_bw_hz / fs, 0.5)
        n = np.arange(L)
        for t in det.tones:
            if c.has_dc and abs(t.freq_hz) <= det.bin_hz:
                continue                        # the DC canceller's
            ph = np.exp(-2j * np.pi * t.freq_hz / fs * n)
            a = complex(np.mean(y * ph)) * np.exp(2j * np.pi * t.freq_hz / fs * L)   # at the span's end
            near = [k for k in range(k0, len(freqs)) if abs(cur[k] - t.freq_hz) <= 2 * det.bin_hz]
            if near and c.g1[near[0]] > 0 and abs(a) ** 2 < 0.1 * abs(amp[near[0]]) ** 2:
                continue                        # a tracked notch's lag residual: its loop follows the tone
            if near:
                k = near[0]
                # the notch's own part at its old frequency, moved to the new one
                a = a + amp[k] * rot[k] / 1.0
                freqs[k], rot[k], amp[k], quiet[k], dw[k], dr[k], res[k] = t.freq_hz, 1.0 + 0j, a, 0, 0.0, 0.0, 0.0
                cur[k] = t.freq_hz
                what = "retuned"
            elif len(freqs) - k0 < cfg.max_tones:
                freqs.append(t.freq_hz), rot.append(1.0 + 0j), amp.append(a), mu.append(t_mu), quiet.append(0)
                dw.append(0.0), dr.append(0.0), res.append(0.0), cur.append(t.freq_hz)
                what = "added"
            else:
                continue
            changed = True
            self.tone_events = self.tone_events + ((int(s + L), what, float(t.freq_hz), float(t.jnr_db)),)
        keep = []
        for k in range(len(freqs)):
            if k >= k0 and abs(amp[k]) ** 2 < 0.25 * p_min:
                quiet[k] += 1
            elif k >= k0:
                quiet[k] = 0
            if k >= k0 and quiet[k] >= QUIET_CHECKS:
                self.tone_events = self.tone_events + (
                    (int(s + L), "removed", float(cur[k]),
                     float(10 * np.log10(max(abs(amp[k]) ** 2, 1e-30) / det.noise_power))),)
                changed = True
                continue
            keep.append(k)
        if changed or any(q != q0 for q, q0 in zip(quiet, c.quiet)):
            c.set_tones([freqs[k] for k in keep], [rot[k] for k in keep], [amp[k] for k in keep],
                        [mu[k] for k in keep], [quiet[k] for k in keep], [dw[k] for k in keep],
                        [dr[k] for k in keep], [res[k] for k in keep])
        else:
            c._loop_arrays()

    def _check_pulses(self, y, s) -> bool:
        """The monitor's pulse check on the conditioned span y (first sample s): the blanker is switched on
        when the span is pulsed (True: the caller leaves the span's tones to the next check), off after
        QUIET_CHECKS checks in which it blanked nothing."""
        cfg, c = self.cfg, self.canceller
        if not c.pulse_on:
            if not pulses.may_be_pulsed(y, cfg.pulse_threshold_db, cfg.pulse_min_count):
                return False
            pt = pulses.pulse_test(y, cfg.pulse_threshold_db, cfg.pulse_min_count)
            if not pt.pulsed:
                return False
            c.start_blanking(pt.floor, cfg.pulse_threshold_db)
            self._pruns, self._pquiet = float(c.pst[pulses.S_RUNS]), 0
            self.pulse_events = self.pulse_events + ((int(s + len(y)), "on", pt.floor, pt.fraction),)
            return True
        runs = float(c.pst[pulses.S_RUNS]) - self._pruns
        self._pruns = float(c.pst[pulses.S_RUNS])
        self._pquiet = 0 if runs > 0 else self._pquiet + 1
        if self._pquiet >= QUIET_CHECKS:
            c.pulse_on = False
            self.pulse_events = self.pulse_events + (
                (int(s + len(y)), "off", float(c.pst[pulses.S_Q]) / gamma_median(pulses.BLOCK), 0.0),)
        return False

    def _check_tf(self, s, L) -> bool:
        """The monitor's test for moving narrowband interference on the raw span [s, s + L): excision on when
        found (True: the caller leaves the span's tones to the next check), the per-bin floor renewed while
        on, off after QUIET_CHECKS checks excising in under 1 % of the frames."""
        tt = excision.tf_test(self._reader.read(s, L), self._tf_n)
        if not self._tf_on:
            if not tt.moving:
                return False
            self._tf_on, self._tf_floor, self._tf_hits, self._tf_frames, self._tf_quiet = True, tt.floor, 0, 0, 0
            self.tf_events = self.tf_events + ((int(s + L), "on", tt.frames),)
            return True
        if tt.floor.size and np.all(tt.floor > 1e-30):
            self._tf_floor = tt.floor
        busy = self._tf_hits >= 0.01 * max(self._tf_frames, 1)
        self._tf_hits = self._tf_frames = 0
        self._tf_quiet = 0 if busy else self._tf_quiet + 1
        if self._tf_quiet >= QUIET_CHECKS:
            self._tf_on = False
            self.tf_events = self.tf_events + ((int(s + L), "off", tt.frames),)
        return False

    @property
    def blanked_fraction(self) -> float:
        """Share of the conditioned samples set to zero by a pulse blanker (static or adaptive)."""
        n = self.blanked + float(self.canceller.pst[pulses.S_BLANKED])
        return n / self.processed if self.processed else 0.0

    # ------------------------------------------------------------------ reporting
    def summary_lines(self) -> list:
        """The conditioning's lines of the run summary: DC removal, tones found and cancelled, blanking."""
        d, c = self.detection, self.cfg
        lines = []
        parts = []
        if c.dc_removal and not self.dc_removal:
            parts.append(f"no DC removal (the input stage mixed the front end's DC to "
                         f"{self.dc_hz / 1e6:+.4g} MHz)")
        if self.dc_removal:
            p = abs(d.dc) ** 2 / d.noise_power if d.noise_power else 0.0
            parts.append(f"DC removal (offset {d.dc.real:.3g}{d.dc.imag:+.3g}j"
                         + (f", {10 * np.log10(p):.1f} dB re noise" if p > 0 else "") + ")")
        if c.tone_detection:
            if d.tones:
                parts.append(f"{len(d.tones)} tone(s): " + ", ".join(
                    f"{t.freq_hz / 1e3:+.3f} kHz {t.jnr_db:+.1f} dB"
                    + (" (DC removal)" if t.dc else "" if t.cancelled else " (not cancelled)")
                    for t in d.tones))
            else:
                parts.append("no tones")
        if self.tone_events:
            fs = self._reader.fs
            ev = self.tone_events
            shown = ", ".join(f"{w} {f / 1e3:+.3f} kHz at {smp / fs:.2f} s" for smp, w, f, _ in ev[:6])
            parts.append(f"interference monitor: {len(ev)} notch change(s): {shown}"
                         + (", ..." if len(ev) > 6 else ""))
        if self.blank_level > 0:
            frac = self.blanked / self.processed if self.processed else 0.0
            parts.append(f"pulse blanking {100 * frac:.3f} % of samples")
        if self.tf_events:
            fs = self._reader.fs
            shown = ", ".join(f"{w} at {smp / fs:.2f} s" for smp, w, _ in self.tf_events[:6])
            parts.append(f"moving narrowband interference: time-frequency excision {shown}"
                         + (", ..." if len(self.tf_events) > 6 else ""))
        if self.pulse_events:
            fs = self._reader.fs
            shown = ", ".join(f"{w} at {smp / fs:.2f} s" for smp, w, _, _ in self.pulse_events[:6])
            parts.append(f"pulsed interference: blanking {shown}"
                         + (", ..." if len(self.pulse_events) > 6 else "")
                         + f"; {100 * self.blanked_fraction:.2f} % of samples blanked")
        if parts:
            lines.append("conditioning    " + "; ".join(parts))
        return lines

    def write(self, writer):
        """/conditioning: the detected tones and the stage's settings (attrs)."""
        d = self.detection
        g = writer.f.require_group("conditioning")
        for name in list(g):
            del g[name]
        g.create_dataset("freq_hz", data=np.array([t.freq_hz for t in d.tones], float))
        g.create_dataset("jnr_db", data=np.array([t.jnr_db for t in d.tones], float))
        g.create_dataset("snr_bin_db", data=np.array([t.snr_bin_db for t in d.tones], float))
        g.create_dataset("cancelled", data=np.array([t.cancelled for t in d.tones], bool))
        ev = self.tone_events
        g.create_dataset("event_time_s", data=np.array([e[0] / self._reader.fs for e in ev], float))
        g.create_dataset("event_kind", data=np.array([e[1] for e in ev], "S8"))
        g.create_dataset("event_freq_hz", data=np.array([e[2] for e in ev], float))
        g.create_dataset("event_power_db", data=np.array([e[3] for e in ev], float))
        attrs = {"dc_removal": self.dc_removal, "dc_hz": self.dc_hz,
                 "tone_detection": bool(self.cfg.tone_detection),
                 "tone_excision": bool(self.cfg.tone_excision), "fft_size": d.fft_size,
                 "segments": d.segments, "bin_hz": d.bin_hz, "threshold_db": d.threshold_db,
                 "pfa": self.cfg.pfa, "noise_power": d.noise_power, "dc_i": d.dc.real, "dc_q": d.dc.imag,
                 "notch_bw_hz": self.cfg.notch_bw_hz, "pulse_blanking": bool(self.cfg.pulse_blanking),
                 "blank_level": self.blank_level, "blanked_samples": self.blanked,
                 "processed_samples": self.processed, "monitor_ms": float(self.cfg.monitor_ms),
                 "monitor_checks": self.checks, "pulse_detection": self._pdet,
                 "blanked_fraction": self.blanked_fraction}
        te = self.tf_events
        g.create_dataset("tf_event_time_s", data=np.array([e[0] / self._reader.fs for e in te], float))
        g.create_dataset("tf_event_kind", data=np.array([e[1] for e in te], "S8"))
        g.attrs["tf_excision"] = self._tf
        g.attrs["tf_frame"] = self._tf_n
        pe = self.pulse_events
        g.create_dataset("pulse_event_time_s", data=np.array([e[0] / self._reader.fs for e in pe], float))
        g.create_dataset("pulse_event_kind", data=np.array([e[1] for e in pe], "S8"))
        g.create_dataset("pulse_event_floor", data=np.array([e[2] for e in pe], float))
        for k, v in attrs.items():
            g.attrs[k] = v
