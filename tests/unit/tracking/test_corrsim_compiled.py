"""The correlator-level simulator's compiled driver (receiver.evaluate.corrloop.run: every epoch in one
numba function with the loops' compiled twins) against its numpy + Python-loop reference path, for every
loop variant and setting the paper figures use (scripts/figures/figures_carrier.py).

Runs are short (3-4 s) on purpose: the two paths do the same arithmetic in the same order (on this machine
the records are bit-identical), but a closed tracking loop under strong scintillation, and the paper's
unclipped per-epoch PLI-EKF in particular, is chaotic: a last-bit difference (e.g. a vectorised sin in
another numpy build) grows over minutes.  Over a few seconds it stays far below the 1e-9 tolerance."""
import os
import sys

import numpy as np
import pytest

from receiver.schema import load_receiver_config
from receiver.gnss.signals import L1_HZ
from receiver.gnss.signals_bds import B1I_HZ
from receiver.evaluate.corrloop import run as run_compiled
from receiver.sim.corrsim import OUT_KEYS, CorrScenario, make_truth, run
from receiver.tracking.carrier import make_carrier_loop

from repo_paths import SCRIPTS
sys.path.insert(0, str(SCRIPTS / "figures"))
import figures_carrier as FC  # noqa: E402


def _loop(name, extra=()):
    return FC._loop(name, extra)


def _assert_same(a, b):
    assert set(a) == set(b) == set(OUT_KEYS)
    for k in OUT_KEYS:
        x, y = a[k], b[k]
        assert x.shape == y.shape and x.size > 0
        assert (np.isnan(x) == np.isnan(y)).all(), k
        f = ~np.isnan(x)
        if not f.any():
            continue
        np.testing.assert_allclose(y[f], x[f], rtol=1e-9, atol=1e-9 * max(1.0, np.abs(x[f]).max()), err_msg=k)


@pytest.fixture(scope="module")
def scint_truth():
    s4, sp = FC.SCENARIOS[3]                        # strong-moderate, the figures-check scenario
    sc = CorrScenario(duration_s=4.0, t_coh_ms=5, carrier_hz=B1I_HZ, cn0_dbhz=40.0, s4=s4, sigma_phi=sp,
                      tau0_s=FC.TAU0, h0=FC.H0, h_2=FC.H_2, seed=3001)
    return sc, make_truth(sc)


@pytest.mark.slow
@pytest.mark.parametrize("name", FC.SCINT_LOOPS)
def test_scintillation_loops_compiled_equals_python(scint_truth, name):
    sc, truth = scint_truth
    ref = run(_loop(name), sc, truth)
    fast = run_compiled(_loop(name), sc, truth)
    _assert_same(ref, fast)
    # not a trivial run: the loop moved the NCO, the noise is there, and the C/N0 estimate is the loop's
    assert np.ptp(ref["doppler"]) > 1.0
    assert np.isnan(fast["cn0_est"]).all() == (name == "cpll_atan")


@pytest.mark.parametrize("T", FC.WEAK_T)
@pytest.mark.parametrize("name", FC.WEAK_LOOPS)
def test_weak_signal_loops_compiled_equals_python(name, T):
    # the weak-signal experiment's setting (2 g manoeuvre, falling C/N0), ramp compressed into 3 s
    sc = CorrScenario(duration_s=3.0, t_coh_ms=T, carrier_hz=L1_HZ, cn0_schedule=((0, 0.5, 3), (45, 45, 25)),
                      h0=FC.H0, h_2=FC.H_2, dynamics="manoeuvre", accel_g=2.0, seed=500 + T)
    ref = run(_loop(name), sc)
    fast = run_compiled(_loop(name), sc)
    _assert_same(ref, fast)


def test_compiled_path_reads_the_loop_parameters(scint_truth):
    """A perturbed loop gives another record in the compiled path too, the one the reference gives."""
    sc, truth = scint_truth
    base = run_compiled(_loop("ekf"), sc, truth)
    ovr = ["tracking.carrier.ekf.bn_hz=8.0"]
    pert_fast = run_compiled(_loop("ekf", ovr), sc, truth)
    assert not np.allclose(base["doppler"], pert_fast["doppler"], rtol=1e-6)
    _assert_same(run(_loop("ekf", ovr), sc, truth), pert_fast)


def test_compiled_path_limits():
    cfg = load_receiver_config(overrides=["tracking.carrier.bn_hz=15.0"])
    with pytest.raises(ValueError, match="t_coh_ms"):
        run_compiled(make_carrier_loop("cpll_atan", cfg.tracking), CorrScenario(duration_s=0.5, t_coh_ms=80))
    with pytest.raises(ValueError, match="no compiled twin"):
        run_compiled(object(), CorrScenario(duration_s=0.5))


def test_jit_cache_table_covers_corrsim():
    """the compiled corrsim driver calls the loops' compiled twins: the stale-cache table lists it with existing
    files, so a change of a loop drops its cached machine code (receiver/tracking/_jitcache.py)."""
    from receiver.tracking import _jitcache as J
    deps = J.DEPENDS["../evaluate/corrloop.py"]
    assert {"loops/compiled.py", "loops/ekf.py", "loops/kfpll.py"} <= set(deps)
    for mod, ds in J.DEPENDS.items():
        for f in [mod] + ds:
            assert os.path.isfile(os.path.join(J._HERE, f)), f
