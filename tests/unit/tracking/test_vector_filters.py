"""Vector-loop filter math: PPF coefficients, chi-square manoeuvre detection, adaptive R, discriminators."""
import numpy as np
import pytest

from receiver.config import build
from receiver.schema import RECEIVER_SCHEMA
from receiver.errors import UserError
from receiver.tracking.correlator import correlate, extend_code
from receiver.gnss.signals import C_LIGHT, CA_CHIP_RATE, L1_HZ, ca_code
from receiver.tracking.vector import REGISTRY, make_filter
from receiver.tracking.vector.discriminators import (code_discriminator, freq_disc_hz,
                                                     frequency_discriminator)
from receiver.tracking.vector.kalman import adapt_r, kf_predict, kf_update
from receiver.tracking.vector.polynomial import PolynomialFilter, ppf_coefficients


def vcfg(**over):
    return build(RECEIVER_SCHEMA, {"vector": over}).vector


# ------------------------------------------------------------------------------------------- PPF
@pytest.mark.parametrize("degree,taps,expect", [(1, 2, [2, -1]), (2, 3, [3, -3, 1]), (3, 4, [4, -6, 4, -1])])
def test_ppf_binomial_coefficients(degree, taps, expect):
    assert ppf_coefficients(degree, taps).tolist() == expect


@pytest.mark.parametrize("degree,taps", [(1, 2), (2, 3), (3, 4), (2, 6), (1, 5)])
def test_ppf_reproduces_polynomials_exactly(degree, taps):
    h = ppf_coefficients(degree, taps)
    n = np.arange(-20, 40)
    rng = np.random.default_rng(degree * 10 + taps)
    for _ in range(5):
        c = rng.integers(-50, 50, degree + 1)
        x = sum(ci * n.astype(float) ** i for i, ci in enumerate(c))     # integer-valued polynomial
        for k in range(taps, len(n) - 1):
            pred = float(np.dot(h, x[k::-1][:taps]))
            if taps == degree + 1:
                assert pred == x[k + 1]                                  # integer arithmetic: exact
            else:
                assert pred == pytest.approx(x[k + 1], rel=1e-12, abs=1e-9)
    # one degree higher is NOT reproduced (the predictor really is of degree L)
    x = n.astype(float) ** (degree + 1)
    assert abs(np.dot(h, x[30::-1][:taps]) - x[31]) > 0.5


def test_polynomial_transition_propagates_quadratic_position_and_linear_velocity():
    f = PolynomialFilter(vcfg(), 1e-3)
    assert f.n == 19 and f.layout().tolist() == [0, 9, 15, 16, 18]
    F = f.paper_transition()
    T = 1e-3
    a, v0, p0 = np.array([3.0, -2.0, 0.5]), np.array([10.0, 5.0, -1.0]), np.array([100.0, 200.0, 300.0])
    pos = lambda k: p0 + v0 * k * T + 0.5 * a * (k * T) ** 2          # noqa: E731
    vel = lambda k: v0 + a * k * T                                     # noqa: E731
    xp = np.concatenate([pos(0), pos(-1), pos(-2), vel(0), vel(-1), [7.0], [1.5, 1.4], [0.0]])
    for k in range(1, 200):
        xp = F @ xp
    assert np.allclose(xp[0:3], pos(199), atol=1e-8)
    assert np.allclose(xp[9:12], vel(199), atol=1e-10)
    assert xp[16] == pytest.approx(1.5 + 0.1 * 199)                    # drift: linear PPF
    # internal (backward-difference) basis: same filter, integer constant-derivative transition
    Fi, _, _ = f.matrices()
    x_int = f.from_paper(np.concatenate([pos(0), pos(-1), pos(-2), vel(0), vel(-1), [7.0], [1.5, 1.4],
                                         [0.0]]))
    for k in range(1, 200):
        x_int = Fi @ x_int
    assert np.allclose(f.to_paper(x_int), xp, atol=1e-8)
    assert np.array_equal(Fi[0:9, 0:9], np.kron(np.array([[1, 1, 1], [0, 1, 1], [0, 0, 1]]), np.eye(3)))


