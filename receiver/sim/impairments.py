"""Front-end impairments of the simulator (scenario section ``impairments``), applied to each block of
samples after the satellites' signals and the thermal noise are summed and before the file is written:

1. CW tones (``tones``: list of {freq_hz, power_db, phase_deg}); ``freq_hz`` is the offset from the
   nominal carrier (the tone sits at if_hz + freq_hz in the sampled band), ``power_db`` its power over
   the thermal-noise power of the sampled band (2 sigma^2 complex, sigma^2 real formats).  Phase
   continuous across blocks (computed from the absolute sample index).
2. Band-limiting filter (``filter.bandwidth_hz``, ``filter.order``): a Butterworth filter of that
   two-sided bandwidth centred on the IF (complex formats: low-pass after mixing the IF to 0; real
   formats: band-pass), filter state carried from block to block.
3. DC offset (``dc_offset``: [I, Q] in units of the noise sigma) -- added after the filter, as an ADC's
   offset or LO leakage would be.
4. Quantisation (``quantization.bits``: 1, 2, 3, 4 ... 8) with an AGC on the total power: per block the
   RMS of each component (signals + noise + interference) sets the step to the step that minimises the
   mean-square error of a Gaussian input (Max, 1960).  b <= 7 bits: mid-rise levels +/-1, +/-3, ...
   +/-(2^b - 1); 8 bits: mid-tread -128..127.  The levels are what the file holds.

A very strong satellite is ``cn0.per_prn``.  Nothing here draws random numbers: the noise stream (and so
every other output) is unchanged by the impairments.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, sosfilt, sosfilt_zi

from ..errors import UserError
from ..suggest import check_list_item

# step / sigma minimising the MSE of a uniform quantiser with 2^b levels on a Gaussian input (Max 1960)
_STEP_SIGMA = {2: 0.9957, 3: 0.5860, 4: 0.3352, 5: 0.1881, 6: 0.1041, 7: 0.0569, 8: 0.0308}


def _tones(items):
    out = []
    for i, t in enumerate(items or []):
        key = f"impairments.tones[{i}]"
        check_list_item(t, key, ("freq_hz", "power_db"), ("freq_hz", "power_db", "phase_deg"), "freq_hz and power_db")
        try:
            out.append((float(t["freq_hz"]), float(t["power_db"]), float(t.get("phase_deg", 0.0))))
        except (TypeError, ValueError):
            raise UserError(f"config key '{key}' must hold numbers") from None
    return out


class Impairments:
    """The front-end impairments of one simulated stream (the module docstring), built from the scenario's
    ``impairments`` section for sample rate ``fs`` and IF ``if_hz`` (Hz), noise ``sigma`` per component and a
    complex or real format; a tone outside the sampled band, a bad dc_offset or filter band is a UserError.
    ``active`` is False when nothing is configured (:meth:`apply` then returns the block unchanged)."""

    def __init__(self, cfg, fs: float, if_hz: float, sigma: float, complex_fmt: bool):
        self.fs, self.if_hz, self.sigma, self.cplx = fs, if_hz, sigma, complex_fmt
        self.tones = _tones(cfg.tones)
        noise_power = (2.0 if complex_fmt else 1.0) * sigma ** 2
        for f, _, _ in self.tones:
            band = if_hz + f
            if (complex_fmt and abs(band) >= fs / 2) or (not complex_fmt and not 0 <= band < fs / 2):
                raise UserError(f"impairments.tones: {f:g} Hz (at {band:g} Hz in the band) is outside the "
                                "sampled band")
        # amplitudes: complex exp (power A^2) or real cosine (power A^2 / 2)
        self.tone_amp = [math.sqrt(noise_power * 10 ** (p / 10) * (1.0 if complex_fmt else 2.0))
                         for _, p, _ in self.tones]
        dc = cfg.dc_offset
        if len(dc) != 2:
            raise UserError("config key 'impairments.dc_offset' must hold 2 numbers (I, Q)")
        self.dc = complex(dc[0], dc[1]) * sigma
        self.sos, self.zi = None, None
        bw = cfg.filter.bandwidth_hz
        if bw is not None:
            if complex_fmt:
                if bw / 2 >= fs / 2:
                    raise UserError("config key 'impairments.filter.bandwidth_hz' must be below the sample rate")
                self.sos = butter(cfg.filter.order, bw / 2, fs=fs, output="sos")
            else:
                lo, hi = if_hz - bw / 2, if_hz + bw / 2
                if lo <= 0 or hi >= fs / 2:
                    raise UserError("config key 'impairments.filter.bandwidth_hz': the pass band "
                                    f"{lo:g}..{hi:g} Hz must lie within (0, sample_rate/2)")
                self.sos = butter(cfg.filter.order, [lo, hi], btype="bandpass", fs=fs, output="sos")
            self.zi = sosfilt_zi(self.sos)[:, :] * 0.0
            if complex_fmt:
                self.zi = self.zi.astype(np.complex128)
        self.bits = cfg.quantization.bits
        self.active = bool(self.tones or self.dc or self.sos is not None or self.bits)

    def apply(self, out: np.ndarray, first: int) -> np.ndarray:
        """Impair the complex64 block ``out`` whose first sample has file index ``first``."""
        if not self.active:
            return out
        n = out.size
        x = out.astype(np.complex128) if self.cplx else out.real.astype(np.float64)
        k = np.arange(n)
        for (f, _, ph), a in zip(self.tones, self.tone_amp):
            c = (self.if_hz + f) / self.fs
            phase = 2 * np.pi * (np.mod(c * first, 1.0) + c * k) + math.radians(ph)
            x += a * (np.exp(1j * phase) if self.cplx else np.cos(phase))
        if self.sos is not None:
            if self.cplx and self.if_hz:
                rot = np.exp(-2j * np.pi * (np.mod(self.if_hz / self.fs * first, 1.0)
                                            + self.if_hz / self.fs * k))
                y, self.zi = sosfilt(self.sos, x * rot, zi=self.zi)
                x = y * np.conj(rot)
            else:
                x, self.zi = sosfilt(self.sos, x, zi=self.zi)
        if self.dc:
            x = x + (self.dc if self.cplx else self.dc.real)
        if self.bits:
            x = self._quantize(x)
        res = np.empty(n, np.complex64)
        if self.cplx:
            res[:] = x
        else:
            res.real = x
            res.imag = 0.0
        return res

    def _quantize(self, x):
        b = self.bits
        comps = [x.real, x.imag] if self.cplx else [x]
        q = []
        for c in comps:
            rms = math.sqrt(float(np.mean(c ** 2))) or 1.0           # the AGC: total power of this block
            if b == 1:
                q.append(np.where(c >= 0, 1.0, -1.0))
            elif b < 8:
                top = 2 ** b - 1
                q.append(np.clip(2 * np.floor(c / (_STEP_SIGMA[b] * rms)) + 1, -top, top))
            else:
                q.append(np.clip(np.rint(c / (_STEP_SIGMA[8] * rms)), -128, 127))
        return q[0] + 1j * q[1] if self.cplx else q[0]
