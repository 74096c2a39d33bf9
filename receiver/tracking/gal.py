"""Galileo E1 tracking channel (``gal_e1``): PLL on the E1-C pilot with CS25 wiped off, carrier-aided DLL on
the pilot's BOC(1,1) replica, E1-B prompt for the I/NAV symbols; one epoch per 4-ms code period.

This is a channel of its own, not a variant of the 1-ms tracking kernel (receiver/tracking/kernel.py), which
is built around 1-ms code periods and 20-ms bit synchronisation: it is what the Galileo-only acceptance run
(scripts/bench/accuracy_galileo.py) uses until the scalar tracking framework handles 4-ms codes.

Start (:func:`receiver.acquisition.galileo.refine_pilot`): the acquisition's code phase, the Doppler refined over
100 ms of pilot periods and the CS25 phase (which of the 25 chips the first period carries) found at the same
time; the secondary code is then known for every later period, so the pilot is a pure carrier and the PLL uses
the four-quadrant arctangent (no data, no 180-degree ambiguity beyond the pilot's own sign).

Per epoch: early / prompt / late correlations of E1-C (spacing ``dll_spacing`` chips early-to-late) and the
E1-B prompt, the carrier wiped by the NCO.  BOC(1,1) near the peak: R(tau) = 1 - 3|tau| (chips), so with
early-minus-late spacing d the envelope discriminator (|E| - |L|) / (|E| + |L|) x (2 - 3d) / 6 is the code
error in chips while |tau| < d / 2 (the side peaks at +/-1/2 chip are outside; acquisition made sure of the
main peak).  Numba correlates the samples; the loop filters run per epoch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..gnss.gal_codes import (E1_CHIP_RATE, E1_CODE_LEN, E1_HZ, boc11, cs25_signs, e1b_code, e1c_code)


@njit(cache=True, nogil=True)
def _wrap(i, n):
    """Index ``i`` brought into 0 .. n-1 by whole periods ``n`` (usually no step: the loop's indices stay
    within one period of the range)."""
    while i >= n:
        i -= n
    while i < 0:
        i += n
    return i


@njit(cache=True, nogil=True)
def _correlate_block(x, start, n, code_phase, code_step, carr_phase, carr_step, rep_c, rep_b, half_d):
    """E, P, L of the E1-C replica and P of the E1-B replica over samples start .. start+n-1 of the complex
    block x: the carrier NCO starts at carr_phase (cycles) and advances carr_step cycles per sample, the code
    at code_phase (chips) by code_step chips per sample; replicas are BOC(1,1) half-chips (8184).

    The carrier replica is a unit phasor rotated by one sample's phase step per sample and set again from the
    exact phase every 256 samples (rounding stays ~1e-13); replica indices are floor(2 x code phase) modulo the
    replica length, computed on a phase shifted by whole periods to be positive (so truncation is floor)."""
    er = ei = pr = pi = lr = li = br = bi = 0.0
    nrep = rep_c.size
    two_pi = 2.0 * math.pi
    dr = math.cos(two_pi * carr_step)
    di = -math.sin(two_pi * carr_step)
    cp0 = (2.0 * code_phase) % nrep + nrep                  # half-chips, nrep .. 2 nrep
    step2 = 2.0 * code_step
    d2 = 2.0 * half_d
    k0 = 0
    while k0 < n:
        k1 = min(n, k0 + 256)
        ph = two_pi * (carr_phase + k0 * carr_step)
        wr = math.cos(ph)
        wi = -math.sin(ph)
        for k in range(k0, k1):
            v = x[start + k]
            xr = float(v.real)
            xi = float(v.imag)
            yr = xr * wr - xi * wi                                  # the sample times exp(-j carrier phase)
            yi = xi * wr + xr * wi
            t = wr * dr - wi * di
            wi = wr * di + wi * dr
            wr = t
            cp = cp0 + k * step2
            ip = _wrap(int(cp), nrep)
            ie = _wrap(int(cp + d2), nrep)
            il = _wrap(int(cp - d2), nrep)
            vc = rep_c[ip]
            pr += yr * vc
            pi += yi * vc
            ve = rep_c[ie]
            er += yr * ve
            ei += yi * ve
            vl = rep_c[il]
            lr += yr * vl
            li += yi * vl
            vb = rep_b[ip]
            br += yr * vb
            bi += yi * vb
        k0 = k1
    return complex(er, ei), complex(pr, pi), complex(lr, li), complex(br, bi)


@dataclass
class GalEpochs:
    """Per 4-ms epoch of one channel: first sample, replica code phase there (chips, ~0: epochs start at code
    period boundaries), period count since the channel start (the first epoch is period ``first_period`` of
    the acquisition block), E1-B and E1-C prompts, carrier NCO frequency (Hz, IF included), C/N0 estimate of
    the whole E1 signal (E1-B + E1-C, :meth:`GalChannel._cn0_update`), accumulated carrier phase (for carrier
    smoothing)."""
    sample: np.ndarray
    code_phase: np.ndarray
    period: np.ndarray
    prompt_b: np.ndarray
    prompt_c: np.ndarray
    carr_hz: np.ndarray
    cn0_dbhz: np.ndarray
    carr_cycles: np.ndarray      # accumulated carrier NCO phase at the epoch start (cycles, IF included)


class GalChannel:
    """One Galileo E1 channel.  ``run(x, n_epochs)`` tracks n epochs of the interleaved I/Q samples ``x``
    (e.g. an int8 memmap of the whole recording; sample indices count complex samples) and returns
    :class:`GalEpochs`."""

    def __init__(self, prn: int, fs: float, if_hz: float, sample: int, code_phase_chips: float, doppler_hz: float,
                 cs25_offset: int, pll_bw_hz: float = 15.0, dll_bw_hz: float = 8.0, dll_spacing: float = 0.2):
        self.prn = int(prn)
        self.fs, self.if_hz = float(fs), float(if_hz)
        code_phase_chips, doppler_hz = float(code_phase_chips), float(doppler_hz)
        self.rep_c = boc11(e1c_code(prn)).astype(np.float32)
        self.rep_b = boc11(e1b_code(prn)).astype(np.float32)
        self.cs25 = cs25_signs()
        self.d = float(dll_spacing)
        self.k_dll = 4.0 * dll_bw_hz
        wn = pll_bw_hz / 0.53                               # 2nd order, zeta = 0.707 (Bn = 0.53 wn)
        self.pll_a, self.pll_b = 2.0 * 0.707 * wn, wn * wn
        # the first epoch starts at the next code period boundary after `sample`
        rate = E1_CHIP_RATE * (1.0 + doppler_hz / E1_HZ)
        step = rate / fs
        n_to = math.ceil((E1_CODE_LEN - code_phase_chips) / step - 1e-9)
        self.next_sample = int(sample + n_to)
        self.code_phase = code_phase_chips + n_to * step - E1_CODE_LEN
        self.dll_rate = 0.0
        self.freq_int = self.if_hz + doppler_hz             # PLL integrator (Hz)
        self.carr_hz = self.freq_int
        self.carr_phase = 0.0
        self.carr_cycles = 0.0                              # accumulated NCO phase (cycles)
        self.period = 1                                     # periods after the acquisition block's first
        self.cs25_offset = int(cs25_offset)
        self._m = None                                      # low-passed |P_C|^2, |P_C|^4, |P_B|^2, |P_B|^4

    def _epoch_length(self):
        """(samples, code step chips/sample) of the next epoch: up to the next code-period boundary."""
        rate = E1_CHIP_RATE * (1.0 + (self.carr_hz - self.if_hz) / E1_HZ) + self.dll_rate
        step = rate / self.fs
        return int(math.ceil((E1_CODE_LEN - self.code_phase) / step - 1e-9)), step

    def _cn0_update(self, p, b, T) -> float:
        """C/N0 (dB-Hz) of the whole E1 signal -- E1-B plus E1-C, the power the simulator's and the ICD's C/N0
        refer to -- from this epoch's pilot and data prompts (low-passed over ~20 epochs).  Moments estimator
        (M2M4) per component: with S the signal power and N the noise power of a prompt, E|P|^2 = S + N and
        E|P|^4 = S^2 + 4 S N + 2 N^2, so S = sqrt(2 M2^2 - M4); it uses magnitudes only, so neither the PLL's
        phase jitter (the in-phase / quadrature ratio of the pilot read ~2.5 dB low with a TCXO at 15 Hz) nor
        the E1-B symbols bias it.  C/N0 = (S_C + S_B) / (N T), N the mean of the two noise powers."""
        pc = p.real * p.real + p.imag * p.imag
        pb = b.real * b.real + b.imag * b.imag
        if self._m is None:                                 # the first epoch: its own moments
            self._m = [pc, pc * pc, pb, pb * pb]
        m = self._m
        for k, pw in ((0, pc), (2, pb)):
            m[k] += 0.05 * (pw - m[k])
            m[k + 1] += 0.05 * (pw * pw - m[k + 1])
        s_c = math.sqrt(max(2.0 * m[0] * m[0] - m[1], 0.0))
        s_b = math.sqrt(max(2.0 * m[2] * m[2] - m[3], 0.0))
        noise = 0.5 * ((m[0] - s_c) + (m[2] - s_b))
        return 10.0 * math.log10(max((s_c + s_b) / max(noise, 1e-30 * max(m[0], 1e-30)), 1e-3) / T)

    def _update(self, e, p, l, b, n, step):
        """Loop filters of one epoch from its correlations (E, P, L of E1-C, P of E1-B; n samples): the
        epoch's values (sample, code phase, period, E1-B prompt, E1-C prompt with CS25 wiped, NCO Hz, C/N0,
        carrier cycles, |E|, |L|, carrier and code errors), the state advanced to the next epoch."""
        # (a Python float: the CS25 table is float32, and a float32 sign would make the correlations complex64,
        # the DLL rate float32 and, through it, the code rate and code phase float32 -- NumPy keeps float32 when
        # a Python float is added --: code rates rounded to 1/16 chip/s and code phases to 1/4096 chip, a code-rate
        # error the first-order DLL follows with a lag of its own per satellite, ~1 m at 2 Hz)
        s = float(self.cs25[(self.period + self.cs25_offset) % 25])
        p, e, l = p * s, e * s, l * s
        T = n / self.fs
        # PLL (the pilot: four-quadrant arctangent)
        err = math.atan2(p.imag, p.real) / (2.0 * math.pi)            # cycles
        self.freq_int += self.pll_b * T * err
        new_hz = self.freq_int + self.pll_a * err
        # carrier phase at the next epoch start (the NCO ran at carr_hz over this epoch)
        self.carr_phase = (self.carr_phase + self.carr_hz * T) % 1.0
        # DLL (envelope discriminator on the pilot)
        ae, al = abs(e), abs(l)
        tau = (ae - al) / max(ae + al, 1e-30) * (2.0 - 3.0 * self.d) / 6.0
        self.dll_rate = self.k_dll * tau
        row = (self.next_sample, self.code_phase, self.period, b, p, self.carr_hz, self._cn0_update(p, b, T),
               self.carr_cycles, ae, al, err, tau)
        self.carr_cycles += self.carr_hz * T
        self.code_phase = self.code_phase + n * step - E1_CODE_LEN
        self.next_sample += n
        self.period += 1
        self.carr_hz = new_hz
        return row

    def run(self, x, n_epochs: int) -> GalEpochs:
        """Track ``n_epochs`` 4-ms epochs of the samples ``x`` from the channel's current state; returns the
        epochs' records (sample index, code phase, code period, E1-B and E1-C prompts, Doppler, C/N0)."""
        rows = []
        for _ in range(n_epochs):
            n, step = self._epoch_length()
            if 2 * (self.next_sample + n) > len(x):
                break
            seg = x[2 * self.next_sample:2 * (self.next_sample + n)]      # interleaved I, Q (exact in float32)
            block = seg[0::2].astype(np.complex64) + 1j * seg[1::2].astype(np.float32)
            e, p, l, b = _correlate_block(block.astype(np.complex64), 0, n, self.code_phase, step,
                                          self.carr_phase, self.carr_hz / self.fs, self.rep_c, self.rep_b,
                                          0.5 * self.d)
            rows.append(self._update(e, p, l, b, n, step))
        col = list(zip(*rows)) if rows else [()] * 8
        return GalEpochs(np.array(col[0], np.int64), np.array(col[1], float), np.array(col[2], np.int64),
                         np.array(col[3], np.complex128), np.array(col[4], np.complex128),
                         np.array(col[5], float), np.array(col[6], float), np.array(col[7], float))