# ------------------------------------------------------------------------------------------- synthetic
LOS = np.array([[0.3, 0.4, 0.866], [-0.5, 0.2, 0.84], [0.7, -0.6, 0.39], [-0.2, -0.9, 0.39],
                [0.9, 0.1, 0.42], [-0.8, -0.3, 0.52], [0.1, 0.95, 0.3], [-0.6, 0.7, 0.39]])
LOS = LOS / np.linalg.norm(LOS, axis=1)[:, None]


def run_synthetic(filt, traj, n_epochs, sig_c, sig_f, R0=(None, None), seed=0, blocked=(), gate=0.0,
                  only=None):
    """Drive a filter with linear synthetic code/carrier measurements; returns per-epoch logs.

    blocked: channels whose discriminators output noise; only = (t0, channels): from t0 on only these
    channels have a measurement (the others are out of the update).
    """
    T = filt.T
    rng = np.random.default_rng(seed)
    F, Q, QB = filt.matrices()
    lay = filt.layout()
    r0, v0 = traj(0.0)
    x, P = filt.initial(r0, v0, 0.0, 0.0, 0.0, {"pos": 5.0, "vel": 0.5, "b": 5.0, "d": 0.5, "delta": 0.1})
    m = len(LOS)
    Rc = np.full(m, R0[0] if R0[0] is not None else filt.r_code)
    Rf = np.full(m, R0[1] if R0[1] is not None else filt.r_carr)
    N = filt.window
    W, WI, WN, WS = np.zeros((m, 2, N)), np.zeros(m, np.int64), np.zeros(m, np.int64), np.zeros((m, 2))
    valid = np.ones(m, np.bool_)
    diag = np.zeros((m, 8))
    out = {"tags": [], "fired": [], "vel_err": [], "Rc": [], "Rf": []}
    for k in range(1, n_epochs + 1):
        r, v = traj(k * T)
        kf_predict(x, P, F, Q)
        rh, vh, bh, dh, _ = filt.nav_state(x)
        zc = -LOS @ (r - rh) - bh + sig_c * rng.standard_normal(m)        # true b = d = 0
        zf = -LOS @ (v - vh) - dh + sig_f * rng.standard_normal(m)
        if only is not None and k * T >= only[0]:
            valid[:] = False
            valid[list(only[1])] = True
        for j in blocked:                         # no signal: the discriminators output noise
            zc[j] = rng.uniform(-220.0, 220.0)
            zf[j] = rng.uniform(-190.0, 190.0)
        tp, tv, fired = kf_update(x, P, lay, LOS, zc, zf, valid, Rc, Rf, QB, filt.chi2_threshold, diag, gate)
        adapt_r(filt.adaptive_form, valid, diag, W, WI, WN, WS, Rc, Rf, min(N, 100), filt.floor_code,
                filt.floor_carr)
        out["tags"].append((tp, tv))
        out["fired"].append(fired)
        out["vel_err"].append(np.linalg.norm(filt.nav_state(x)[1] - v))
        out["Rc"].append(Rc.copy())
        out["Rf"].append(Rf.copy())
    return {k: np.array(v) for k, v in out.items()}


