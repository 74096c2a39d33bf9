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
    x_PLI(k) = PLI(k) x(k) + (1 - PLI(k)) x0(k),  PLI = (I^2 - Q^2)/(I^2 + Q^2) (clipped to [0, 1]; I^2 and
    Q^2 low-passed over tracking.carrier.ekf.pli_tau_s, 0 = the epoch's own values),
    x0(k) = x_PLI(k-1) + H(k-1) Delta s(k-1),     Delta s(k-1) = s^(k|k-1) - s^(k-1|k-1)
with Delta s taken relative to the NCO (its phase component minus the NCO midpoint-phase advance), so x0 is
the previous weighted observation carried to the current epoch by the linearised model.  With PLI = 1 it is
the EKF.
"""
from __future__ import annotations

import math

import numpy as np

from .common import NWPR, PythonLoop, clock_q, q_for_bandwidth, taylor_phi, white_last_q

TWO_PI = 2.0 * math.pi


def observation(s, A, nco_mid):
    """h(s) = [A cos(L s - phi_nco), A sin(L s - phi_nco)]."""
    pe = s[0] - nco_mid
    return np.array([A * math.cos(pe), A * math.sin(pe)])


def jacobian(s, A, nco_mid):
    """H = dh/ds = [-A sin(phi_E), A cos(phi_E)]^T L, L = [1 0 0 0]."""
    pe = s[0] - nco_mid
    H = np.zeros((2, 4))
    H[0, 0] = -A * math.sin(pe)
    H[1, 0] = A * math.cos(pe)
    return H


class EKF(PythonLoop):
    name = "ekf"
    use_pli = False

    def __init__(self, cfg, bn_hz=None, cn0_dbhz=None, h0=None, h_2=None, amp_tau_s=None, cn0_tau_s=None,
                 pli_tau_s=None):
        super().__init__(cfg)
        e = self.car.ekf if self.car is not None else None
        self.bn = float(bn_hz if bn_hz is not None else e.bn_hz)
        self.cn0_design = 10 ** ((cn0_dbhz if cn0_dbhz is not None else e.cn0_dbhz) / 10.0)
        self.h0 = float(h0 if h0 is not None else self.car.clock_h0)
        self.h_2 = float(h_2 if h_2 is not None else self.car.clock_h_2)
        self.amp_tau = float(amp_tau_s if amp_tau_s is not None else e.amp_tau_s)
        self.cn0_tau = float(cn0_tau_s if cn0_tau_s is not None else e.cn0_tau_s)
        self.pli_tau = float(pli_tau_s if pli_tau_s is not None else e.pli_tau_s)
        self.q = q_for_bandwidth(4, self.bn, 1.0 / (2.0 * self.cn0_design))
        self._mats = {}

    def matrices(self, T):
        key = round(T, 9)
        m = self._mats.get(key)
        if m is None:
            phi = taylor_phi(4, T)
            Q = white_last_q(4, T, self.q)
            Q[:2, :2] += clock_q(T, self.h0, self.h_2, self.carrier_hz) * TWO_PI ** 2
            m = self._mats[key] = (phi, Q)
        return m

    def init(self, doppler_hz, rate_hz_s):
        T = self.T
        # prediction for the midpoint of the first epoch (NCO starts at phase 0 with the given Doppler)
        self.s = np.array([TWO_PI * doppler_hz * T / 2.0, TWO_PI * doppler_hz, TWO_PI * rate_hz_s, 0.0])
        self.P = np.diag([0.3 ** 2, (TWO_PI * 3.0) ** 2, (TWO_PI * 20.0) ** 2, (TWO_PI * 20.0) ** 2])
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
        phi, Q = self.matrices(T)
        A, sig2 = self._amplitude(ip, qp, T, p1, p2)
        nco_mid = TWO_PI * (self.nco_phase + self.nco_freq * T / 2.0)
        pe = self.s[0] - nco_mid                          # predicted phase error phi_E^
        c, s_ = math.cos(pe), math.sin(pe)
        x = np.array([ip, qp])
        if ip * c + qp * s_ < 0.0:                        # decision-directed data wipe-off
            x = -x
        H = jacobian(self.s, A, nco_mid)
        if self.use_pli:
            if self.pli_i2 is None:
                self.pli_i2, self.pli_q2 = ip * ip, qp * qp
            w = min(1.0, T / self.pli_tau) if self.pli_tau > 0 else 1.0
            self.pli_i2 += w * (ip * ip - self.pli_i2)
            self.pli_q2 += w * (qp * qp - self.pli_q2)
            tot = self.pli_i2 + self.pli_q2
            pli = (self.pli_i2 - self.pli_q2) / tot if tot > 0 else 0.0
            pli = min(max(pli, 0.0), 1.0)
            self.pli = pli
            if self.prev_x is not None:
                ds = self.s - self.prev_post
                ds[0] -= nco_mid - self.prev_nco_mid       # relative to the NCO
                x0 = self.prev_x + self.prev_H @ ds
                x = pli * x + (1.0 - pli) * x0
            self.prev_H = H
            self.prev_nco_mid = nco_mid
        hx = observation(self.s, A, nco_mid)
        R = sig2 * np.eye(2)
        S = H @ self.P @ H.T + R
        Kg = self.P @ H.T @ np.linalg.inv(S)
        self.s = self.s + Kg @ (x - hx)
        IKH = np.eye(4) - Kg @ H
        self.P = IKH @ self.P @ IKH.T + Kg @ R @ Kg.T
        self.last_err = (self.s[0] - nco_mid) / TWO_PI
        if self.use_pli:
            self.prev_x = x
            self.prev_post = self.s.copy()
        # predict to the next epoch's midpoint (next epoch assumed as long as this one)
        self.s = phi @ self.s
        self.P = phi @ self.P @ phi.T + Q
        f = self.s[1] / TWO_PI
        return self._command(T, self.s[0] / TWO_PI - f * T / 2.0, f)


class PLIEKF(EKF):
    name = "pli_ekf"
    use_pli = True
