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


def test_e1e5a_group_delays_from_bgd():
    """Galileo E1/E5a (ICD 5.1.5): satellite group delays TR_E1, TR_E5a give BGD(E1,E5a) = (TR_E1 - TR_E5a) /
    (1 - gamma) (Eq. 14); with the receiver's E1 single-frequency clock dt(E1) = dt(E1,E5b) - BGD(E1,E5b) (Eq. 15,
    the I/NAV clock) the E1/E5a ionosphere-free pseudorange plus c BGD(E1,E5a) is the geometry plus the receiver
    clock minus c dt(E1), whatever the group delays (the same BGD moves the simulator's E5a clock by
    (1 - gamma) BGD)."""
    from types import SimpleNamespace

    from receiver.gnss.signals_gal_e5a import GAL_E5A
    from receiver.gnss.signals_l5 import GPS_L5
    from receiver.navigation.ionofree import if_clock_correction_s
    from receiver.sim.multiband import GAMMA_E1E5A, e5a_clock_offset_s

    g = gamma(GAL_E5A.carrier_hz)
    assert g == pytest.approx(GAMMA_E1E5A) and g == pytest.approx(1.7933, abs=1e-4)
    rho, b_m, i1 = 2.4e7, 1234.5, 6.0                 # geometry, receiver clock (m), E1 ionosphere (m)
    dt_if5b, tr_e5b = 1.5e-4, 2.0e-9                   # the I/NAV clock dt(E1,E5b) and an E5b group delay
    for tr_e1, tr_e5a in ((3.0e-9, 1.0e-9), (-2.0e-9, 4.5e-9), (0.0, 0.0)):
        bgd_a = (tr_e1 - tr_e5a) / (1.0 - g)
        bgd_b = (tr_e1 - tr_e5b) / (1.0 - (1575.42 / 1207.14) ** 2)
        # the clocks of the signals: the E1/E5a and E1/E5b clocks differ by what their group delays make them
        dt_if5a = dt_if5b - bgd_b + bgd_a            # both reduce to the same E1 single-frequency clock
        dt_e1 = dt_if5b - bgd_b
        assert dt_e1 == pytest.approx(dt_if5a - bgd_a, abs=1e-18)
        dt_e5a = dt_if5a - g * bgd_a                 # Eq. 16
        assert dt_e5a - dt_e1 == pytest.approx(e5a_clock_offset_s(bgd_a), abs=1e-18)
        p1 = rho + b_m - C_LIGHT * dt_e1 + i1
        p5 = rho + b_m - C_LIGHT * dt_e5a + g * i1
        eph = SimpleNamespace(bgd_e1e5a=bgd_a, tgd=bgd_b)
        p_if = ionofree(p1, p5, g) + C_LIGHT * if_clock_correction_s(eph, GAL_E5A)
        assert p_if == pytest.approx(rho + b_m - C_LIGHT * dt_e1, abs=1e-6)
        if tr_e1 != tr_e5a:                          # without the correction: off by c BGD(E1,E5a)
            assert abs(ionofree(p1, p5, g) - p_if) == pytest.approx(C_LIGHT * abs(bgd_a), rel=1e-9)
    # GPS L5: no correction (CNAV ISCs not decoded)
    assert if_clock_correction_s(SimpleNamespace(bgd_e1e5a=1e-8, tgd=1e-8), GPS_L5) == 0.0


def test_dual_frequency_solver_takes_the_navigation_weighting_settings():
    """The ionosphere-free fix's solver is configured from the navigation section: every solver setting it
    copies reaches it (cn0_elevation's reference C/N0 included), and the ionosphere model is off."""
    from types import SimpleNamespace
    from receiver.navigation.ionofree import DualFrequency
    nav = SimpleNamespace(elevation_mask_deg=12.0, weighting="cn0_elevation", cn0_ref_dbhz=42.0,
                          troposphere="none", residual_threshold_m=25.0, max_pdop=9.0, smoothing_s=0.0,
                          rate_hz=10.0)
    s = DualFrequency(nav, [], None).solver
    assert (s.weighting, s.cn0_ref_dbhz, s.elevation_mask_deg, s.ionosphere) == ("cn0_elevation", 42.0, 12.0, "none")