@pytest.mark.slow
def test_chi2_detector_quiet_on_constant_acceleration_fires_on_step():
    sig_c, sig_f = 5.0, 2.0
    cfg = vcfg(r_code_m2=sig_c ** 2, r_carrier_m2s2=sig_f ** 2,
               polynomial={"chi2_threshold": 25.0, "adaptive_r": False})
    a = np.array([4.0, -3.0, 1.0])

    def const_acc(t):
        return np.array([10.0, 20.0, 0.0]) * t + 0.5 * a * t * t, np.array([10.0, 20.0, 0.0]) + a * t

    res = run_synthetic(PolynomialFilter(cfg, 1e-3), const_acc, 3000, sig_c, sig_f, seed=1)
    # chi-square(8) exceeds 25 with probability 0.16 %: allow a few false alarms, no systematic firing
    assert res["fired"][500:].mean() < 0.01
    assert np.median(res["tags"][500:, 1]) < 12.0

    t_step = 2.0
    jump = np.array([30.0, -20.0, 10.0])                 # acceleration step (m/s^2)

    def step(t):
        p, v = const_acc(t)
        if t > t_step:
            dt = t - t_step
            p, v = p + 0.5 * jump * dt * dt, v + jump * dt
        return p, v

    res2 = run_synthetic(PolynomialFilter(cfg, 1e-3), step, 3000, sig_c, sig_f, seed=1)
    k0 = int(t_step / 1e-3)
    fired_after = np.nonzero(res2["fired"][k0:])[0]
    # one 1-ms chi-square test sees the step once the velocity has drifted a few m/s off the PPF line
    assert len(fired_after) > 0 and fired_after[0] < 150          # detected within 150 ms
    # with the detector the velocity error after the step recovers; without it the pure PPF lags
    cfg_off = vcfg(r_code_m2=sig_c ** 2, r_carrier_m2s2=sig_f ** 2,
                   polynomial={"chi2_threshold": 0.0, "adaptive_r": False})
    res3 = run_synthetic(PolynomialFilter(cfg_off, 1e-3), step, 3000, sig_c, sig_f, seed=1)
    assert res2["vel_err"][-200:].mean() < 1.5
    assert res3["vel_err"][-200:].mean() > 5 * res2["vel_err"][-200:].mean()


@pytest.mark.parametrize("form", ["paper", "innovation", "residual"])
def test_adaptive_r_converges_to_true_noise_variance(form):
    sig_c, sig_f = 20.0, 5.0                              # true: 400 m^2, 25 (m/s)^2; start 1500 / 900
    cfg = vcfg(q_accel=1.0, adaptive_r={"window": 500, "form": form})
    filt = make_filter("adaptive_r", cfg)
    static = lambda t: (np.array([1.0, 2.0, 3.0]), np.zeros(3))      # noqa: E731
    res = run_synthetic(filt, static, 6000, sig_c, sig_f, seed=3)
    rc, rf = res["Rc"][-1], res["Rf"][-1]
    assert rc[0] == pytest.approx(400.0, rel=0.15) and rf[0] == pytest.approx(25.0, rel=0.15)
    assert np.mean(rc) == pytest.approx(400.0, rel=0.08)
    assert np.mean(rf) == pytest.approx(25.0, rel=0.08)
    assert res["Rc"][50, 0] == 1500.0                     # initial R until the window fills
    # a fixed-R filter keeps its (wrong) R
    fixed = run_synthetic(make_filter("fixed_r", cfg), static, 300, sig_c, sig_f, seed=3)
    assert np.all(fixed["Rc"] == 1500.0)


def test_registry_and_state_sizes():
    assert set(REGISTRY) == {"fixed_r", "adaptive_r", "polynomial", "cv"}
    assert make_filter("fixed_r", vcfg()).n == 9
    assert make_filter("fixed_r", vcfg(code_carrier_drift=False)).n == 8
    assert make_filter("adaptive_r", vcfg(motion_model="ca")).n == 12
    for name in ("cv", "polynomial"):                   # models of their own: motion_model is an error
        with pytest.raises(UserError, match="motion_model"):
            make_filter(name, vcfg(motion_model="ca"))
    assert make_filter("polynomial", vcfg(code_carrier_drift=False)).n == 18
    cv = make_filter("cv", vcfg(cv={"q_velocity": 0.1}))
    _, Q, _ = cv.matrices()
    assert np.allclose(np.diag(Q)[:8], [0.1] * 3 + [0.1] * 3 + [1e-7, 0.1])


