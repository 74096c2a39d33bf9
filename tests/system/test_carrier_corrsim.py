"""The correlator-level simulator against theory and against the IF-level receiver + simulator."""
import math

import numpy as np
import pytest
from scipy.integrate import quad

from receiver.schema import load_receiver_config
from receiver.sim.corrsim import (CorrScenario, if_phase_error, loss_of_lock_probability, phase_error_std_deg,
                              run)
from receiver.tracking.carrier import make_carrier_loop

from repo_paths import ROOT as REPO
H0, H_2 = 1.2e-20, 2e-22
OVR = ["tracking.carrier.clock_h0=1.2e-20", "tracking.carrier.clock_h_2=2.0e-22"]


def cpll_theory_deg(bn, cn0_db, T, fc, h0, h_2):
    """Thermal (ATAN, squaring loss) + oscillator jitter of the continuous 3rd-order loop."""
    cn0 = 10 ** (cn0_db / 10)
    th = bn / cn0 * (1 + 1 / (2 * T * cn0))
    w0 = bn / 0.7845

    def g(f):
        s = 2j * math.pi * f
        h = (2.4 * w0 * s ** 2 + 1.1 * w0 ** 2 * s + w0 ** 3) / (s ** 3 + 2.4 * w0 * s ** 2 + 1.1 * w0 ** 2 * s
                                                                 + w0 ** 3)
        return fc ** 2 * (h0 / (4 * math.pi ** 2 * f ** 2) + h_2 / (4 * math.pi ** 2 * f ** 4)) * abs(1 - h) ** 2
    osc = sum(quad(g, a, b, limit=200)[0] for a, b in [(1e-4, 1), (1, 10), (10, 100), (100, 1e4)])
    return math.degrees(math.sqrt(th + osc * (2 * math.pi) ** 2))


def test_cpll_matches_theory():
    cfg = load_receiver_config(overrides=OVR)
    stds = []
    for seed in range(3):
        out = run(make_carrier_loop("cpll_atan", cfg.tracking),
                  CorrScenario(duration_s=20.0, cn0_dbhz=40.0, h0=H0, h_2=H_2, seed=seed))
        stds.append(phase_error_std_deg(out["err_cycles"], per_s=17.0, t=out["t"])[0])
    theory = cpll_theory_deg(15.0, 40.0, 5e-3, 1561.098e6, H0, H_2)
    assert np.mean(stds) == pytest.approx(theory, rel=0.15)


@pytest.fixture(scope="module")
def if_runs(tmp_path_factory):
    from receiver.pipeline import run as rx_run
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("scint")
    res = {}
    for name, scint in (("clean", "false"), ("scint", "true")):
        out = d / f"{name}.bin"
        simulate(str(REPO / "configs/scenarios/scint_if_check.yaml"), str(out),
                 overrides=[f"scintillation.enabled={scint}"], progress=False)
        cfg = load_receiver_config(REPO / "configs/carrier_scint_b1i.yaml",
                                   [f"input.path={out}", f"output.path={d / (name + '.h5')}"])
        rx_run(cfg, quiet=True, log=lambda *a: None)
        res[name] = if_phase_error(d / (name + ".h5"), str(out)[:-4] + ".truth.h5", 5)
    return res


def _corr_stats(s4, sp, seeds):
    cfg = load_receiver_config(overrides=OVR)
    h0 = h_2 = 0.0                        # the IF scenario has an ideal oscillator
    std, lol = [], []
    for seed in seeds:
        out = run(make_carrier_loop("cpll_atan", cfg.tracking),
                  CorrScenario(duration_s=8.0, cn0_dbhz=40.0, h0=h0, h_2=h_2, s4=s4, sigma_phi=sp, tau0_s=0.5,
                               seed=seed))
        sel = out["t"] >= 2.0
        std.append(phase_error_std_deg(out["err_cycles"][sel], per_s=5.5, t=out["t"][sel])[0])
        lol.append(loss_of_lock_probability(out["ip"][sel], out["qp"][sel], 5e-3))
    return np.mean(std), np.mean(lol), std


def test_if_level_matches_correlator_level(if_runs):
    # no scintillation: the same thermal + oscillator statistics (IF: one 6 s realisation)
    t, err, ip, qp, T = if_runs["clean"]
    sel = t >= 2.0
    if_std = phase_error_std_deg(err[sel], per_s=5.5, t=t[sel])[0]
    c_std, c_lol, _ = _corr_stats(0.0, 0.0, range(4))
    assert if_std == pytest.approx(c_std, rel=0.25)
    assert loss_of_lock_probability(ip[sel], qp[sel], 5e-3) == pytest.approx(c_lol, abs=0.02)


def test_if_level_matches_correlator_level_scintillation(if_runs):
    t, err, ip, qp, T = if_runs["scint"]
    sel = t >= 2.0
    if_std = phase_error_std_deg(err[sel], per_s=5.5, t=t[sel])[0]
    c_std, c_lol, all_std = _corr_stats(0.6, 0.5, range(6))
    # one IF realisation against the Monte Carlo spread of the correlator-level runs
    assert min(all_std) * 0.8 <= if_std <= max(all_std) * 1.25
    assert abs(loss_of_lock_probability(ip[sel], qp[sel], 5e-3) - c_lol) < 0.15
