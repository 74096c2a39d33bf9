"""polynomial: VDFLL with polynomial predictive filters (PPF) instead of a dynamics model.

A PPF of degree L and length K predicts the next sample of a sequence from its last K samples,
x(n+1) = sum_{k=0}^{K-1} h(k) x(n-k), exactly for every polynomial of degree <= L (for K = L + 1 the
coefficients are h(k) = (-1)^k C(K, k+1); for K > L + 1 they are the least-squares extrapolator).
Position: L = 2, K = 3, h2 = [3, -3, 1]; velocity: L = 1, K = 2, h1 = [2, -1]; clock drift: L = 1, K = 2.

State (the paper's 18-state layout for the default lengths; axis-minor, lag-major):
    [x(n) y(n) z(n), x(n-1) .., x(n-2) .., vx(n) vy(n) vz(n), vx(n-1) .., t_b(n), t_d(n), t_d(n-1)]
(+ the code-minus-carrier drift when ``vector.code_carrier_drift``).  Transition: position rows
[h2(0) I, h2(1) I, h2(2) I] then shifts, velocity [h1(0) I, h1(1) I] then shift, drift likewise, and
t_b(n+1) = t_b(n) + T (t_d(n) + delta): the bias accrued over one epoch is T times the drift (the paper's
t_b is that per-epoch increment because its NCO feedback resets the error state; this filter keeps the
total state).  Position and velocity are deliberately not coupled (no dynamics prior): the code
discriminators observe the position PPF, the frequency discriminators the velocity PPF.

Q = 0 normally.  Manoeuvre detection: with P_s = H P- H^T + R split into its code and carrier blocks,
tag_p = z_code^T P_s,code^-1 z_code and tag_v = z_carr^T P_s,carr^-1 z_carr are chi-square with (number of
satellites) degrees of freedom; when either exceeds ``vector.polynomial.chi2_threshold`` the manoeuvre
noise QB is added for that epoch.  "Q large" is specified physically, as the variances of jumps of position,
velocity, acceleration and clock drift (``q_manoeuvre_*``; see :meth:`PolynomialFilter.manoeuvre_noise`):
a diagonal Q on the paper's lag states would instead give the first difference of the velocity lags (an
acceleration over one epoch) twice the velocity variance, i.e. destroy the slope information on every
detection (with 1 ms epochs, 1 (m/s)^2 on each velocity lag means a 1400 m/s^2 acceleration uncertainty).
R is re-estimated from the post-fit residuals, R = C_r + H P H^T (``polynomial.adaptive_r``).

Numerics: with Q = 0 the covariance of lagged samples becomes nearly singular (x(n), x(n-1), x(n-2) agree
to a part in 1e8 and their second difference is known to 1e-20 of their variance), so the filter runs in
the equivalent backward-difference basis y_i = nabla^i x(n) (x(n-k) = sum_i (-1)^i C(k, i) y_i), where the
PPF of K = L + 1 becomes the exact constant-derivative transition.  The two bases give the same filter in
exact arithmetic; :meth:`PolynomialFilter.to_paper` / ``from_paper`` convert states and matrices.
"""
from __future__ import annotations

from fractions import Fraction
from math import comb

import numpy as np

from .base import VectorFilter
from .kalman import FORM_NONE, FORM_RESIDUAL


def ppf_coefficients(degree: int, taps: int) -> np.ndarray:
    """h(0..K-1) of the one-step polynomial predictive filter of degree L and length K >= L + 1."""
    L, K = int(degree), int(taps)
    if K < L + 1:
        raise ValueError(f"a PPF of degree {L} needs at least {L + 1} taps, got {K}")
    if K == L + 1:
        return np.array([(-1) ** k * comb(K, k + 1) for k in range(K)], dtype=float)
    # least squares: h = [1, 1, ..] (V^T V)^-1 V^T with V[k, i] = (-k)^i, in exact rationals
    V = [[Fraction((-k) ** i) for i in range(L + 1)] for k in range(K)]
    A = [[sum(V[k][i] * V[k][j] for k in range(K)) for j in range(L + 1)] for i in range(L + 1)]
    n = L + 1
    inv = [[Fraction(int(i == j)) for j in range(n)] for i in range(n)]
    for c in range(n):                                   # Gauss-Jordan
        p = next(r for r in range(c, n) if A[r][c] != 0)
        A[c], A[p], inv[c], inv[p] = A[p], A[c], inv[p], inv[c]
        f = A[c][c]
        A[c] = [v / f for v in A[c]]
        inv[c] = [v / f for v in inv[c]]
        for r in range(n):
            if r != c and A[r][c] != 0:
                g = A[r][c]
                A[r] = [a - g * b for a, b in zip(A[r], A[c])]
                inv[r] = [a - g * b for a, b in zip(inv[r], inv[c])]
    w = [sum(inv[i][j] for i in range(n)) for j in range(n)]           # [1..1] (V^T V)^-1
    return np.array([float(sum(w[i] * V[k][i] for i in range(n))) for k in range(K)])