# ------------------------------------------------------------------------------------------- discriminators
def _correlate(code_offset_chips, freq_hz, fs=2.6e6, prn=7, n_ms=1, spacing=0.5):
    n = int(round(fs * 1e-3 * n_ms))
    k = np.arange(n)
    code = ca_code(prn).astype(float)
    chips = 200.0 + code_offset_chips + k * CA_CHIP_RATE / fs
    sig = code[np.floor(chips).astype(int) % 1023] * np.exp(2j * np.pi * (freq_hz * k / fs + 0.3))
    ext = extend_code(ca_code(prn), 20)
    e, p, l, p1, p2 = correlate(sig.astype(np.complex64), 0, n, ext, 200.0, CA_CHIP_RATE / fs, spacing / 2,
                                0.0, 0.0)
    return abs(e), abs(l), p1, p2, n / fs


@pytest.mark.slow
@pytest.mark.parametrize("tau", [-0.15, -0.05, 0.0, 0.08, 0.2])
def test_code_discriminator_metres(tau):
    e, l, _, _, _ = _correlate(tau, 0.0)
    z = float(code_discriminator(e, l, 0.5))
    # signal leading the replica by tau chips = shorter pseudorange by tau c / f_code
    assert z == pytest.approx(-tau * C_LIGHT / CA_CHIP_RATE, abs=0.02 * C_LIGHT / CA_CHIP_RATE)


@pytest.mark.parametrize("df", [-400.0, -60.0, 25.0, 300.0])
def test_frequency_discriminator_half_interval_factor(df):
    _, _, p1, p2, t = _correlate(0.0, df, n_ms=1)
    assert freq_disc_hz(p1.real, p1.imag, p2.real, p2.imag, t) == pytest.approx(df, rel=0.03, abs=2.0)
    z = float(frequency_discriminator(p1.real, p1.imag, p2.real, p2.imag, t))
    assert z == pytest.approx(-df * C_LIGHT / L1_HZ, rel=0.03, abs=0.5)


@pytest.mark.slow
def test_innovation_gate_rejects_blocked_channel_noise():
    """Two channels without signal, fixed R: a 3-sigma gate keeps most of their noise out."""
    cfg = vcfg(q_accel=1.0, r_code_m2=400.0, r_carrier_m2s2=100.0)
    static = lambda t: (np.array([1.0, 2.0, 3.0]), np.zeros(3))      # noqa: E731
    free = run_synthetic(make_filter("fixed_r", cfg), static, 3000, 20.0, 10.0, seed=5, blocked=(2, 5))
    gated = run_synthetic(make_filter("fixed_r", cfg), static, 3000, 20.0, 10.0, seed=5, blocked=(2, 5),
                          gate=3.0)
    clean = run_synthetic(make_filter("fixed_r", cfg), static, 3000, 20.0, 10.0, seed=5)
    e_free, e_gated = free["vel_err"][500:].mean(), gated["vel_err"][500:].mean()
    e_clean = clean["vel_err"][500:].mean()
    assert e_gated < 0.7 * e_free
    assert e_gated < 2.0 * e_clean


# ------------------------------------------------------------------------------------------- kinematic models
def _van_loan(A, G, T):
    """Exact discretisation (Phi, Qd) of dx = A x dt + dw, E[dw dw^T] = G dt (Van Loan)."""
    from scipy.linalg import expm
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -A, G, A.T
    E = expm(M * T)
    Phi = E[n:, n:].T
    return Phi, Phi @ E[:n, n:]


