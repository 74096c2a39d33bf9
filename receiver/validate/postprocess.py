"""Noiseless GPS-SDR-SIM output (int16 I/Q) -> a realistic recording, streamed in blocks.

The impairments mapping (every key optional)::

    cn0_dbhz: 45            C/N0 of every satellite (GPS-SDR-SIM with -p 128: equal powers), set by the
                            white noise added at the output rate: complex outputs  C/N0 = P fs / (2 s^2),
                            real IF outputs  C/N0 = P fs / (4 s_r^2) ... see ``noise_sigma``
    osc_ppm: 0              oscillator error (one reference for LO and ADC): the file's true sample rate is
                            fs (1 + e) (resampled by a windowed-sinc interpolator) and every carrier moves by
                            -e * 1575.42 MHz
    lo_offset_hz: 0         an extra carrier offset (LO alone)
    format: int8_iq         int8_iq, uint8_iq, int16_iq, int8_real, int16_real (real: the sampling rate is
                            doubled, IF = simulator rate / 2)
    bits: null              ADC bits 1..8 with an AGC on each block's total power (MSE-optimal step of a
                            Gaussian input, receiver/sim/impairments.py); null: 8 for 8-bit formats, for
                            int16 the AGC scales each block's RMS to 1000 LSB
    filter: {bandwidth_hz: null, order: 4}     Butterworth low-pass (two-sided bandwidth) of the baseband
    iq_imbalance: {gain_db: 0, phase_deg: 0}   Q branch gain and phase error (complex formats)
    dc: [0, 0]              DC offset (I, Q) in units of the noise sigma, after the filter
    outages: [{start_s, end_s, atten_db: inf, dropout: false}]  signal attenuated (inf: removed) in
                            [start, end) of true time; dropout: the front end delivers zeros there (no noise,
                            no interference either: a dead front end / lost USB transfers)
                            time; the noise and interference stay
    interference: [{kind: cw | swept | pulsed, freq_hz, power_db, start_s: 0, end_s: inf,
                    sweep_hz (swept: +/- span), period_s (swept / pulsed), duty (pulsed)}]
                            power over the noise of the sampled band; freq_hz from the L1 carrier
    seed: 0                 the noise stream (nothing else is random)
    whole_ms: true          cut the file to a whole number of milliseconds of samples (false: the length
                            the oscillator error gives, e.g. 12 s + 6 samples)

Output sample n sits at true time n / (fs_out (1 + e)); the first at the scenario's start (GPS-SDR-SIM's
first sample).  Memory is bounded by the block (0.1 s of the simulator's samples).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit
from scipy.signal import butter, sosfilt

from ..sim.impairments import _STEP_SIGMA
from ..source.io import quantize
from .gpssdrsim import SAT_POWER

F_L1 = 1575.42e6
FORMATS = ("int8_iq", "uint8_iq", "int16_iq", "int8_real", "int16_real")
_HALF = 8                      # interpolator half-width (taps 2 * _HALF)
_PHASES = 4096


def _kernel_table():
    u = np.arange(-_HALF + 1, _HALF + 1)[None, :] - (np.arange(_PHASES + 1) / _PHASES)[:, None]
    w = np.kaiser(2 * _HALF * 64 + 1, 8.0)
    wi = np.interp(u, np.linspace(-_HALF, _HALF, w.size), w)
    h = np.sinc(u) * wi
    return (h / h.sum(axis=1, keepdims=True)).astype(np.float64)


_TABLE = _kernel_table()


@njit(cache=True)
def _resample(x, base, pos0, step, n_out, table, out):
    """out[m] = x interpolated at input index pos0 + m*step (global index; x[0] is global ``base``)."""
    nph = table.shape[0] - 1
    for m in range(n_out):
        p = pos0 + m * step - base
        i = int(math.floor(p))
        ph = int((p - i) * nph + 0.5)
        acc_r = 0.0
        acc_i = 0.0
        for k in range(2 * 8):
            j = i - 8 + 1 + k
            w = table[ph, k]
            acc_r += w * x[j].real
            acc_i += w * x[j].imag
        out[m] = complex(acc_r, acc_i)


def real_format(fmt: str) -> bool:
    """True for the real-IF output formats."""
    return fmt.endswith("_real")


def noise_sigma(cn0_dbhz: float, fs_out: float, real: bool, power: float = SAT_POWER) -> float:
    """Per-component sigma of the complex white noise added at the output rate for a C/N0."""
    c = 10 ** (cn0_dbhz / 10.0)
    return math.sqrt(power * fs_out / ((4.0 if real else 2.0) * c))


class _Interferer:
    """One interferer; times and frequencies on the file's time axis (sample n at n / fs)."""

    def __init__(self, d, noise_power):
        self.kind = d.get("kind", "cw")
        if self.kind not in ("cw", "swept", "pulsed"):
            raise ValueError(f"unknown interference kind '{self.kind}'")
        self.f = float(d.get("freq_hz", 0.0))
        self.amp = math.sqrt(noise_power * 10 ** (float(d["power_db"]) / 10.0))
        self.t0, self.t1 = float(d.get("start_s", 0.0)), float(d.get("end_s", math.inf))
        self.span = float(d.get("sweep_hz", 0.0))
        self.period = float(d.get("period_s", 1e-3 if self.kind == "pulsed" else 0.01))
        self.duty = float(d.get("duty", 0.1))
        self.cycles = 0.0           # phase accumulated up to the block (swept)

    def add(self, y, t, dt):
        on = (t >= self.t0) & (t < self.t1)
        if self.kind == "pulsed":
            on &= np.mod(t - self.t0, self.period) < self.duty * self.period
        if self.kind == "swept":        # triangle sweep f +/- span, phase continuous across blocks
            tri = 2.0 * np.abs(2.0 * np.mod(t / self.period, 1.0) - 1.0) - 1.0
            ph = self.cycles + np.cumsum(self.f + self.span * tri) * dt
            self.cycles = float(np.mod(ph[-1], 1.0))
        else:
            ph = self.f * t
        if np.any(on):
            y[on] += self.amp * np.exp(2j * np.pi * np.mod(ph[on], 1.0))


