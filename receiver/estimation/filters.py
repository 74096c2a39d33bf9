"""Model-agnostic Kalman filters: linear KF, EKF, cubature KF and square-root cubature KF.

All filters hold a state ``x`` (n,) and a covariance ``P`` (n, n) and expose ``predict`` and ``update``.
The models are passed at every call, so the same filter object can be used with a measurement set that
changes from epoch to epoch (satellites rising and setting):

* ``f(x)`` / ``h(x)``: process and measurement functions.  For the cubature filters they are applied to
  every cubature point; with ``vectorized=True`` they receive all points at once as an (m, n) array and
  must return (m, n) / (m, p).
* ``F`` / ``H``: Jacobians for the EKF, either arrays or callables of ``x``; ``f=None`` means the linear
  model ``F x``.

Cubature Kalman filter (Arasaratnam & Haykin, IEEE TAC 54(6), 2009): third-degree spherical-radial rule
with m = 2n points  x + S xi_i, xi_i = +-sqrt(n) e_i, equal weights 1/m, S a square root of P.
``CubatureKalmanFilter`` factors P by Cholesky at every step (and fails when round-off makes P
indefinite); ``SquareRootCubatureKalmanFilter`` propagates S itself and obtains every factor by a QR
decomposition, S = Tria([...]) with Tria(A) = R^T where A^T = QR, so S S^T stays positive semi-definite
by construction.
"""
from __future__ import annotations

import numpy as np


class FilterDivergence(np.linalg.LinAlgError):
    """The covariance lost positive definiteness (Cholesky failed) or became non-finite."""


def tria(A: np.ndarray) -> np.ndarray:
    """Lower-triangular S with S S^T = A A^T, from the QR decomposition of A^T (S = R^T)."""
    r = np.linalg.qr(A.T, mode="r")
    S = r.T
    n = A.shape[0]
    if S.shape[1] < n:                       # fewer columns than rows: pad (rank-deficient factor)
        S = np.hstack([S, np.zeros((n, n - S.shape[1]))])
    # fix the signs so the diagonal is non-negative (unique factor, easier to compare)
    sign = np.where(np.diag(S) < 0, -1.0, 1.0)
    return S * sign[None, :]


def solve_triangular(T: np.ndarray, B: np.ndarray, lower: bool) -> np.ndarray:
    """Solve T X = B for triangular T.

    Small systems are solved by plain substitution: LAPACK's threaded trsm in OpenBLAS can be ~50x
    slower than that for 4x4 systems when the other cores are busy.
    """
    n = T.shape[0]
    if n > 32:
        import scipy.linalg as sla          # (not at import: ~0.25 s at start-up)
        return sla.solve_triangular(T, B, lower=lower)
    B = np.array(B, dtype=float, copy=True)
    vec = B.ndim == 1
    if vec:
        B = B[:, None]
    X = np.empty_like(B)
    rows = range(n) if lower else range(n - 1, -1, -1)
    for i in rows:
        acc = B[i] - (T[i, :i] @ X[:i] if lower else T[i, i + 1:] @ X[i + 1:])
        X[i] = acc / T[i, i]
    return X[:, 0] if vec else X


def _as_matrix(M, x):
    return np.asarray(M(x) if callable(M) else M, dtype=float)


def _chol(P: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(P)):
        raise FilterDivergence("covariance is not finite")
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        raise FilterDivergence("covariance is not positive definite (Cholesky failed)") from None


def _cov(M, n: int) -> np.ndarray:
    """Noise covariance given as a scalar (times identity), a diagonal vector or a matrix."""
    M = np.asarray(M, float)
    if M.ndim == 0:
        return M * np.eye(n)
    if M.ndim == 1:
        return np.diag(M)
    return M


def _psd_sqrt(M: np.ndarray | None, n: int) -> np.ndarray:
    """A square root of a noise covariance (Cholesky; eigen-decomposition for singular PSD input)."""
    if M is None:
        return np.zeros((n, n))
    M = _cov(M, n)
    if np.count_nonzero(M - np.diag(np.diag(M))) == 0:
        return np.diag(np.sqrt(np.clip(np.diag(M), 0.0, None)))
    try:
        return np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (M + M.T))
        return V * np.sqrt(np.clip(w, 0.0, None))[None, :]


