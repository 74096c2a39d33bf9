"""kf / adaptive_kf: Kalman-filter PLL on the ATAN discriminator (3 states), and its adaptive version.

State (absolute carrier, cycles / Hz / Hz/s) at the start of epoch k: s = [theta, f, a].  The ATAN
discriminator measures the epoch-average phase error, so with the NCO's average phase over the epoch
(p + f_nco T/2) the measurement is

    z_k = atan(Q/I)/(2 pi) + p_k + f_nco,k T/2 = H s_k + v_k,     H = [1, T/2, T^2/6]

(in error-state terms: state [phase error, Doppler error, Doppler rate], Phi = [[1,T,T^2/2],[0,1,T],[0,0,1]],
H = [1, T/2, T^2/6]).  After the update the state is predicted to the start of the next epoch and the
NCO takes the predicted phase (phase step) and the predicted mean frequency f + a T/2.

R = 1/(2 T C/N0) (1 + 1/(2 T C/N0)) / (2 pi)^2 cycles^2 (ATAN discriminator variance) at the design C/N0
(tracking.carrier.kf.cn0_dbhz).  Q = oscillator (two-state clock model: S_f = h0/2, S_g = 2 pi^2 h_-2, times
f_carrier^2) on (theta, f) + white line-of-sight jerk of PSD q_j (kf.jerk_psd, (m/s^3)^2/Hz) times
(f_carrier/c)^2 through the integrator chain: q [[T^5/20, T^4/8, T^3/6], [T^4/8, T^3/3, T^2/2],
[T^3/6, T^2/2, T]].

Adaptive (adaptive_kf): innovation d_k = z_k - H s_k^-;  R_k from the NWPR C/N0 estimate (formula above
with C/N0_k);  C^_k = (1/m) sum_{i=k-m+1..k} d_i^2 (kf.window = m);  with the unscaled prediction
P0^- = Phi P^+ Phi^T + Q:

    lambda_k = max(1, (C^_k - R_k) / (H P0^- H^T)),        P_k^- = Phi P^+ Phi^T + lambda_k Q

(the exact form used: lambda scales Q only, the rest of the predicted covariance is kept).
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np
from numba import njit

from ...gnss.signals import C_LIGHT
from .common import NWPR, PythonLoop, atan_variance_cycles2, clock_q


def kf_matrices(T, fc, h0, h_2, jerk_psd):
    """(Phi, H, Q) of the 3-state KF-PLL (cycles, Hz, Hz/s) for epoch length T (s) at carrier fc (Hz): oscillator
    h0, h_-2 plus a line-of-sight jerk of PSD jerk_psd ((m/s^3)^2/Hz); see the module docstring."""
    phi = np.array([[1.0, T, T * T / 2.0], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    H = np.array([1.0, T / 2.0, T * T / 6.0])
    q = jerk_psd * (fc / C_LIGHT) ** 2
    Q = q * np.array([[T ** 5 / 20, T ** 4 / 8, T ** 3 / 6],
                      [T ** 4 / 8, T ** 3 / 3, T ** 2 / 2],
                      [T ** 3 / 6, T ** 2 / 2, T]])
    Q[:2, :2] += clock_q(T, h0, h_2, fc)
    return phi, H, Q


def kf_step_numpy(s, P, phi, H, Q, d, R, lam, first):
    """Reference (numpy) of :func:`kf_step`: prior covariance (P itself on the first epoch, else
    phi P phi^T + lam Q), scalar update with innovation d (Joseph form), prediction of s; in place."""
    Pm = P.copy() if first else phi @ P @ phi.T + lam * Q
    S = float(H @ Pm @ H) + R
    Kg = Pm @ H / S
    s += Kg * d
    IKH = np.eye(len(s)) - np.outer(Kg, H)
    P[:, :] = IKH @ Pm @ IKH.T + R * np.outer(Kg, Kg)
    s[:] = phi @ s


@njit(cache=True, nogil=True)
def _abat(A, B, out):
    """out = A B A^T for small square matrices, in plain loops (a BLAS call per 3x3 product costs more
    than the whole epoch's correlation of a 1-ms epoch; the sums' order differs from numpy's at the
    float-rounding level)."""
    n = A.shape[0]
    AB = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += A[i, k] * B[k, j]
            AB[i, j] = acc
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += AB[i, k] * A[j, k]
            out[i, j] = acc


@njit(cache=True, nogil=True)
def kf_prior_hph(P, phi, Q, H):
    """H (phi P phi^T + Q) H^T (the unscaled prediction seen by the measurement; adaptive_kf)."""
    n = P.shape[0]
    Pm = np.empty((n, n))
    _abat(phi, P, Pm)
    acc = 0.0
    for i in range(n):
        for j in range(n):
            acc += H[i] * (Pm[i, j] + Q[i, j]) * H[j]
    return acc


@njit(cache=True, nogil=True)
def kf_step(s, P, phi, H, Q, d, R, lam, first):
    """Compiled :func:`kf_step_numpy` (plain loops, no BLAS calls)."""
    n = s.shape[0]
    Pm = np.empty((n, n))
    if first:
        Pm[:, :] = P
    else:
        _abat(phi, P, Pm)
        for i in range(n):
            for j in range(n):
                Pm[i, j] += lam * Q[i, j]
    Ph = np.empty(n)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += Pm[i, j] * H[j]
        Ph[i] = acc
    S = R
    for i in range(n):
        S += H[i] * Ph[i]
    Kg = Ph / S
    for i in range(n):
        s[i] += Kg[i] * d
    IKH = np.eye(n)
    for i in range(n):
        for j in range(n):
            IKH[i, j] -= Kg[i] * H[j]
    Pn = np.empty((n, n))
    _abat(IKH, Pm, Pn)
    for i in range(n):
        for j in range(n):
            P[i, j] = Pn[i, j] + R * Kg[i] * Kg[j]
    sn = np.empty(n)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += phi[i, j] * s[j]
        sn[i] = acc
    for i in range(n):
        s[i] = sn[i]


class KFPLL(PythonLoop):
    """Kalman-filter PLL (``kf``) with R at the design C/N0 (see the module docstring); the arguments override
    ``tracking.carrier.kf`` and the clock h0 / h_-2 of the configuration."""
    name = "kf"
    adaptive = False

    def __init__(self, cfg, cn0_dbhz=None, jerk_psd=None, h0=None, h_2=None, window=None, cn0_tau_s=None):
        super().__init__(cfg)
        kf = self.car.kf if self.car is not None else None
        self.cn0_design = 10 ** ((cn0_dbhz if cn0_dbhz is not None else kf.cn0_dbhz) / 10.0)
        self.jerk_psd = float(jerk_psd if jerk_psd is not None else kf.jerk_psd)
        self.h0 = float(h0 if h0 is not None else self.car.clock_h0)
        self.h_2 = float(h_2 if h_2 is not None else self.car.clock_h_2)
        self.window = int(window if window is not None else kf.window)
        self.cn0_tau = float(cn0_tau_s if cn0_tau_s is not None else kf.cn0_tau_s)
        self._mats = {}

    def matrices(self, T):
        """(Phi, H, Q) for epoch length T (s), cached per T (ns resolution)."""
        key = int(T * 1e9 + 0.5)            # ns (round(T, 9) is slow per epoch)
        m = self._mats.get(key)
        if m is None:
            m = self._mats[key] = kf_matrices(T, self.carrier_hz, self.h0, self.h_2, self.jerk_psd)
        return m

    def init(self, doppler_hz, rate_hz_s):
        """Initial state [NCO phase cycles, Doppler Hz, rate Hz/s] and covariance at handover."""
        # s: state at the start of the next epoch (prediction), P: posterior of the previous epoch
        self.s = np.array([self.nco_phase, doppler_hz, rate_hz_s])
        self.P = np.diag([0.05 ** 2, 3.0 ** 2, 20.0 ** 2])
        self._pending_P = True          # the first epoch uses P as the prior directly
        self.nwpr = NWPR(10 * math.log10(self.cn0_design), self.cn0_tau)
        self.innov = deque(maxlen=self.window)
        self.lam = 1.0
        self.cn0 = self.cn0_design
        self.last_err = 0.0

    def step(self, ip, qp, T, p1=None, p2=None):
        """One epoch: ATAN phase error of the prompt, KF update (adaptive: R from the NWPR C/N0, Q scaled by
        lambda), prediction to the next epoch; returns (Doppler for the next epoch Hz, phase step cycles)."""
        phi, H, Q = self.matrices(T)
        e = math.atan(qp / ip) / (2.0 * math.pi) if ip != 0.0 else 0.0
        self.last_err = e
        z = e + self.nco_phase + self.nco_freq * T / 2.0
        s = self.s
        d = z - (H[0] * s[0] + H[1] * s[1] + H[2] * s[2])     # (BLAS's ddot may sum in another order)
        if self.adaptive:
            self.cn0 = self.nwpr.update(p1, p2, T)
            R = atan_variance_cycles2(self.cn0, T)
        else:
            R = atan_variance_cycles2(self.cn0_design, T)
        first = self._pending_P
        self._pending_P = False
        if self.adaptive and not first:
            self.innov.append(d * d)
            c_hat = sum(self.innov) / len(self.innov)
            hph = kf_prior_hph(self.P, phi, Q, H)
            self.lam = max(1.0, (c_hat - R) / hph) if hph > 0 else 1.0
        kf_step(self.s, self.P, phi, H, Q, d, R, self.lam, first)   # update, then predict to the next epoch
        return self._command(T, self.s[0], self.s[1] + self.s[2] * T / 2.0)

    # ---- analysis helpers
    def steady_state(self, T):
        """(gain K, predicted P) of the fixed-R filter at epoch length T."""
        from .common import steady_state_gain
        phi, H, Q = kf_matrices(T, self.carrier_hz, self.h0, self.h_2, self.jerk_psd)
        return steady_state_gain(phi, H, Q, atan_variance_cycles2(self.cn0_design, T))


class AdaptiveKFPLL(KFPLL):
    """Adaptive KF-PLL (``adaptive_kf``): R from the NWPR C/N0 estimate, Q scaled by the innovation-matched
    lambda >= 1 (see the module docstring)."""
    name = "adaptive_kf"
    adaptive = True
