"""KF-PLL: steady-state loop bandwidth of the Kalman filter with its Q/R against the analytic value."""
import math

import numpy as np
import pytest

from receiver.schema import load_receiver_config
from receiver.gnss.signals import L1_HZ
from receiver.tracking.carrier import REGISTRY, make_carrier_loop
from receiver.tracking.loops.common import (atan_variance_cycles2, butterworth_bn_factor, clock_q,
                                            continuous_bandwidth, loop_noise_bandwidth_discrete,
                                            steady_state_gain)
from receiver.tracking.loops.kfpll import KFPLL, kf_matrices
from receiver.gnss.signals import C_LIGHT


def test_registry_and_config():
    for v in ("cpll_atan", "ekf", "pli_ekf", "kf", "adaptive_kf"):
        cfg = load_receiver_config(overrides=[f"tracking.carrier.variant={v}"])
        loop = make_carrier_loop(cfg.tracking.carrier.variant, cfg.tracking)
        assert loop.name == v and not loop.builtin and v in REGISTRY


def test_butterworth_factors():
    # closed forms: 2nd order 3/(4 sqrt 2), 3rd order 5/6 (continuous steady-state KF loops)
    assert butterworth_bn_factor(2) == pytest.approx(3 / (4 * math.sqrt(2)), rel=1e-6)
    assert butterworth_bn_factor(3) == pytest.approx(5 / 6, rel=1e-6)


@pytest.mark.parametrize("T,cn0_db,jerk", [(1e-3, 35.0, 4.0), (5e-3, 35.0, 4.0), (1e-3, 30.0, 50.0),
                                           (10e-3, 40.0, 0.02)])
def test_kf_bandwidth_jerk_only(T, cn0_db, jerk):
    """White-jerk Q, ATAN-variance R: the steady-state KF-PLL is a 3rd-order loop with
    omega0 = (q / r)^(1/6), r = R T, Bn = 5/6 omega0 (analytic) -- within 10 %."""
    phi, H, Q = kf_matrices(T, L1_HZ, 0.0, 0.0, jerk)
    R = atan_variance_cycles2(10 ** (cn0_db / 10), T)
    K, _ = steady_state_gain(phi, H, Q, R)
    bn = loop_noise_bandwidth_discrete(phi, H, K, T)
    q = jerk * (L1_HZ / C_LIGHT) ** 2
    w0 = (q / (R * T)) ** (1 / 6)
    assert bn * T < 0.1
    assert bn == pytest.approx(5 / 6 * w0, rel=0.10)


@pytest.mark.parametrize("T", [1e-3, 5e-3])
def test_kf_bandwidth_with_clock(T):
    """Full Q (oscillator h0, h_-2 + jerk): discrete steady-state bandwidth vs the continuous Riccati
    solution of the same model -- within 10 %."""
    h0, h_2, jerk, cn0 = 1.2e-20, 2e-22, 4.0, 10 ** 3.5
    loop = KFPLL(None, cn0_dbhz=35.0, jerk_psd=jerk, h0=h0, h_2=h_2, window=20, cn0_tau_s=0.5)
    K, _ = loop.steady_state(T)
    phi, H, Q = kf_matrices(T, L1_HZ, h0, h_2, jerk)
    bn = loop_noise_bandwidth_discrete(phi, H, K, T)
    cq = clock_q(1.0, h0, h_2, L1_HZ)
    qdiag = [h0 / 2 * L1_HZ ** 2, 2 * math.pi ** 2 * h_2 * L1_HZ ** 2, jerk * (L1_HZ / C_LIGHT) ** 2]
    assert qdiag[1] == pytest.approx(cq[1, 1])
    bn_c = continuous_bandwidth(3, qdiag, atan_variance_cycles2(cn0, T) * T)
    assert bn == pytest.approx(bn_c, rel=0.10)


def test_adaptive_kf_scales_q_and_tracks_cn0():
    from receiver.sim.corrsim import CorrScenario, run
    cfg = load_receiver_config(overrides=["tracking.carrier.clock_h0=1.2e-20", "tracking.carrier.clock_h_2=2.0e-22"])
    loop = make_carrier_loop("adaptive_kf", cfg.tracking)
    out = run(loop, CorrScenario(duration_s=6.0, t_coh_ms=5, cn0_dbhz=32.0, h0=1.2e-20, h_2=2e-22,
                                 carrier_hz=L1_HZ))
    assert loop.lam >= 1.0
    assert np.nanmean(out["cn0_est"][-200:]) == pytest.approx(32.0, abs=1.5)    # NWPR C/N0 -> R_k


@pytest.mark.parametrize("first", [True, False])
def test_compiled_kf_step_equals_the_numpy_reference(first):
    from receiver.tracking.loops.kfpll import kf_step, kf_step_numpy
    rng = np.random.default_rng(3)
    for T in (1e-3, 10e-3):
        phi, H, Q = kf_matrices(T, L1_HZ, 2e-19, 2e-20, 4.0)
        M = rng.standard_normal((3, 3))
        P0 = M @ M.T * 0.01 + np.diag([1e-4, 1.0, 100.0])
        s0 = np.array([0.3, 1200.0, -3.0])
        s1, P1, s2, P2 = s0.copy(), P0.copy(), s0.copy(), P0.copy()
        kf_step(s1, P1, phi, H, Q, 0.02, 1e-3, 2.5, first)
        kf_step_numpy(s2, P2, phi, H, Q, 0.02, 1e-3, 2.5, first)
        assert np.allclose(s1, s2, rtol=1e-13, atol=1e-12)
        assert np.allclose(P1, P2, rtol=1e-10, atol=1e-12 * np.abs(P2).max())