class _Base:
    def __init__(self, x0, P0):
        self.x = np.array(x0, dtype=float).ravel()
        P0 = np.atleast_2d(np.asarray(P0, float))
        if P0.shape != (self.n, self.n):
            raise ValueError(f"P0 must be {self.n}x{self.n}")
        self._P = 0.5 * (P0 + P0.T)
        self.innovation = None            # last z - z_pred
        self.innovation_cov = None        # last innovation covariance

    @property
    def n(self) -> int:
        return self.x.size

    @property
    def P(self) -> np.ndarray:
        return self._P

    @P.setter
    def P(self, value):
        self._P = np.asarray(value, float)

    def _propagate(self, F, Q):
        """P <- F P F^T (+ Q), symmetrised (KF and EKF)."""
        P = F @ self._P @ F.T
        if Q is not None:
            P = P + _cov(Q, self.n)
        self._P = 0.5 * (P + P.T)

    def _correct(self, y, H, R):
        """Measurement update with innovation y, (linearised) H and R (KF and EKF)."""
        S = H @ self._P @ H.T + R
        K = np.linalg.solve(S, H @ self._P).T           # P H^T S^-1 (S symmetric)
        self.x = self.x + K @ y
        P = self._P - K @ S @ K.T
        self._P = 0.5 * (P + P.T)
        self.innovation, self.innovation_cov = y, S
        return self.x


class KalmanFilter(_Base):
    """Linear Kalman filter: x_k = F x_{k-1} + w, z = H x + v."""

    def predict(self, F, Q=None, B=None, u=None):
        """Time update x <- F x (+ B u), P <- F P F^T + Q; returns the predicted state."""
        F = np.asarray(F, float)
        self.x = F @ self.x
        if B is not None and u is not None:
            self.x = self.x + np.asarray(B, float) @ np.asarray(u, float)
        self._propagate(F, Q)
        return self.x

    def update(self, z, H, R):
        """Measurement update with z = H x + v (R: scalar, diagonal vector or matrix); returns the updated state."""
        H = np.atleast_2d(np.asarray(H, float))
        z = np.atleast_1d(np.asarray(z, float))
        return self._correct(z - H @ self.x, H, _cov(R, z.size))


class ExtendedKalmanFilter(_Base):
    """EKF: nonlinear f, h linearised at the current estimate (Jacobians F, H)."""

    def predict(self, f=None, F=None, Q=None):
        """Time update x <- f(x) (F x when f is None), P <- F P F^T + Q with the Jacobian F; returns the state."""
        n = self.n
        Fm = np.eye(n) if F is None else _as_matrix(F, self.x)
        self.x = np.asarray(f(self.x), float) if f is not None else Fm @ self.x
        self._propagate(Fm, Q)
        return self.x

    def update(self, z, h, H, R):
        """Measurement update, innovation z - h(x) (H x when h is None) with the Jacobian H; returns the state."""
        z = np.atleast_1d(np.asarray(z, float))
        Hm = np.atleast_2d(_as_matrix(H, self.x))
        zp = np.atleast_1d(np.asarray(h(self.x), float)) if h is not None else Hm @ self.x
        return self._correct(z - zp, Hm, _cov(R, z.size))


class CubatureKalmanFilter(_Base):
    """Cubature Kalman filter (Arasaratnam & Haykin 2009), Cholesky-factored covariance."""

    def __init__(self, x0, P0, vectorized: bool = False):
        super().__init__(x0, P0)
        self.vectorized = vectorized
        n = self.n
        self.xi = np.sqrt(n) * np.vstack([np.eye(n), -np.eye(n)])     # (2n, n) unit cubature points
        self.m = 2 * n

    def _apply(self, fun, pts):
        if self.vectorized:
            return np.atleast_2d(np.asarray(fun(pts), float)).reshape(len(pts), -1)
        return np.array([np.atleast_1d(np.asarray(fun(p), float)) for p in pts])

    def points(self, x, S):
        """Cubature points x + S xi_i as rows of an (2n, n) array."""
        return x[None, :] + self.xi @ S.T

    def predict(self, f=None, Q=None):
        """Time update through the cubature points of f (f None: state unchanged, P grows by Q); returns the state."""
        if f is None:                        # identity dynamics: mean unchanged, P grows by Q
            if Q is not None:
                self._P = self._P + _cov(Q, self.n)
            return self.x
        S = _chol(self._P)
        Xs = self._apply(f, self.points(self.x, S))
        x = Xs.mean(axis=0)
        D = Xs - x
        P = D.T @ D / self.m
        if Q is not None:
            P = P + _cov(Q, self.n)
        self.x, self._P = x, 0.5 * (P + P.T)
        return self.x

    def update(self, z, h, R):
        """Measurement update through the cubature points of h (R: scalar, diagonal or matrix); returns the state."""
        z = np.atleast_1d(np.asarray(z, float))
        S = _chol(self._P)
        X = self.points(self.x, S)
        Z = self._apply(h, X)
        zp = Z.mean(axis=0)
        dX = X - self.x
        dZ = Z - zp
        Pzz = dZ.T @ dZ / self.m + _cov(R, z.size)
        Pxz = dX.T @ dZ / self.m
        W = np.linalg.solve(Pzz, Pxz.T).T
        y = z - zp
        self.x = self.x + W @ y
        P = self._P - W @ Pzz @ W.T
        self._P = 0.5 * (P + P.T)
        self.innovation, self.innovation_cov = y, Pzz
        return self.x


