"""L5 pseudoranges from the L5 code phase and the L1 epoch, and the L1/L5 ionosphere-free combination."""
import numpy as np
import pytest

from receiver.gnss.signals import C_LIGHT
from receiver.navigation.ionofree import band_pseudorange, gamma, ionofree


def test_gamma_and_combination_remove_the_first_order_ionosphere():
    g = gamma(1176.45e6)
    assert g == pytest.approx((154 / 115) ** 2)
    rho, i1 = np.array([2.1e7, 2.3e7]), np.array([3.0, 12.5])
    assert np.allclose(ionofree(rho + i1, rho + g * i1, g), rho, rtol=0, atol=1e-7)
    # coefficients 2.261 and -1.261
    assert ionofree(1.0, 0.0, g) == pytest.approx(2.2606, abs=1e-4)


@pytest.mark.parametrize("tx_frac_ms", [0.0004, 0.5, 0.9997])
def test_band_pseudorange_from_code_phase(tx_frac_ms):
    """Transmit times near a millisecond boundary: the L5 code phase gives the fraction, the L1 pseudorange
    (a few metres off: ionosphere, smoothing) the whole milliseconds."""
    rx = 345600.0775
    tx5 = 345600.0 + (3 + tx_frac_ms) * 1e-3
    pr5 = (rx - tx5) * C_LIGHT
    code = ((tx5 * 1e3) % 1.0) * 10230.0
    for off_m in (-25.0, 0.0, 40.0):
        got = band_pseudorange(pr5 + off_m, rx, code, 10.23e6)
        assert got == pytest.approx(pr5, abs=1e-4)
