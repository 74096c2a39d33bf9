"""The example plugin on its own: its compiled path equals its reference path, it pulls in a frequency
error the PLL alone (fll_bw_hz: 0) does not, and gnssrx finds it through its entry point."""
import math
from types import SimpleNamespace

import numpy as np

from gnssrx_fll_pll import FllPll


def _cfg(pll_bw=15.0, fll_bw=2.0):
    sec = SimpleNamespace(pll_bw_hz=pll_bw, fll_bw_hz=fll_bw)
    return SimpleNamespace(carrier={"fll_pll": sec})


def _track(loop, f_err_hz, T=0.001, n=3000, cn0_dbhz=45.0, compiled=False, seed=1):
    """Prompt correlations of a carrier f_err_hz away from the loop's start frequency, with noise at C/N0,
    closed around the loop; returns the loop's Doppler per epoch."""
    rng = np.random.default_rng(seed)
    amp = math.sqrt(2 * 10 ** (cn0_dbhz / 10) * T)           # |P| / sigma per component
    if compiled:
        start, update, lp, ls = loop.compiled()
        start(lp, ls, 0.0, T, 0.0, 1575.42e6)
    else:
        loop.start(0.0, T, 0.0, 1575.42e6)
    phase_sig, phase_nco, f_nco, out = 0.3, 0.0, 0.0, []
    for _ in range(n):
        # mean phase difference over the epoch (the NCO runs at f_nco, the signal at f_err)
        dphi = phase_sig - phase_nco + math.pi * (f_err_hz - f_nco) * T
        ip, qp = amp * math.cos(dphi) + rng.normal(), amp * math.sin(dphi) + rng.normal()
        phase_sig += 2 * math.pi * f_err_hz * T
        phase_nco += 2 * math.pi * f_nco * T
        if compiled:
            f_nco, step = update(lp, ls, ip, qp, T, 0.0, 0.0, 0.0, 0.0)
        else:
            f_nco, step = loop.step(ip, qp, T)
        phase_nco += 2 * math.pi * step
        out.append(f_nco)
    return np.array(out)


def test_compiled_path_equals_reference_path():
    a = _track(FllPll(_cfg()), 20.0, compiled=False)
    b = _track(FllPll(_cfg()), 20.0, compiled=True)
    np.testing.assert_array_equal(a, b)


def test_fll_assist_pulls_in_what_the_pll_alone_loses():
    f_err = 40.0                                  # Hz: beyond a 5 Hz PLL's pull-in range
    assisted = _track(FllPll(_cfg(pll_bw=5.0, fll_bw=5.0)), f_err)
    alone = _track(FllPll(_cfg(pll_bw=5.0, fll_bw=0.0)), f_err)
    assert abs(np.mean(assisted[-500:]) - f_err) < 1.0
    assert abs(np.mean(alone[-500:]) - f_err) > 5.0


def test_gnssrx_finds_it_by_its_entry_point():
    from receiver.plugins import find
    found = find("carrier_loop", "fll_pll")
    assert found.cls is FllPll and found.version == "0.1.0" and "gnssrx-fll-pll" in found.origin