def _diff_basis(K: int) -> np.ndarray:
    """M (K x K): lags x(n-k) = sum_i M[k, i] y_i with y_i = nabla^i x(n)."""
    return np.array([[(-1) ** i * comb(k, i) for i in range(K)] for k in range(K)], dtype=float)


class PolynomialFilter(VectorFilter):
    """VDFLL navigation filter of polynomial predictive filters (``vector.filter: polynomial``; see the module
    docstring); runs in the backward-difference basis."""
    name = "polynomial"

    def __init__(self, vcfg, T):
        super().__init__(vcfg, T)
        pc = vcfg.polynomial
        self.kp, self.kv, self.kd = int(pc.position_taps), int(pc.velocity_taps), int(pc.drift_taps)
        self.hp = ppf_coefficients(2, self.kp)
        self.hv = ppf_coefficients(1, self.kv)
        self.hd = ppf_coefficients(1, self.kd)
        self.chi2_threshold = float(pc.chi2_threshold)
        self.adaptive_form = FORM_RESIDUAL if pc.adaptive_r else FORM_NONE
        self._M = self._basis()
        self._Minv = np.linalg.inv(self._M)
        self._Minv = np.round(self._Minv)            # integer (binomial) matrix, exactly

    # ------------------------------------------------------------------ layout (both bases)
    @property
    def n(self) -> int:
        """State dimension: 3 K_p position and 3 K_v velocity states, the clock bias, K_d drift states (+ delta)."""
        return 3 * self.kp + 3 * self.kv + 1 + self.kd + (1 if self.has_delta else 0)

    @property
    def ib(self) -> int:
        """Index of the clock bias b (m) in the state vector (after the position and velocity states)."""
        return 3 * self.kp + 3 * self.kv

    def layout(self):
        """int64 [ip, iv, ib, id, idel]: where x(n), v(n), b, d and delta sit (idel -1 without the delta state)."""
        ib = self.ib
        return np.array([0, 3 * self.kp, ib, ib + 1, ib + 1 + self.kd if self.has_delta else -1], np.int64)

    def _basis(self):
        n = self.n
        M = np.zeros((n, n))
        for off, K in ((0, self.kp), (3 * self.kp, self.kv)):
            D = _diff_basis(K)
            for a in range(3):
                for k in range(K):
                    for i in range(K):
                        M[off + 3 * k + a, off + 3 * i + a] = D[k, i]
        ib = self.ib
        M[ib, ib] = 1.0
        M[ib + 1:ib + 1 + self.kd, ib + 1:ib + 1 + self.kd] = _diff_basis(self.kd)
        if self.has_delta:
            M[-1, -1] = 1.0
        return M

    # ------------------------------------------------------------------ paper-basis matrices
    def paper_transition(self):
        """F in the paper's lag basis."""
        n, T = self.n, self.T
        F = np.zeros((n, n))
        for off, K, h in ((0, self.kp, self.hp), (3 * self.kp, self.kv, self.hv)):
            for a in range(3):
                for k in range(K):
                    F[off + a, off + 3 * k + a] = h[k]
                for k in range(1, K):
                    F[off + 3 * k + a, off + 3 * (k - 1) + a] = 1.0
        ib, kd = self.ib, self.kd
        F[ib, ib] = 1.0
        F[ib, ib + 1] = T
        for k in range(kd):
            F[ib + 1, ib + 1 + k] = self.hd[k]
        for k in range(1, kd):
            F[ib + 1 + k, ib + k] = 1.0
        if self.has_delta:
            F[ib, n - 1] = T
            F[n - 1, n - 1] = 1.0
        return F

    def manoeuvre_noise(self):
        """QB in the difference basis: jumps of position, velocity and acceleration (and clock drift).

        A manoeuvre changes the derivatives of the trajectory, so QB is specified as independent jumps of
        position (q_manoeuvre_pos_m2), velocity (q_manoeuvre_vel_m2s2) and acceleration
        (q_manoeuvre_acc_m2s4): on the position PPF the k-th backward difference (~ T^k times the k-th
        derivative) gets (T^k)^2 times the variance of the k-th derivative jump, on the velocity PPF the
        first difference gets T^2 q_acc; the clock drift gets q_manoeuvre_clock.
        """
        pc, T = self.vcfg.polynomial, self.T
        q = np.zeros(self.n)
        deriv = [pc.q_manoeuvre_pos_m2, pc.q_manoeuvre_vel_m2s2, pc.q_manoeuvre_acc_m2s4]
        for i in range(min(self.kp, 3)):
            q[3 * i:3 * i + 3] = deriv[i] * T ** (2 * i)
        iv = 3 * self.kp
        for i in range(min(self.kv, 2)):
            q[iv + 3 * i:iv + 3 * i + 3] = deriv[1 + i] * T ** (2 * i)
        q[self.ib + 1] = pc.q_manoeuvre_clock
        return np.diag(q)

    def paper_manoeuvre_noise(self):
        """QB expressed in the paper's lag basis (for reference)."""
        M = self._M
        return M @ self.manoeuvre_noise() @ M.T

    def paper_process_noise(self):
        """Q in the paper's lag basis: zero except the code-minus-carrier drift (q_code_carrier_drift T)."""
        q = np.zeros(self.n)
        if self.has_delta:
            q[-1] = float(self.vcfg.q_code_carrier_drift) * self.T
        return np.diag(q)

    # ------------------------------------------------------------------ conversions
    def to_paper(self, x):
        """A state vector of the difference basis in the paper's lag basis (x_lag = M y)."""
        return self._M @ x

    def from_paper(self, x_paper):
        """A state vector of the paper's lag basis in the difference basis (y = M^-1 x_lag)."""
        return self._Minv @ x_paper

    def matrices(self):
        """(F, Q, QB) for one epoch of T seconds, in the difference basis the filter runs in (F = M^-1 F_lag M)."""
        Mi, M = self._Minv, self._M
        F = Mi @ self.paper_transition() @ M
        F[np.abs(F) < 1e-12] = 0.0
        return F, Mi @ self.paper_process_noise() @ Mi.T, self.manoeuvre_noise()

    def initial(self, r, v, b, d, delta, sig):
        """Lags consistent with constant velocity / drift; the difference states get the uncertainty of an
        unknown acceleration (5 m/s^2) / drift rate (0.1 m/s^2) over one epoch."""
        T, n = self.T, self.n
        xp = np.zeros(n)
        for k in range(self.kp):
            xp[3 * k:3 * k + 3] = np.asarray(r) - k * T * np.asarray(v)
        for k in range(self.kv):
            xp[3 * self.kp + 3 * k:3 * self.kp + 3 * k + 3] = v
        ib = self.ib
        xp[ib] = b
        xp[ib + 1:ib + 1 + self.kd] = d
        if self.has_delta:
            xp[-1] = delta
        x = self.from_paper(xp)
        var = np.zeros(n)
        acc, ddot = 5.0, 0.1
        for i in range(self.kp):
            var[3 * i:3 * i + 3] = [sig["pos"] ** 2, (sig["vel"] * T) ** 2, (acc * T * T) ** 2][min(i, 2)] \
                if i < 3 else 0.0
        for i in range(self.kv):
            var[3 * self.kp + 3 * i:3 * self.kp + 3 * i + 3] = [sig["vel"] ** 2, (acc * T) ** 2][min(i, 1)] \
                if i < 2 else 0.0
        var[ib] = sig["b"] ** 2
        var[ib + 1] = sig["d"] ** 2
        if self.kd > 1:
            var[ib + 2] = (ddot * T) ** 2
        if self.has_delta:
            var[-1] = sig["delta"] ** 2
        return x, np.diag(var)

    def describe(self):
        """One line for the log: the PPF coefficients and the chi-square threshold."""
        return (f"polynomial VDFLL: h_pos {self.hp.tolist()}, h_vel {self.hv.tolist()}, chi2 threshold "
                f"{self.chi2_threshold:g}")
