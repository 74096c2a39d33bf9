"""EKF and PLI-EKF carrier loops: linearisation and the PLI = 1 reduction."""
import numpy as np
import pytest

from receiver.schema import load_receiver_config
from receiver.tracking.carrier import make_carrier_loop
from receiver.tracking.loops.ekf import jacobian, observation


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(0)
    for _ in range(20):
        s = rng.normal(size=4) * [3.0, 50.0, 10.0, 5.0]
        A, nco = rng.uniform(0.5, 100.0), rng.normal() * 3.0
        H = jacobian(s, A, nco)
        num = np.zeros((2, 4))
        for j in range(4):
            d = np.zeros(4)
            d[j] = 1e-6
            num[:, j] = (observation(s + d, A, nco) - observation(s - d, A, nco)) / 2e-6
        assert np.allclose(H, num, atol=1e-6 * A)


def _run(variant, seq, T=5e-3, **over):
    cfg = load_receiver_config(overrides=[f"tracking.carrier.{k}={v}" for k, v in over.items()])
    loop = make_carrier_loop(variant, cfg.tracking)
    loop.start(12.0, T)
    return np.array([loop.step(ip, qp, T, p1, p2) for ip, qp, p1, p2 in seq])


def test_pli_ekf_reduces_to_ekf_when_pli_is_one():
    rng = np.random.default_rng(1)
    n = 300
    ip = 200.0 + rng.normal(size=n) * 10
    p1 = ip / 2 + rng.normal(size=n)
    seq = [(ip[k], 0.0, complex(p1[k], 0.0), complex(ip[k] - p1[k], 0.0)) for k in range(n)]  # Q = 0
    a = _run("ekf", seq)
    b = _run("pli_ekf", seq)
    assert np.allclose(a, b, rtol=0, atol=1e-12)
    # with a phase error the PLI drops below 1 and the two filters differ
    seq2 = [(ip[k], 60.0 + rng.normal() * 10, complex(p1[k], 30.0), complex(ip[k] - p1[k], 30.0))
            for k in range(n)]
    assert not np.allclose(_run("ekf", seq2), _run("pli_ekf", seq2))


def test_pli_weight_range_paper_vs_ours():
    """pli_min = 1 pins the weight at 1 (PLI-EKF == EKF exactly); the paper's form (per-epoch PLI, pli_min =
    -1) lets the weight go negative when |Q| > |I| while ours (pli_min = 0) stops at 0."""
    rng = np.random.default_rng(3)
    n = 200
    ip = 100.0 + rng.normal(size=n) * 10
    qp = rng.normal(size=n) * 10
    qp[100:110] = 200.0                                  # a deep phase excursion: I^2 - Q^2 < 0
    seq = [(ip[k], qp[k], complex(ip[k] / 2, qp[k] / 2), complex(ip[k] / 2, qp[k] / 2)) for k in range(n)]
    assert np.allclose(_run("ekf", seq), _run("pli_ekf", seq, **{"ekf.pli_min": 1.0}), rtol=0, atol=1e-12)
    plis = {}
    for name, over in (("ours", {"ekf.pli_tau_s": 0.0}), ("paper", {"ekf.pli_tau_s": 0.0, "ekf.pli_min": -1.0})):
        cfg = load_receiver_config(overrides=[f"tracking.carrier.{k}={v}" for k, v in over.items()])
        loop = make_carrier_loop("pli_ekf", cfg.tracking)
        loop.start(12.0, 5e-3)
        plis[name] = []
        for ip_, qp_, p1, p2 in seq:
            loop.step(ip_, qp_, 5e-3, p1, p2)
            plis[name].append(loop.pli)
    assert min(plis["ours"]) == 0.0
    assert min(plis["paper"]) < -0.5
    assert not np.allclose(_run("pli_ekf", seq, **{"ekf.pli_tau_s": 0.0}),
                           _run("pli_ekf", seq, **{"ekf.pli_tau_s": 0.0, "ekf.pli_min": -1.0}))


@pytest.mark.parametrize("variant", ["ekf", "pli_ekf"])
def test_ekf_converges_on_a_frequency_offset(variant):
    from receiver.sim.corrsim import CorrScenario, phase_error_std_deg, run
    cfg = load_receiver_config()
    loop = make_carrier_loop(variant, cfg.tracking)
    sc = CorrScenario(duration_s=5.0, cn0_dbhz=40.0, h0=0.0, h_2=0.0, init_doppler_err_hz=5.0)
    out = run(loop, sc)
    assert abs(out["doppler"][-1] - out["doppler_true"][-1]) < 1.0
    assert phase_error_std_deg(out["err_cycles"], per_s=2.5, t=out["t"])[0] < 6.0


def test_compiled_ekf_step_equals_the_numpy_reference():
    from receiver.tracking.loops.common import taylor_phi, white_last_q
    from receiver.tracking.loops.ekf import ekf_step, ekf_step_numpy
    rng = np.random.default_rng(7)
    for T in (1e-3, 5e-3, 20e-3):
        phi, Q = taylor_phi(4, T), white_last_q(4, T, 3e4)
        M = rng.standard_normal((4, 4))
        P0 = M @ M.T + np.diag([0.1, 10.0, 100.0, 1000.0])
        s0 = rng.standard_normal(4) * [1.0, 600.0, 50.0, 5.0]
        args = (rng.normal() * 20, rng.normal() * 20, rng.normal() * 3, rng.normal() * 3, 4.0)
        s1, P1, post1 = s0.copy(), P0.copy(), np.zeros(4)
        s2, P2, post2 = s0.copy(), P0.copy(), np.zeros(4)
        ekf_step(s1, P1, phi, Q, *args, post1)
        ekf_step_numpy(s2, P2, phi, Q, *args, post2)
        assert np.allclose(s1, s2, rtol=1e-12, atol=1e-9)
        assert np.allclose(post1, post2, rtol=1e-12, atol=1e-9)
        assert np.allclose(P1, P2, rtol=1e-10, atol=1e-9 * np.abs(P2).max())
        assert not np.allclose(post1, s0)                 # the update did something
