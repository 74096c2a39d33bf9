"""The vector filter's compiled linear algebra (receiver/tracking/vector/kalman.py: plain loops instead of
BLAS / LAPACK calls per epoch) against numpy on random filters."""
import numpy as np
import pytest

from receiver.tracking.vector.kalman import chi2_tag, kf_predict

LAY = np.array([0, 3, 6, 7, -1], np.int64)


def _filter(seed, n=8, m=8):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    P = A @ A.T + np.eye(n)
    E = rng.normal(size=(m, 3))
    E /= np.linalg.norm(E, axis=1)[:, None]
    return rng, P, E


def _numpy_tag(P, E, z, R, valid, kind):
    idx = np.flatnonzero(valid)
    i0, ic = (LAY[0], LAY[2]) if kind == 0 else (LAY[1], LAY[3])
    H = np.zeros((len(idx), P.shape[0]))
    for a, j in enumerate(idx):
        H[a, ic] = 1.0
        H[a, i0:i0 + 3] = -E[j]
    S = H @ P @ H.T + np.diag(R[idx])
    return float(z[idx] @ np.linalg.solve(S, z[idx]))


@pytest.mark.slow
@pytest.mark.parametrize("kind", [0, 1])
def test_chi2_tag_equals_the_numpy_quadratic_form(kind):
    rng, P, E = _filter(1)
    z = rng.normal(size=8)
    R = rng.uniform(1.0, 5.0, 8)
    valid = np.ones(8, np.bool_)
    valid[2] = False
    tag = chi2_tag(P, LAY, E, z, R, valid, kind)
    assert tag == pytest.approx(_numpy_tag(P, E, z, R, valid, kind), rel=1e-12) and tag > 0


def test_chi2_tag_of_an_indefinite_innovation_covariance_falls_back_to_the_solve():
    rng, P, E = _filter(2)
    z = rng.normal(size=8)
    R = np.full(8, -1e3)                  # S = H P H^T + R not positive definite: no Cholesky factor
    valid = np.ones(8, np.bool_)
    tag = chi2_tag(P, LAY, E, z, R, valid, 0)
    assert tag == pytest.approx(_numpy_tag(P, E, z, R, valid, 0), rel=1e-9)


def test_kf_predict_equals_numpy():
    rng, P, _ = _filter(3)
    F = np.eye(8) + 0.1 * rng.normal(size=(8, 8))
    Q = np.diag(rng.uniform(0.1, 1.0, 8))
    x = rng.normal(size=8)
    x_ref, P_ref = F @ x, F @ P @ F.T + Q
    kf_predict(x, P, F, Q)
    np.testing.assert_allclose(x, x_ref, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(P, P_ref, rtol=1e-12, atol=1e-12)


def test_kf_predict_of_a_sparse_transition_equals_the_dense_sums():
    """kf_predict sums over each row's non-zero entries only: with a sparse F (the polynomial filter's
    shape, a few entries per row) the result equals the dense sums in the same order bit for bit, i.e.
    numpy's product to rounding, and exactly for the rows that are identity rows."""
    rng, P, _ = _filter(4, n=12)
    F = np.eye(12)
    F[0, 3], F[0, 6], F[5, 9], F[11, 2] = 3.0, -1.0, 1e-3, -2.5      # a few couplings
    Q = np.zeros((12, 12))
    x = rng.normal(size=12)
    dense_x = np.array([sum(F[i, k] * x[k] for k in range(12)) for i in range(12)])
    FP = np.array([[sum(F[i, k] * P[k, j] for k in range(12)) for j in range(12)] for i in range(12)])
    dense_P = np.array([[Q[i, j] + sum(FP[i, k] * F[j, k] for k in range(12)) for j in range(12)]
                        for i in range(12)])
    kf_predict(x, P, F, Q)
    assert np.array_equal(x, dense_x) and np.array_equal(P, dense_P)