def _outage_gain(t, outages):
    g = np.ones(t.size)
    for o in outages or []:
        a, b = float(o["start_s"]), float(o["end_s"])
        att = float(o.get("atten_db", math.inf))
        sel = (t >= a) & (t < b)
        g[sel] = 0.0 if math.isinf(att) else 10 ** (-att / 20.0)
    return g


class _Chain:
    """The per-output-sample impairments (after the resampler), state carried across blocks."""

    def __init__(self, imp, fs_sim):
        self.fmt = imp.get("format", "int8_iq")
        if self.fmt not in FORMATS:
            raise ValueError(f"unknown format '{self.fmt}' (one of {', '.join(FORMATS)})")
        self.real = real_format(self.fmt)
        self.up = 2 if self.real else 1
        self.fs = fs_sim * self.up
        self.if_hz = fs_sim / 2.0 if self.real else 0.0
        self.eps = float(imp.get("osc_ppm", 0.0)) * 1e-6
        # carrier offset in the file's time: LO error of the shared reference, plus any extra
        self.lo_hz = -self.eps * F_L1 / (1.0 + self.eps) + float(imp.get("lo_offset_hz", 0.0))
        self.sigma = noise_sigma(float(imp.get("cn0_dbhz", 45.0)), self.fs, self.real)
        noise_power = (1.0 if self.real else 2.0) * self.sigma ** 2
        self.itf = [_Interferer(d, noise_power) for d in imp.get("interference") or []]
        self.rng = np.random.default_rng(int(imp.get("seed", 0)))
        filt = imp.get("filter") or {}
        self.sos = self.zi = None
        if filt.get("bandwidth_hz"):
            self.sos = butter(int(filt.get("order", 4)), float(filt["bandwidth_hz"]) / 2, fs=self.fs,
                              output="sos")
            self.zi = np.zeros((self.sos.shape[0], 2), np.complex128)
        iq = imp.get("iq_imbalance") or {}
        self.iq_g = 10 ** (float(iq.get("gain_db", 0.0)) / 20.0)
        self.iq_ph = math.radians(float(iq.get("phase_deg", 0.0)))
        dc = imp.get("dc") or [0.0, 0.0]
        self.dc = complex(float(dc[0]), float(dc[1])) * self.sigma
        self.bits = imp.get("bits")
        if self.bits is not None and not 1 <= int(self.bits) <= 8:
            raise ValueError("bits must be 1 .. 8")
        if self.fmt == "uint8_iq" and self.bits not in (None, 8):
            raise ValueError("uint8_iq is an 8-bit format (bits: 8)")
        self.dropouts = [(float(o["start_s"]), float(o["end_s"])) for o in imp.get("outages") or []
                         if o.get("dropout")]

    def apply(self, y, n0):
        n, fs = y.size, self.fs
        k = n0 + np.arange(n)
        if self.lo_hz:
            y *= np.exp(2j * np.pi * np.mod(self.lo_hz / fs * k, 1.0))
        y += self.sigma * (self.rng.standard_normal(n) + 1j * self.rng.standard_normal(n))
        for itf in self.itf:
            itf.add(y, k / fs, 1.0 / fs)
        if self.sos is not None:
            y, self.zi = sosfilt(self.sos, y, zi=self.zi)
        if self.real:
            y = np.real(y * np.exp(2j * np.pi * np.mod(self.if_hz / fs * k, 1.0)))
        elif self.iq_g != 1.0 or self.iq_ph:
            y = y.real + 1j * (self.iq_g * (y.imag * math.cos(self.iq_ph) + y.real * math.sin(self.iq_ph)))
        if self.dc:
            y = y + (self.dc.real if self.real else self.dc)
        raw = _quantize(y, self.fmt, self.bits, self.real, self.sigma)
        if self.dropouts:
            t = k / (fs * (1.0 + self.eps))
            dead = np.zeros(n, bool)
            for a, b in self.dropouts:
                dead |= (t >= a) & (t < b)
            if dead.any():
                dead = dead if self.real else np.repeat(dead, 2)
                raw[dead] = 128 if self.fmt == "uint8_iq" else 0
        return raw


