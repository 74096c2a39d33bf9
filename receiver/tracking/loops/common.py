"""Shared parts of the Python carrier loops: NCO bookkeeping, NWPR C/N0, process-noise models, bandwidths.

Units: the KF-PLL works in cycles (phase), Hz and Hz/s; the EKFs in rad, rad/s, rad/s^2, rad/s^3.

NCO convention (as the kernel's): during an epoch of duration T that starts with NCO phase p (cycles,
Doppler part only: the IF ramp is common to signal and replica) and frequency f, the replica phase is
p + f t.  A loop returns, after each epoch, the frequency for the next epoch and a phase step added to the
NCO phase at the start of the next epoch; it keeps its own copy of the NCO phase so that it can command an
absolute phase.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ...gnss.signals import C_LIGHT, GPS_L1CA
from .base import CarrierLoop
from .. import kernel as K


class PythonLoop(CarrierLoop):
    """Base of the Python loops: reads an epoch row, keeps the NCO model, calls :meth:`step`."""

    def __init__(self, cfg):
        super().__init__(cfg)
        self.car = cfg.carrier if cfg is not None else None
        self.epoch_s = None
        self.carrier_hz = GPS_L1CA.carrier_hz      # until start() is given the channel signal's carrier

    def start(self, doppler_hz: float, T: float, rate_hz_s: float = 0.0, carrier_hz: float | None = None):
        """Reset at handover: NCO at phase 0 (cycles) and ``doppler_hz`` (Hz), epoch length T (s), carrier
        frequency (Hz; kept when None), then :meth:`init` with the Doppler and its rate (Hz/s)."""
        self.doppler_hz = float(doppler_hz)
        self.T = float(T)
        if carrier_hz is not None:
            self.carrier_hz = float(carrier_hz)
        self.nco_phase = 0.0          # cycles at the start of the next epoch
        self.nco_freq = float(doppler_hz)
        self.init(float(doppler_hz), float(rate_hz_s))

    def init(self, doppler_hz, rate_hz_s):          # pragma: no cover - interface
        """Set the loop's state from the Doppler (Hz) and Doppler rate (Hz/s) at handover (subclasses)."""
        raise NotImplementedError

    def update(self, epoch):
        """One epoch from a kernel output row (prompt I/Q, its two halves, the integration length unless
        ``epoch_s`` is set): :meth:`step`'s (Doppler for the next epoch Hz, phase step cycles)."""
        T = self.epoch_s if self.epoch_s else float(epoch[K.O_INT_MS]) * 1e-3
        p1 = complex(epoch[K.O_P1I], epoch[K.O_P1Q])
        p2 = complex(epoch[K.O_P2I], epoch[K.O_P2Q])
        return self.step(float(epoch[K.O_PI]), float(epoch[K.O_PQ]), T, p1, p2)

    def step(self, ip, qp, T, p1=None, p2=None):   # pragma: no cover - interface
        """One epoch: prompt I/Q (and halves) -> (Doppler for the next epoch, phase step, cycles)."""
        raise NotImplementedError

    def _command(self, T, start_phase, freq):
        """Set the NCO for the next epoch to (start_phase, freq); return (freq, phase step)."""
        end = self.nco_phase + self.nco_freq * T
        self.nco_phase = start_phase
        self.nco_freq = freq
        self.doppler_hz = freq
        return freq, start_phase - end


class NWPR:
    """Narrow-band/wide-band power ratio C/N0 estimator on the two half-epoch prompts (M = 2).

    mu = E[NBP / WBP], NBP = |P1 + P2|^2, WBP = |P1|^2 + |P2|^2;  C/N0 = (mu - 1) / (T_sub (M - mu)),
    T_sub = T / 2; mu is smoothed with the time constant tau (s)."""

    def __init__(self, cn0_dbhz0: float, tau_s: float):
        self.tau = tau_s
        self.cn0 = 10 ** (cn0_dbhz0 / 10.0)
        self.mu = None

    def update(self, p1, p2, T):
        """Add one epoch's half-epoch prompts p1, p2 (complex; epoch length T s); returns C/N0 (linear, Hz).
        Without halves or with zero power the previous estimate is returned unchanged."""
        if p1 is None or p2 is None:
            return self.cn0
        wbp = abs(p1) ** 2 + abs(p2) ** 2
        if wbp <= 0:
            return self.cn0
        r = abs(p1 + p2) ** 2 / wbp
        ts = T / 2.0
        if self.mu is None:
            c = self.cn0 * ts
            self.mu = (1.0 + 2.0 * c) / (1.0 + c)          # E[NBP]/E[WBP] at the initial C/N0
        a = min(1.0, T / self.tau) if self.tau > 0 else 1.0
        self.mu += a * (r - self.mu)
        mu = min(max(self.mu, 1.0 + 1e-4), 2.0 - 1e-4)
        self.cn0 = max((mu - 1.0) / (ts * (2.0 - mu)), 1.0)
        return self.cn0


def atan_variance_cycles2(cn0: float, T: float) -> float:
    """Variance of the ATAN (Costas) discriminator, cycles^2: 1/(2 T C/N0) (1 + 1/(2 T C/N0)) / (2 pi)^2."""
    x = 2.0 * T * cn0
    return (1.0 / x) * (1.0 + 1.0 / x) / (4.0 * math.pi ** 2)


