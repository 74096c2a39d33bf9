"""Receiver clock: initial bias, oscillator frequency error and power-law (Allan variance) noise.

The receiver clock IS the sample counter: its reading at sample n is ``t0 + n / fs_nominal``.  The
oscillator's fractional frequency error y(T) (= clock drift, s/s) scales the sample clock and the local
oscillator together.  The clock is generated on a uniform grid of receiver time (step ``dt``, 1 ms in the
simulator): y_k is the (constant) fractional frequency error over [T_k, T_k+1), and the bias
b = receiver clock reading - true GPS time obeys db/dT = y / (1 + y), so

    b_{k+1} = b_k + dt * y_k / (1 + y_k),     true time t_k = T_k - b_k.

Noise model, one-sided PSD of y:  S_y(f) = h0 + h_1 / f + h_2 / f^2  (white, flicker and random-walk
frequency modulation), with Allan variance  sigma_y^2(tau) = h0/(2 tau) + 2 ln2 h_1 + (2 pi^2/3) h_2 tau.
The textbook h-values describe clocks over tau >~ 0.1 s; a real crystal's frequency noise falls off at
Fourier frequencies above a few Hz (its phase noise flattens to white/flicker PM), whereas white FM carried
up to the 500 Hz Nyquist frequency of the 1 ms grid would add tens of dB of unrealistic phase noise at
tracking-loop frequencies.  So white FM is band-limited by default: S_y = h0 / (1 + (f/fc)^2) with
fc = ``white_fm_corner_hz`` (1 Hz; None: unfiltered), which changes the Allan variance only for
tau <~ 1/fc (closed form in :func:`allan_variance_theory`).
  white FM:  y_k i.i.d. with variance h0 / (2 dt) (unfiltered), or the AR(1) process
             x_k = a x_{k-1} + w_k, a = exp(-2 pi fc dt), var(w) = h0 (1 - a)^2 / (2 dt) (band-limited)
  flicker:   sum of first-order Gauss-Markov processes with corner frequencies spaced 3 per decade from
             0.1/duration to 1/(2 dt), each with variance h_1 ln(r) (r = corner spacing ratio), which has
             S_y ~= h_1/f between the outer corners
  RW FM:     y random walk with increments of variance 2 pi^2 h_2 dt
Generation is streamed: :meth:`ClockGenerator.take` returns the next grid points and keeps its state.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from ..gnss.clock import OSCILLATORS

#: (h0, h_1, h_2) of the scenario's ``clock.noise`` presets (the oscillator table of receiver.gnss.clock)
CLOCK_PRESETS = {
    "none": (0.0, 0.0, 0.0),
    "tcxo": OSCILLATORS["tcxo"],
    "ocxo": OSCILLATORS["ocxo"],
}


def allan_variance_theory(tau, h0, h_1, h_2, white_fm_corner_hz=None):
    """Theoretical Allan variance of y for the power-law model above.

    With a white-FM corner fc the white term is that of a Gauss-Markov frequency noise (variance
    s2 = pi fc h0 / 2, correlation time tc = 1 / (2 pi fc)):
    s2 tc^2 / tau^2 (2 tau/tc - 3 + 4 exp(-tau/tc) - exp(-2 tau/tc)), -> h0 / (2 tau) for tau >> tc.
    """
    tau = np.asarray(tau, dtype=float)
    if white_fm_corner_hz:
        tc = 1.0 / (2.0 * math.pi * white_fm_corner_hz)
        s2 = math.pi * white_fm_corner_hz * h0 / 2.0
        r = tau / tc
        white = s2 / r ** 2 * (2.0 * r - 3.0 + 4.0 * np.exp(-r) - np.exp(-2.0 * r))
    else:
        white = h0 / (2.0 * tau)
    return white + 2.0 * math.log(2.0) * h_1 + (2.0 * math.pi ** 2 / 3.0) * h_2 * tau


def allan_deviation(phase_s, dt, m_list):
    """Overlapping Allan deviation from time-error (phase) samples x_k spaced dt: tau = m dt."""
    x = np.asarray(phase_s, dtype=float)
    out = []
    for m in m_list:
        d = x[2 * m:] - 2.0 * x[m:-m] + x[:-2 * m]
        out.append(math.sqrt(np.mean(d * d) / (2.0 * (m * dt) ** 2)))
    return np.array(out)


class ClockGenerator:
    """Streamed receiver clock on a grid of receiver time.

    take(n) -> (bias_s[n], drift[n]) for the next n grid points (the first call starts at T = t0 with
    bias_s = bias0).  drift[k] is y over the interval starting at that grid point.
    """

    def __init__(self, bias_s: float, freq_error: float, h0: float, h_1: float, h_2: float,
                 dt: float, duration_s: float, rng: np.random.Generator, aging_per_s: float = 0.0,
                 white_fm_corner_hz: float | None = 1.0):
        self.dt = float(dt)
        fc = white_fm_corner_hz
        self._wa = math.exp(-2.0 * math.pi * fc * self.dt) if fc else 0.0
        self._wq = math.sqrt(h0 * (1.0 - self._wa) ** 2 / (2.0 * self.dt))
        # start the band-limited white FM in its stationary state
        self._wx = rng.standard_normal() * self._wq / math.sqrt(1.0 - self._wa ** 2) if fc else 0.0
        self.freq_error = float(freq_error)
        self.aging = float(aging_per_s)
        self.h0, self.h_1, self.h_2 = float(h0), float(h_1), float(h_2)
        self.rng = rng
        self._bias = float(bias_s)
        self._k = 0
        self._rw = 0.0
        # flicker FM: bank of AR(1) processes
        self._fl_a = np.zeros(0)
        self._fl_x = np.zeros(0)
        self._fl_q = np.zeros(0)
        if self.h_1 > 0:
            f_lo = 0.1 / max(duration_s, 10.0 * dt)
            f_hi = 0.5 / dt
            per_decade = 3
            n = max(int(math.ceil(per_decade * math.log10(f_hi / f_lo))), 1)
            corners = f_lo * (f_hi / f_lo) ** (np.arange(n + 1) / n)
            ratio = (f_hi / f_lo) ** (1.0 / n)
            var = self.h_1 * math.log(ratio)
            self._fl_a = np.exp(-2.0 * math.pi * corners * self.dt)
            self._fl_q = np.sqrt(var * (1.0 - self._fl_a ** 2))
            self._fl_x0 = rng.standard_normal(corners.size) * math.sqrt(var)   # stationary start
            self._fl_x = self._fl_x0.copy()
            self._fl_offset = float(np.sum(self._fl_x0))      # removed so that y(0) = freq_error
        else:
            self._fl_offset = 0.0

    def _noise(self, n):
        y = np.zeros(n)
        if self.h0 > 0:
            w = self.rng.standard_normal(n) * self._wq
            if self._wa > 0:
                w, _ = lfilter([1.0], [1.0, -self._wa], w, zi=[self._wa * self._wx])
                self._wx = float(w[-1])
            y += w
        if self.h_2 > 0:
            steps = self.rng.standard_normal(n) * math.sqrt(2.0 * math.pi ** 2 * self.h_2 * self.dt)
            if self._k == 0:
                steps[0] = 0.0                     # the random walk starts at 0
            rw = self._rw + np.cumsum(steps)
            self._rw = float(rw[-1])
            y += rw
        for i in range(self._fl_a.size):
            a = self._fl_a[i]
            w = self.rng.standard_normal(n) * self._fl_q[i]
            x, _ = lfilter([1.0], [1.0, -a], w, zi=[a * self._fl_x[i]])
            self._fl_x[i] = x[-1]
            y += x
        if self._fl_a.size:
            y -= self._fl_offset
        return y

    def take(self, n: int):
        """Bias (s) and fractional frequency error at the next n grid points."""
        k = self._k + np.arange(n)
        y = self.freq_error + self.aging * k * self.dt + self._noise(n)
        steps = self.dt * y / (1.0 + y)
        bias = self._bias + np.concatenate(([0.0], np.cumsum(steps[:-1])))
        self._bias = float(bias[-1] + steps[-1])
        self._k += n
        return bias, y
