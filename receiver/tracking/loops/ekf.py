"""ekf / pli_ekf: extended Kalman filter carrier loops on the prompt I/Q (no discriminator).

State (rad units) at the midpoint of the epoch being processed: s = [theta, w0, w1, w2] (carrier phase,
angular Doppler and its first two derivatives).  The NCO is a known input: its phase at the epoch midpoint
phi_nco (rad), so the phase error is phi_E = L s - phi_nco with L = [1 0 0 0], and

    x(k) = [I, Q] = [A cos(phi_E), A sin(phi_E)] + n,      n ~ N(0, sigma^2 I_2)
    H(k) = [-A sin(phi_E^), A cos(phi_E^)]^T L                           (linearised at the prediction)
    s(k+1) = Phi s(k) + w,   Phi = Taylor transition [[1,T,T^2/2,T^3/6],[0,1,T,T^2/2],[0,0,1,T],[0,0,0,1]]

Q = the Taylor remainder: white noise of PSD q on w2's derivative through the chain,
Q_ij = q T^(7-i-j)/((3-i)!(3-j)!(7-i-j)), plus the oscillator (h0, h_-2) on (theta, w0), in rad^2.  q is set
from the bandwidth at the design C/N0 (tracking.carrier.ekf.bn_hz, cn0_dbhz): the continuous steady-state
loop of a 4-integrator chain has Bn = 1.1432 omega0 with omega0 = (q / r)^(1/8), r = 1/(2 C/N0) rad^2 s.
A and sigma^2 from the correlator power: P_fast = E|P|^2 over amp_tau_s, P_slow over cn0_tau_s, NWPR C/N0:
sigma^2 = P_slow / (2 (1 + C/N0 T)), A^2 = max(P_fast - 2 sigma^2, sigma^2 / 10).
Data symbols inside an epoch are removed decision-directed (x -> sign(I cos phi_E^ + Q sin phi_E^) x).
After the update the state is predicted to the next midpoint; the NCO takes w0/2pi and the phase that puts
its midpoint phase on theta^.

PLI-EKF: the observation is replaced by
    x_PLI(k) = PLI(k) x(k) + (1 - PLI(k)) x0(k),  PLI = (I^2 - Q^2)/(I^2 + Q^2) (clipped to [pli_min, 1];
    I^2 and Q^2 low-passed over tracking.carrier.ekf.pli_tau_s, 0 = the epoch's own values),
    x0(k) = x_PLI(k-1) + H(k-1) Delta s(k-1),     Delta s(k-1) = s^(k|k-1) - s^(k-1|k-1)
with Delta s taken relative to the NCO (its phase component minus the NCO midpoint-phase advance), so x0 is
the previous weighted observation carried to the current epoch by the linearised model.  With PLI = 1 it is
the EKF.

Against the paper (BDS B1I scintillation, PLI-EKF; eqs. 15-17): the weighting x_PLI = PLI x + (1 - PLI) x0,
the correction x0 = x_PLI(k-1) + H(k-1) Delta s(k-1) and the EKF recursion are the paper's.  Ours: the PLI is
computed from low-passed I^2, Q^2 (pli_tau_s = 0.1 s; the paper uses the epoch's IP_k, QP_k, i.e. 0) and
clipped at pli_min = 0 (the paper's PLI ranges over [-1, 1], and a negative weight extrapolates past x0);
pli_tau_s = 0, pli_min = -1 is the paper's form.  Also ours (the paper leaves them to its reference [18] or
does not state them): Q from a bandwidth at a design C/N0, A and R from NWPR power estimates, the innovation
x - h(s^) (the paper writes x - H s^), and the decision-directed data wipe-off.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .common import NWPR, PythonLoop, clock_q, q_for_bandwidth, taylor_phi, white_last_q

TWO_PI = 2.0 * math.pi


def obs_and_jacobian(pe, A):
    """(h, H column) at the predicted phase error pe: h = A [cos pe, sin pe], dh/dtheta = A [-sin pe, cos pe]
    (the only non-zero column of H = dh/ds, L = [1 0 0 0])."""
    c, s_ = math.cos(pe), math.sin(pe)
    return (A * c, A * s_), (-A * s_, A * c)


def observation(s, A, nco_mid):
    """h(s) = [A cos(L s - phi_nco), A sin(L s - phi_nco)]."""
    return np.array(obs_and_jacobian(s[0] - nco_mid, A)[0])


def jacobian(s, A, nco_mid):
    """H = dh/ds = [-A sin(phi_E), A cos(phi_E)]^T L, L = [1 0 0 0]."""
    H = np.zeros((2, 4))
    H[:, 0] = obs_and_jacobian(s[0] - nco_mid, A)[1]
    return H


def ekf_step_numpy(s, P, phi, Q, h0, h1, e0, e1, sig2, post):
    """Reference (numpy) of :func:`ekf_step`: update with H = [h0, h1]^T L, innovation (e0, e1) and
    R = sig2 I (Joseph form), posterior state into ``post``, then prediction; s and P in place."""
    H = np.zeros((2, len(s)))
    H[0, 0], H[1, 0] = h0, h1
    R = sig2 * np.eye(2)
    Kg = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    s += Kg @ np.array([e0, e1])
    IKH = np.eye(len(s)) - Kg @ H
    P[:, :] = IKH @ P @ IKH.T + Kg @ R @ Kg.T
    post[:] = s
    s[:] = phi @ s
    P[:, :] = phi @ P @ phi.T + Q


@njit(cache=True)
def ekf_step(s, P, phi, Q, h0, h1, e0, e1, sig2, post):
    """Compiled :func:`ekf_step_numpy` (the loops' per-epoch linear algebra; H has one non-zero column)."""
    n = s.shape[0]
    p00 = P[0, 0]
    S00 = h0 * h0 * p00 + sig2
    S01 = h0 * h1 * p00
    S11 = h1 * h1 * p00 + sig2
    det = S00 * S11 - S01 * S01
    i00, i01, i11 = S11 / det, -S01 / det, S00 / det
    K = np.empty((n, 2))
    for i in range(n):
        a0 = P[i, 0] * h0
        a1 = P[i, 0] * h1
        K[i, 0] = a0 * i00 + a1 * i01
        K[i, 1] = a0 * i01 + a1 * i11
    for i in range(n):
        s[i] += K[i, 0] * e0 + K[i, 1] * e1
    g = np.empty(n)                     # (K H)[:, 0]; IKH = I - g e_0^T
    for i in range(n):
        g[i] = K[i, 0] * h0 + K[i, 1] * h1
    A = P.copy()                        # IKH P
    for j in range(n):
        for i in range(n):
            A[i, j] = P[i, j] - g[i] * P[0, j]
    for i in range(n):                  # (IKH P) IKH^T + sig2 K K^T
        for j in range(n):
            P[i, j] = A[i, j] - A[i, 0] * g[j] + sig2 * (K[i, 0] * K[j, 0] + K[i, 1] * K[j, 1])
    for i in range(n):
        post[i] = s[i]
    for i in range(n):
        acc = 0.0
        for k in range(n):
            acc += phi[i, k] * post[k]
        s[i] = acc
    B = np.zeros((n, n))                # phi P
    for i in range(n):
        for k in range(n):
            if phi[i, k] != 0.0:
                for j in range(n):
                    B[i, j] += phi[i, k] * P[k, j]
    for i in range(n):
        for j in range(n):
            acc = Q[i, j]
            for k in range(n):
                acc += B[i, k] * phi[j, k]
            P[i, j] = acc


class EKF(PythonLoop):
    """EKF carrier loop (``ekf``) on the prompt I/Q with the 4-state Taylor model (rad units; see the module
    docstring); the arguments override ``tracking.carrier.ekf`` and the clock h0 / h_-2 of the configuration."""
    name = "ekf"
    use_pli = False

    def __init__(self, cfg, bn_hz=None, cn0_dbhz=None, h0=None, h_2=None, amp_tau_s=None, cn0_tau_s=None,
                 pli_tau_s=None, pli_min=None):
        super().__init__(cfg)
        e = self.car.ekf if self.car is not None else None
        self.bn = float(bn_hz if bn_hz is not None else e.bn_hz)
        self.cn0_design = 10 ** ((cn0_dbhz if cn0_dbhz is not None else e.cn0_dbhz) / 10.0)
        self.h0 = float(h0 if h0 is not None else self.car.clock_h0)
        self.h_2 = float(h_2 if h_2 is not None else self.car.clock_h_2)
        self.amp_tau = float(amp_tau_s if amp_tau_s is not None else e.amp_tau_s)
        self.cn0_tau = float(cn0_tau_s if cn0_tau_s is not None else e.cn0_tau_s)
        self.pli_tau = float(pli_tau_s if pli_tau_s is not None else e.pli_tau_s)
        self.pli_min = float(pli_min if pli_min is not None else (e.pli_min if e is not None else 0.0))
        self.q = q_for_bandwidth(4, self.bn, 1.0 / (2.0 * self.cn0_design))
        self._mats = {}

    def matrices(self, T):
        """(Phi, Q) of the 4-state model for epoch length T (s), rad units, cached per T (ns resolution)."""
        key = int(T * 1e9 + 0.5)            # ns (round(T, 9) is slow per epoch)
        m = self._mats.get(key)
        if m is None:
            phi = taylor_phi(4, T)
            Q = white_last_q(4, T, self.q)
            Q[:2, :2] += clock_q(T, self.h0, self.h_2, self.carrier_hz) * TWO_PI ** 2
            m = self._mats[key] = (phi, Q)
        return m

    def init(self, doppler_hz, rate_hz_s):
        """Initial state (prediction for the first epoch's midpoint) and covariance from the Doppler (Hz) and rate
        (Hz/s) at handover; resets the power, C/N0 and PLI estimators."""
        T = self.T
        # prediction for the midpoint of the first epoch (NCO starts at phase 0 with the given Doppler)
        self.s = np.array([TWO_PI * doppler_hz * T / 2.0, TWO_PI * doppler_hz, TWO_PI * rate_hz_s, 0.0])
        self.P = np.diag([0.3 ** 2, (TWO_PI * 3.0) ** 2, (TWO_PI * 20.0) ** 2, (TWO_PI * 20.0) ** 2])
        self._post = np.zeros(4)     # posterior state of the last epoch
        self.nwpr = NWPR(10 * math.log10(self.cn0_design), self.cn0_tau)
        self.p_fast = None
        self.p_slow = None
        self.cn0 = self.cn0_design
        self.prev_x = None           # PLI-EKF: x_PLI(k-1)
        self.prev_H = None           # H(k-1) (2x4)
        self.prev_post = None        # s^(k-1|k-1)
        self.prev_nco_mid = None
        self.last_err = 0.0
        self.pli = 1.0
        self.pli_i2 = None
        self.pli_q2 = None

    def _amplitude(self, ip, qp, T, p1, p2):
        pw = ip * ip + qp * qp
        self.cn0 = self.nwpr.update(p1, p2, T)
        if self.p_fast is None:
            self.p_fast = self.p_slow = pw
        a = min(1.0, T / self.amp_tau) if self.amp_tau > 0 else 1.0
        b = min(1.0, T / self.cn0_tau) if self.cn0_tau > 0 else 1.0
        self.p_fast += a * (pw - self.p_fast)
        self.p_slow += b * (pw - self.p_slow)
        sig2 = self.p_slow / (2.0 * (1.0 + self.cn0 * T))
        A2 = max(self.p_fast - 2.0 * sig2, sig2 / 10.0)
        return math.sqrt(A2), sig2

    def step(self, ip, qp, T, p1=None, p2=None):
        """One epoch: EKF update with the prompt I/Q (data wiped off; PLI-weighted for ``pli_ekf``), prediction to
        the next midpoint; returns (Doppler for the next epoch Hz, phase step cycles)."""
        phi, Q = self.matrices(T)
        A, sig2 = self._amplitude(ip, qp, T, p1, p2)
        nco_mid = TWO_PI * (self.nco_phase + self.nco_freq * T / 2.0)
        (hc, hs), (h0, h1) = obs_and_jacobian(self.s[0] - nco_mid, A)    # at phi_E^, H = [h0, h1]^T L
        xi, xq = ip, qp
        if ip * hc + qp * hs < 0.0:                       # decision-directed data wipe-off
            xi, xq = -xi, -xq
        if self.use_pli:
            if self.pli_i2 is None:
                self.pli_i2, self.pli_q2 = ip * ip, qp * qp
            w = min(1.0, T / self.pli_tau) if self.pli_tau > 0 else 1.0
            self.pli_i2 += w * (ip * ip - self.pli_i2)
            self.pli_q2 += w * (qp * qp - self.pli_q2)
            tot = self.pli_i2 + self.pli_q2
            pli = (self.pli_i2 - self.pli_q2) / tot if tot > 0 else 0.0
            pli = min(max(pli, self.pli_min), 1.0)
            self.pli = pli
            if self.prev_x is not None:
                # x0 = x_PLI(k-1) + H(k-1) ds, ds relative to the NCO; H has only its first column
                ds0 = self.s[0] - self.prev_post[0] - (nco_mid - self.prev_nco_mid)
                xi = pli * xi + (1.0 - pli) * (self.prev_x[0] + self.prev_H[0] * ds0)
                xq = pli * xq + (1.0 - pli) * (self.prev_x[1] + self.prev_H[1] * ds0)
            self.prev_H = (h0, h1)
            self.prev_nco_mid = nco_mid
        post = self._post
        # update (innovation x - h(s)), then predict to the next midpoint
        ekf_step(self.s, self.P, phi, Q, h0, h1, xi - hc, xq - hs, sig2, post)
        self.last_err = (post[0] - nco_mid) / TWO_PI
        if self.use_pli:
            self.prev_x = (xi, xq)
            self.prev_post = post.copy()
        f = self.s[1] / TWO_PI
        return self._command(T, self.s[0] / TWO_PI - f * T / 2.0, f)


class PLIEKF(EKF):
    """PLI-EKF (``pli_ekf``): the EKF with the observation weighted by the phase lock indicator (module docstring)."""
    name = "pli_ekf"
    use_pli = True