def clock_q(T: float, h0: float, h_2: float, fc: float) -> np.ndarray:
    """2x2 process noise (cycles^2, cycles^2/s, Hz^2) of the oscillator phase/frequency over T:
    S_f = h0/2, S_g = 2 pi^2 h_-2 (two-state clock model), scaled by fc^2."""
    sf = h0 / 2.0 * fc * fc
    sg = 2.0 * math.pi ** 2 * h_2 * fc * fc
    return np.array([[sf * T + sg * T ** 3 / 3.0, sg * T ** 2 / 2.0],
                     [sg * T ** 2 / 2.0, sg * T]])


def taylor_phi(n: int, T: float) -> np.ndarray:
    """Transition matrix of an n-state Taylor (integrator chain) model."""
    phi = np.eye(n)
    for i in range(n):
        for j in range(i + 1, n):
            phi[i, j] = T ** (j - i) / math.factorial(j - i)
    return phi


def white_last_q(n: int, T: float, q: float) -> np.ndarray:
    """Process noise of an n-state integrator chain driven by white noise of PSD q on the last
    derivative (the Taylor remainder): Q_ij = q T^(2n-1-i-j) / ((n-1-i)! (n-1-j)! (2n-1-i-j))."""
    Q = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            e = 2 * n - 1 - i - j
            Q[i, j] = q * T ** e / (math.factorial(n - 1 - i) * math.factorial(n - 1 - j) * e)
    return Q


def loop_noise_bandwidth_discrete(phi, H, K, T, n_imp=20000) -> float:
    """One-sided noise bandwidth (Hz) of a steady-state Kalman loop: Bn = sum(g_k^2) / (2 T), g the
    response of the measurement-phase estimate H s^- to a unit measurement-noise impulse."""
    n = phi.shape[0]
    A = phi @ (np.eye(n) - np.outer(K, H))
    b = phi @ K
    x = b.copy()
    acc = 0.0
    for _ in range(n_imp):
        g = float(H @ x)
        acc += g * g
        x = A @ x
        if abs(g) < 1e-12 and np.abs(x).max() < 1e-12:
            break
    return acc / (2.0 * T)


def steady_state_gain(phi, H, Q, R, iters=20000):
    """Steady-state (predicted-covariance) Kalman gain of a scalar-measurement filter."""
    P = np.eye(phi.shape[0])
    for _ in range(iters):
        S = float(H @ P @ H) + R
        Kg = P @ H / S
        Pp = (np.eye(len(Kg)) - np.outer(Kg, H)) @ P
        Pn = phi @ Pp @ phi.T + Q
        if np.allclose(Pn, P, rtol=1e-12, atol=1e-30):
            P = Pn
            break
        P = Pn
    S = float(H @ P @ H) + R
    return P @ H / S, P


def continuous_bandwidth(n: int, qdiag, r: float) -> float:
    """Noise bandwidth (Hz) of the continuous-time steady-state Kalman loop of an n-integrator chain with
    white process noise PSDs qdiag (per state) and measurement-noise PSD r, observing the first state:
    K = P C^T / r from the continuous ARE, H(s) = C (sI - A + K C)^-1 K, Bn = int_0^inf |H(j 2 pi f)|^2 df."""
    from scipy.integrate import quad
    from scipy.linalg import solve_continuous_are
    A = np.diag(np.ones(n - 1), 1)
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    P = solve_continuous_are(A.T, C.T, np.diag(qdiag), np.array([[r]]))
    Kc = (P @ C.T / r).ravel()
    Acl = A - np.outer(Kc, C[0])
    I = np.eye(n)

    def h2(f):
        h = C[0] @ np.linalg.solve(2j * math.pi * f * I - Acl, Kc)
        return abs(h) ** 2

    wn = (max(qdiag[-1], 1e-300) / r) ** (1.0 / (2 * n))
    edges = [0.0, wn / 10, wn / 2, wn, 3 * wn, 30 * wn]
    bn = sum(quad(h2, a, b, limit=200)[0] for a, b in zip(edges[:-1], edges[1:]))
    return bn + quad(h2, 30 * wn, np.inf, limit=200)[0]


@lru_cache(maxsize=None)
def butterworth_bn_factor(n: int) -> float:
    """Bn / omega0 of the continuous steady-state Kalman loop of an n-integrator chain with white noise on
    the last state only (omega0 = (q/r)^(1/(2n)))."""
    q = [0.0] * (n - 1) + [1.0]
    return continuous_bandwidth(n, q, 1.0)


def q_for_bandwidth(n: int, bn_hz: float, r: float) -> float:
    """White-noise PSD q on the last state giving a continuous steady-state bandwidth bn_hz at measurement
    PSD r: omega0 = Bn / factor(n), q = r omega0^(2n)."""
    w0 = bn_hz / butterworth_bn_factor(n)
    return r * w0 ** (2 * n)


def los_to_cycles(fc: float) -> float:
    """Metres of line of sight per carrier cycle inverse: cycles per metre."""
    return fc / C_LIGHT
