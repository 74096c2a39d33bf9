"""Generic filters (receiver.leo.filters): KF, EKF, CKF and square-root CKF."""
import numpy as np
import pytest

from receiver.estimation.filters import (CubatureKalmanFilter, ExtendedKalmanFilter, FilterDivergence,
                                  KalmanFilter, SquareRootCubatureKalmanFilter, tria)


def _linear_model(rng, n=4, p=2):
    A = rng.standard_normal((n, n))
    F = np.eye(n) + 0.2 * A
    F /= 1.05 * np.max(np.abs(np.linalg.eigvals(F)))
    B = rng.standard_normal((n, n))
    Q = 0.05 * B @ B.T + 0.01 * np.eye(n)
    H = rng.standard_normal((p, n))
    C = rng.standard_normal((p, p))
    R = 0.2 * C @ C.T + 0.1 * np.eye(p)
    return F, Q, H, R


def test_tria_is_a_lower_triangular_square_root():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((4, 9))
    S = tria(A)
    assert np.allclose(S, np.tril(S))
    assert np.allclose(S @ S.T, A @ A.T, atol=1e-12)
    assert np.all(np.diag(S) >= 0)
    S2 = tria(rng.standard_normal((5, 2)))                 # fewer columns than rows
    assert S2.shape == (5, 5)


def test_ckf_equals_linear_kf_on_linear_gaussian_model():
    rng = np.random.default_rng(1)
    F, Q, H, R = _linear_model(rng)
    x0, P0 = rng.standard_normal(4), 3.0 * np.eye(4)
    kf = KalmanFilter(x0, P0)
    ckf = CubatureKalmanFilter(x0, P0)                     # per-point (non-vectorised) functions
    ekf = ExtendedKalmanFilter(x0, P0)
    x = rng.standard_normal(4)
    worst = 0.0
    for _ in range(300):
        x = F @ x + rng.multivariate_normal(np.zeros(4), Q)
        z = H @ x + rng.multivariate_normal(np.zeros(2), R)
        kf.predict(F, Q)
        ckf.predict(lambda s: F @ s, Q)
        ekf.predict(lambda s: F @ s, F, Q)
        kf.update(z, H, R)
        ckf.update(z, lambda s: H @ s, R)
        ekf.update(z, lambda s: H @ s, H, R)
        worst = max(worst, np.abs(kf.x - ckf.x).max(), np.abs(kf.P - ckf.P).max(),
                    np.abs(kf.x - ekf.x).max(), np.abs(kf.P - ekf.P).max())
    assert worst <= 1e-9
    # and the filter actually tracks the state
    assert np.linalg.norm(kf.x - x) < 5 * np.sqrt(np.trace(kf.P))


def _pendulum(dt=0.05, g=9.81):
    def f(X):                                              # vectorised: rows are states
        X = np.atleast_2d(X)
        return np.c_[X[:, 0] + dt * X[:, 1], X[:, 1] - dt * g * np.sin(X[:, 0])]

    def h(X):
        X = np.atleast_2d(X)
        return np.c_[np.sin(X[:, 0]), 0.3 * X[:, 1] + 0.1 * X[:, 0] ** 2]
    return f, h


@pytest.mark.slow
def test_sqrt_ckf_equals_ckf_over_1000_steps():
    rng = np.random.default_rng(2)
    f, h = _pendulum()
    Q = np.diag([1e-4, 1e-3])
    R = np.diag([0.05 ** 2, 0.05 ** 2])
    x0, P0 = np.array([0.8, 0.0]), np.diag([0.2, 0.5])
    ckf = CubatureKalmanFilter(x0, P0, vectorized=True)
    sr = SquareRootCubatureKalmanFilter(x0, P0, vectorized=True)
    x = np.array([1.0, 0.2])
    dx = dP = 0.0
    for _ in range(1000):
        x = f(x)[0] + rng.multivariate_normal(np.zeros(2), Q)
        z = h(x)[0] + rng.multivariate_normal(np.zeros(2), R)
        ckf.predict(f, Q)
        sr.predict(f, Q)
        ckf.update(z, h, R)
        sr.update(z, h, R)
        dx = max(dx, np.abs(ckf.x - sr.x).max())
        dP = max(dP, np.abs(ckf.P - sr.P).max())
    assert dx <= 1e-8 and dP <= 1e-8
    assert np.abs(sr.x - x).max() < 0.5                     # it is a working filter, not two wrong ones


def test_sqrt_ckf_survives_where_cholesky_of_p_fails():
    # near-perfect measurements of x1 + x2 and x1 - x2 with a very wide prior: the conventional
    # update P - W Pzz W^T cancels catastrophically and leaves an indefinite P
    x0, P0 = np.zeros(2), np.diag([1e10, 1e10])
    truth = np.array([3.0, -2.0])
    h_sum = (lambda s: np.array([s[0] + s[1]]))
    h_diff = (lambda s: np.array([s[0] - s[1]]))
    ckf = CubatureKalmanFilter(x0, P0)
    sr = SquareRootCubatureKalmanFilter(x0, P0)
    ckf.update(h_sum(truth), h_sum, 1e-14)
    sr.update(h_sum(truth), h_sum, 1e-14)
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(ckf.P)
    with pytest.raises(FilterDivergence):
        ckf.update(h_diff(truth), h_diff, 1e-14)
    # the square-root filter keeps running and resolves the state
    for k in range(50):
        sr.predict(lambda s: s, np.diag([1e-12, 1e-12]))
        hh = h_diff if k % 2 == 0 else h_sum
        sr.update(hh(truth), hh, 1e-14)
    assert np.allclose(sr.x, truth, atol=1e-5)
    assert np.all(np.isfinite(sr.S)) and np.all(np.linalg.eigvalsh(sr.P) >= 0)


def test_filters_accept_scalar_and_diagonal_noise_and_identity_dynamics():
    x0, P0 = np.array([1.0, 2.0]), np.diag([4.0, 9.0])
    a = CubatureKalmanFilter(x0, P0)
    b = SquareRootCubatureKalmanFilter(x0, P0)
    a.predict(None, [0.5, 0.25])
    b.predict(None, np.diag([0.5, 0.25]))
    assert np.allclose(a.P, np.diag([4.5, 9.25])) and np.allclose(b.P, a.P)
    H = np.array([[1.0, 0.0]])
    a.update([1.5], lambda s: H @ s, 0.3)
    b.update([1.5], lambda s: H @ s, np.array([[0.3]]))
    kf = KalmanFilter(x0, P0)
    kf.predict(np.eye(2), np.diag([0.5, 0.25]))
    kf.update([1.5], H, 0.3)
    assert np.allclose(a.x, kf.x) and np.allclose(b.x, kf.x) and np.allclose(b.P, kf.P)
    assert a.innovation.shape == (1,) and a.innovation_cov.shape == (1, 1)


def test_triangular_solver_matches_scipy():
    import scipy.linalg as sla
    from receiver.estimation.filters import solve_triangular
    rng = np.random.default_rng(4)
    for n in (1, 3, 7, 40):
        T = np.tril(rng.standard_normal((n, n))) + 3 * np.eye(n)
        B = rng.standard_normal((n, 2))
        assert np.allclose(solve_triangular(T, B, True), sla.solve_triangular(T, B, lower=True))
        assert np.allclose(solve_triangular(T.T, B[:, 0], False),
                           sla.solve_triangular(T.T, B[:, 0], lower=False))