@pytest.mark.parametrize("model", ["cv", "ca"])
def test_kinematic_transition_and_q_equal_the_continuous_model(model):
    T = 0.05                                            # long epoch: the T^5 terms are not negligible
    f = make_filter("fixed_r", vcfg(motion_model=model, q_accel=7.0, q_jerk=0.3, clock_class="tcxo"))
    f.T = T
    F, Q, _ = f.matrices()
    k = f.nk
    A = np.zeros((f.n, f.n))
    G = np.zeros((f.n, f.n))
    A[0:3, 3:6] = np.eye(3)
    if model == "ca":
        A[3:6, 6:9] = np.eye(3)
        G[6:9, 6:9] = 0.3 * np.eye(3)
    else:
        G[3:6, 3:6] = 7.0 * np.eye(3)
    A[k, k + 1] = 1.0                                   # db/dt = d + delta
    A[k, k + 2] = 1.0
    from receiver.tracking.vector.base import clock_psd
    sb, sd = clock_psd("tcxo")
    G[k, k], G[k + 1, k + 1] = sb, sd
    G[k + 2, k + 2] = f.vcfg.q_code_carrier_drift
    Phi, Qd = _van_loan(A, G, T)
    assert np.allclose(F, Phi, atol=1e-12)
    # the clock block keeps the two-state model (the delta random walk is not integrated into b)
    Qd[k, k + 2] = Qd[k + 2, k] = 0.0
    Qd[k, k] -= f.vcfg.q_code_carrier_drift * T ** 3 / 3.0
    assert np.allclose(Q, Qd, rtol=1e-9, atol=1e-15)
    # a constant acceleration is propagated exactly by the ca model
    if model == "ca":
        x = np.zeros(f.n)
        x[0:3], x[3:6], x[6:9] = [1.0, 2.0, 3.0], [10.0, -5.0, 0.0], [2.0, 1.0, -0.5]
        for _ in range(40):
            x = F @ x
        t = 40 * T
        assert np.allclose(x[0:3], np.array([1.0, 2.0, 3.0]) + np.array([10.0, -5.0, 0.0]) * t
                           + 0.5 * np.array([2.0, 1.0, -0.5]) * t * t, atol=1e-9)
        assert np.allclose(x[3:6], np.array([10.0, -5.0, 0.0]) + np.array([2.0, 1.0, -0.5]) * t, atol=1e-12)


def test_vertical_scale_shapes_q_in_the_local_level():
    from receiver.gnss.geodesy import enu_matrix, lla2ecef
    f = make_filter("adaptive_r", vcfg(q_accel=10.0, q_vertical_scale=0.001))
    r0 = np.asarray(lla2ecef(35.68, 139.77, 40.0), float)
    f.initial(r0, np.zeros(3), 0.0, 0.0, 0.0, {"pos": 1, "vel": 1, "b": 1, "d": 1, "delta": 1})
    _, Q, _ = f.matrices()
    E = enu_matrix(35.68, 139.77)
    qv = E @ Q[3:6, 3:6] @ E.T / f.T                    # velocity block in ENU, per second
    assert np.allclose(qv, np.diag([10.0, 10.0, 0.01]), atol=1e-9)
    iso = make_filter("adaptive_r", vcfg(q_accel=10.0))
    iso.initial(r0, np.zeros(3), 0.0, 0.0, 0.0, {"pos": 1, "vel": 1, "b": 1, "d": 1, "delta": 1})
    assert np.allclose(iso.matrices()[1][3:6, 3:6], 10.0 * iso.T * np.eye(3))


@pytest.mark.slow
@pytest.mark.parametrize("pair", [(0, 1), (2, 3), (0, 6)])
def test_constant_acceleration_model_carries_a_turn_through_two_satellites(pair):
    """50 m/s on a 600 m circle (4.2 m/s^2): 6 s with 8 satellites, then 2 s with two.  The cv model's
    velocity error grows with the unobserved centripetal acceleration; the ca model predicts it."""
    rad, spd = 600.0, 50.0
    w = spd / rad

    def turn(t):
        return (np.array([rad * np.sin(w * t), rad * (1 - np.cos(w * t)), 0.0]),
                np.array([spd * np.cos(w * t), spd * np.sin(w * t), 0.0]))

    err = {}
    for model in ("cv", "ca"):
        cfg = vcfg(motion_model=model, q_accel=10.0, q_jerk=1.0, r_code_m2=25.0, r_carrier_m2s2=0.25)
        res = run_synthetic(make_filter("fixed_r", cfg), turn, 8000, 5.0, 0.5, seed=2, only=(6.0, pair))
        err[model] = res["vel_err"][6000:].max()
        assert res["vel_err"][5000:6000].max() < 0.6         # all satellites: both models track the turn
    assert err["cv"] > 3.0
    assert err["ca"] < 1.5 and err["ca"] < 0.35 * err["cv"]