class SquareRootCubatureKalmanFilter(CubatureKalmanFilter):
    """Square-root CKF: propagates a lower-triangular S (P = S S^T); every factor comes from QR.

    Time update:   S- = Tria([chi*, S_Q]),   chi* = (X*_i - x-) / sqrt(m)
    Measurement:   S_zz = Tria([Z, S_R]),    P_xz = chi Z^T,   W = P_xz S_zz^-T S_zz^-1
                   S = Tria([chi - W Z, W S_R])
    Noise square roots can be given directly (SQ, SR) or as covariances (Q, R).
    """

    def __init__(self, x0, P0=None, vectorized: bool = False, S0=None):
        if P0 is None and S0 is None:
            raise ValueError("give P0 or S0")
        n = np.asarray(x0).size
        if S0 is None:
            P0 = np.atleast_2d(np.asarray(P0, float))
            S0 = _psd_sqrt(P0, n)
        S0 = np.atleast_2d(np.asarray(S0, float))
        super().__init__(x0, S0 @ S0.T, vectorized)
        self.S = tria(S0)

    @property
    def P(self) -> np.ndarray:
        """Covariance S S^T (setting it stores a square root of the value)."""
        return self.S @ self.S.T

    @P.setter
    def P(self, value):
        self.S = _psd_sqrt(np.asarray(value, float), self.n)

    def predict(self, f=None, Q=None, SQ=None):
        """Time update of x and the square root S through the cubature points of f (f None: S grows by SQ);
        noise given as Q or its square root SQ.  Returns the predicted state; FilterDivergence if S is non-finite."""
        n = self.n
        SQ = _psd_sqrt(Q, n) if SQ is None else np.atleast_2d(np.asarray(SQ, float))
        if f is None:
            self.S = tria(np.hstack([self.S, SQ]))
            return self.x
        Xs = self._apply(f, self.points(self.x, self.S))
        x = Xs.mean(axis=0)
        chi = (Xs - x).T / np.sqrt(self.m)
        self.x = x
        self.S = tria(np.hstack([chi, SQ]))
        if not np.all(np.isfinite(self.S)):
            raise FilterDivergence("square-root covariance is not finite")
        return self.x

    def update(self, z, h, R=None, SR=None):
        """Measurement update of x and S with the cubature points of h (noise as R or its square root SR);
        returns the state; FilterDivergence on non-finite values."""
        z = np.atleast_1d(np.asarray(z, float))
        p = z.size
        SR = _psd_sqrt(R, p) if SR is None else np.atleast_2d(np.asarray(SR, float))
        X = self.points(self.x, self.S)
        Z = self._apply(h, X)
        zp = Z.mean(axis=0)
        sq = np.sqrt(self.m)
        chi = (X - self.x).T / sq                       # (n, m)
        Zc = (Z - zp).T / sq                            # (p, m)
        Szz = tria(np.hstack([Zc, SR]))                 # (p, p) lower triangular
        Pxz = chi @ Zc.T                                # (n, p)
        # W = Pxz (Szz Szz^T)^-1 via two triangular solves
        tmp = solve_triangular(Szz, Pxz.T, lower=True)              # Szz^-1 Pxz^T
        W = solve_triangular(Szz.T, tmp, lower=False).T             # Pxz Szz^-T Szz^-1
        y = z - zp
        self.x = self.x + W @ y
        self.S = tria(np.hstack([chi - W @ Zc, W @ SR]))
        if not np.all(np.isfinite(self.S)) or not np.all(np.isfinite(self.x)):
            raise FilterDivergence("square-root filter produced non-finite values")
        self.innovation, self.innovation_cov = y, Szz @ Szz.T
        return self.x