def process(src, dst, fs_sim: float, imp: dict, block_s: float = 0.1) -> dict:
    """Write the recording ``dst`` from the simulator's noiseless int16 I/Q file ``src`` (complex at
    ``fs_sim``).  Returns the receiver's input keys (format, sample_rate_hz, if_hz) and n_samples."""
    ch = _Chain(imp, fs_sim)
    step = 1.0 / (ch.up * (1.0 + ch.eps))          # simulator samples per output sample
    outages = imp.get("outages") or []
    total = Path(src).stat().st_size // 4
    nblk = int(round(fs_sim * block_s))
    hist = np.zeros(_HALF, np.complex128)          # zeros before the first sample
    base = -_HALF                                  # global simulator index of hist[0]
    n_done = 0                                     # output samples written
    n_total = int(math.floor((total - 1) / step)) + 1
    ms = ch.fs / 1000.0
    if imp.get("whole_ms", True) and abs(ms - round(ms)) < 1e-9:
        n_total -= n_total % int(round(ms))         # a whole number of milliseconds (see the docstring)
    with open(src, "rb") as fi, open(dst, "wb") as fo:
        a = 0
        while n_done < n_total:
            raw = np.fromfile(fi, np.int16, count=2 * nblk)
            x = raw[0::2].astype(np.float64) + 1j * raw[1::2].astype(np.float64)
            if outages and x.size:
                x *= _outage_gain((a + np.arange(x.size)) / fs_sim, outages)
            a += x.size
            last = a >= total
            buf = np.concatenate([hist, x] + ([np.zeros(_HALF + 1, np.complex128)] if last else []))
            # output m needs the taps up to floor(m step) + _HALF inside buf
            lim = int(math.ceil((base + buf.size - _HALF - 1) / step))
            n_new = min(lim, n_total) - n_done
            if n_new > 0:
                if ch.up == 1 and ch.eps == 0.0:
                    i0 = n_done - base
                    y = buf[i0:i0 + n_new].copy()
                else:
                    y = np.empty(n_new, np.complex128)
                    _resample(buf, base, n_done * step, step, n_new, _TABLE, y)
                fo.write(ch.apply(y, n_done).tobytes())
                n_done += n_new
            if last:
                break
            keep = max(int(math.floor(n_done * step)) - _HALF - base, 0)
            hist = buf[keep:]
            base += keep
    return {"format": ch.fmt, "sample_rate_hz": ch.fs, "if_hz": ch.if_hz, "n_samples": n_done}


def _quantize(y, fmt, bits, real, sigma):
    comps = [y.real] if real else [y.real, y.imag]
    out = []
    for c in comps:
        rms = math.sqrt(float(np.mean(c * c))) or 1.0
        if fmt.startswith("int16") and not bits:
            out.append(np.rint(c * (1000.0 / rms)))       # AGC: 1000 LSB RMS, 30 dB of headroom
            continue
        b = int(bits or 8)
        if b == 1:
            q = np.where(c >= 0, 1.0, -1.0)
        elif fmt.startswith("uint8") or b < 8:
            st = _STEP_SIGMA[b] * rms if b > 1 else 1.0
            top = 2 ** b - 1
            q = np.clip(2 * np.floor(c / st) + 1, -top, top)
            if fmt.startswith("uint8"):
                q = q * 2.0 ** (7 - b)       # levels +/-0.5 .. +/-127.5 at 8 bits (value = u - 127.5)
        else:
            q = np.clip(np.rint(c / (_STEP_SIGMA[8] * rms)), -128, 127)
        out.append(q)
    z = out[0] if real else out[0] + 1j * out[1]
    return quantize(z, fmt)
