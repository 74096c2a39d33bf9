"""Ionospheric scintillation: Cornell scintillation model (CSM) amplitude plus phase scintillation.

Model (Humphreys et al., "Simulating ionosphere-induced scintillation for testing GPS receiver phase
tracking loops", 2009): the complex channel gain is z = g (1 + a xi), a Rician process: a unit direct
component plus a diffuse zero-mean complex Gaussian xi.  xi is complex white noise shaped by a 2nd-order
Butterworth low-pass whose power spectrum is 1 / (1 + (f/fc)^4), fc = sqrt(2) beta0 / (2 pi tau0),
beta0 = 1.2396464; with it the autocorrelation of xi falls to 1/e at the decorrelation time tau0.  The
Rician K = 1/a^2 follows from S4: S4^2 = (1 + 2K)/(1 + K)^2, and g normalises the mean power E|z|^2 to 1.

  amplitude   |z|                    (the signal amplitude is multiplied by it)
  phase       b * Im(xi)             (the CSM phase in its small-angle form, scaled to the target sigma_phi;
                                      it shares xi's spectrum and decorrelation time)

So that the generated series meet their targets (S4 = std(I)/mean(I) with I = |z|^2, and std(phase) =
sigma_phi) over every analysis window (default 60 s, aligned with the start) rather than only on average,
the factors are fitted to the realisation window by window (a by bisection; a window whose diffuse part
cannot reach the S4 target is drawn again from the same filter state), and the direct and diffuse
amplitudes (g, g a) and b are blended linearly over a short ramp (min(2 s, window/10)) around window
boundaries so that amplitude and phase stay continuous.

The series is streamed on the simulator's 1 ms grid: :meth:`Scintillation.take` returns the next samples,
generating one window ahead.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, sosfilt, sosfilt_zi

BETA0 = 1.23964643681047


def rician_k(s4: float) -> float:
    """Rician K factor (direct / diffuse power) of a given S4 (0 < S4 < 1)."""
    r = math.sqrt(1.0 - s4 * s4)
    return r / (1.0 - r)


def s4_index(intensity) -> float:
    """S4 = std(I) / mean(I)."""
    i = np.asarray(intensity, dtype=float)
    return float(np.std(i) / np.mean(i))


def sigma_phi(phase_rad) -> float:
    """Phase scintillation index sigma_phi: standard deviation of a phase series (rad)."""
    return float(np.std(np.asarray(phase_rad, dtype=float)))


def butterworth_cutoff_hz(tau0_s: float) -> float:
    """Cut-off frequency (Hz) of the 2nd-order Butterworth shaping filter for decorrelation time tau0 (s)."""
    return math.sqrt(2.0) * BETA0 / (2.0 * math.pi * tau0_s)


def _s4_of(xi, a):
    z = 1.0 + a * xi
    return s4_index(z.real ** 2 + z.imag ** 2)


def _fit_diffuse_scale(xi, s4_target):
    """Scale a of the diffuse part with S4(|1 + a xi|^2) = target (bisection; S4 grows with a)."""
    if s4_target <= 0:
        return 0.0
    lo, hi = 0.0, 1.0 / math.sqrt(rician_k(min(s4_target, 0.999)))
    for _ in range(12):
        if _s4_of(xi, hi) >= s4_target:
            break
        lo, hi = hi, hi * 2.0
    else:
        return math.inf                 # out of reach for this realisation: pure diffuse is closest
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if _s4_of(xi, mid) < s4_target:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-6 * hi:
            break
    return 0.5 * (lo + hi)


class Scintillation:
    """Streamed CSM amplitude / phase scintillation for one satellite, sampled every ``dt`` seconds."""

    def __init__(self, s4: float, sigma_phi_rad: float, tau0_s: float, dt: float, rng: np.random.Generator,
                 window_s: float = 60.0):
        if not 0.0 <= s4 < 1.0:
            raise ValueError("S4 must be in [0, 1)")
        self.s4, self.sigma_phi, self.tau0, self.dt = float(s4), float(sigma_phi_rad), float(tau0_s), float(dt)
        self.rng = rng
        self.window = max(int(round(window_s / dt)), 10)
        self.ramp = max(min(int(round(2.0 / dt)), self.window // 10), 2)
        fc = butterworth_cutoff_hz(self.tau0)
        self.sos = butter(2, min(fc, 0.45 / dt), fs=1.0 / dt, output="sos")
        # unit-power diffuse component: scale by the filter's noise gain (energy of its impulse response)
        imp = np.zeros(max(int(40.0 * self.tau0 / dt), 1000))
        imp[0] = 1.0
        self._gain = 1.0 / math.sqrt(2.0 * np.sum(sosfilt(self.sos, imp) ** 2))
        # start in steady state: run the filter over a warm-up of ~10 tau0
        self._zr = np.zeros_like(sosfilt_zi(self.sos))
        self._zi = self._zr.copy()
        self._filter(max(int(10.0 * self.tau0 / dt), 100))
        self._windows = []            # [(xi, factors)] generated, not yet fully emitted
        self._prev_factors = None
        self._buf = np.zeros(0, np.complex128)     # emitted-ready z samples (amplitude/phase packed below)
        self._buf_phase = np.zeros(0)

    def _filter(self, n):
        wr = self.rng.standard_normal(n)
        wi = self.rng.standard_normal(n)
        xr, self._zr = sosfilt(self.sos, wr, zi=self._zr)
        xi, self._zi = sosfilt(self.sos, wi, zi=self._zi)
        return (xr + 1j * xi) * self._gain

    def _new_window(self):
        # A finite window of a (near-)Rayleigh process may not reach a high S4 target at all (its
        # S4 at a -> infinity is the sample S4 of |xi|^2): then draw that window again from the same
        # filter state (a few tries), keeping the series continuous.
        state = (self._zr.copy(), self._zi.copy())
        for _ in range(20):
            xi = self._filter(self.window)
            if self.s4 <= 0 or s4_index(np.abs(xi) ** 2) > self.s4 * 1.02:
                break
            self._zr, self._zi = state[0].copy(), state[1].copy()
        a = _fit_diffuse_scale(xi, self.s4)
        # z = c_direct + c_diffuse * xi with unit mean power over the window
        if math.isinf(a):
            c_dir, c_dif = 0.0, 1.0 / math.sqrt(np.mean(np.abs(xi) ** 2))
        else:
            z = 1.0 + a * xi
            c_dir = 1.0 / math.sqrt(np.mean(z.real ** 2 + z.imag ** 2))
            c_dif = a * c_dir
        sd = np.std(xi.imag)
        b = self.sigma_phi / sd if sd > 0 else 0.0
        self._windows.append((xi, np.array([c_dir, c_dif, b])))

    def _finalize_first(self):
        """Turn the oldest generated window into output samples (needs the next window's factors)."""
        while len(self._windows) < 2:
            self._new_window()
        xi, f = self._windows[0]
        nxt = self._windows[1][1]
        prev = self._prev_factors if self._prev_factors is not None else f
        n, r = self.window, self.ramp
        j = np.arange(n)
        fac = np.tile(f, (n, 1))
        head = j < r // 2                     # blend from the previous window's factors
        lam = 0.5 + j[head] / r
        fac[head] = prev + lam[:, None] * (f - prev)
        tail = j >= n - r // 2                # blend towards the next window's factors
        lam = (j[tail] - (n - r // 2)) / r
        fac[tail] = f + lam[:, None] * (nxt - f)
        z = fac[:, 0] + fac[:, 1] * xi
        b = fac[:, 2]
        self._buf = np.concatenate([self._buf, z])
        self._buf_phase = np.concatenate([self._buf_phase, b * xi.imag])
        self._prev_factors = f
        self._windows.pop(0)

    def take(self, n: int):
        """Next n samples: (amplitude |z|, phase rad)."""
        while self._buf.size < n:
            self._finalize_first()
        z, ph = self._buf[:n], self._buf_phase[:n]
        self._buf, self._buf_phase = self._buf[n:], self._buf_phase[n:]
        return np.abs(z), ph
