"""L5 acquisition aided by the L1 channel (receiver.acquisition.aided) on synthetic Q5 + NH20 signals."""
import numpy as np
import pytest

from receiver.acquisition.aided import predict_from_l1, search
from receiver.gnss.l5_codes import nh_signs
from receiver.gnss.signals_l5 import GPS_L5

FS = 10.23e6


def _signal(prn, cn0_dbhz, code_phase, doppler, seed, n_ms=10, ms0=3):
    """Q5 x NH20 at code phase ``code_phase`` chips (first sample), complex noise of unit variance per
    component: C/N0 = A^2 fs / 2."""
    rng = np.random.default_rng(seed)
    n = int(FS * 1e-3) * (n_ms + 1)
    t = np.arange(n) / FS
    rate = GPS_L5.chip_rate * (1 + doppler / GPS_L5.carrier_hz)
    chips = code_phase + t * rate
    code = GPS_L5.code(prn)[np.floor(chips).astype(np.int64) % 10230]
    nh = nh_signs(20)[(ms0 + (chips // 10230).astype(np.int64)) % 20]
    amp = np.sqrt(2 * 10 ** (cn0_dbhz / 10) / FS)
    x = amp * code * nh * np.exp(2j * np.pi * doppler * t)
    return (x + rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64)


def test_prediction_from_l1():
    # L1 code phase 123.4 chips = 120.6 us into the ms: the L5 code is 1234 chips into its period
    code, dop = predict_from_l1(123.4, 1540.0, GPS_L5)
    assert code == pytest.approx(1234.0) and dop == pytest.approx(1540.0 * 115 / 154)
    assert predict_from_l1(1023.0 + 5.0, 0.0, GPS_L5)[0] == pytest.approx(50.0)


def test_strong_signal_found_by_both():
    x = _signal(7, 45.0, 4321.3, 820.0, seed=1)
    a = search(x, FS, 0.0, GPS_L5, 7, 820.0, 0.0, 4320.0, 5.0)
    u = search(x, FS, 0.0, GPS_L5, 7, 0.0, 2000.0)
    for r in (a, u):
        assert r.detected
        assert abs(((r.code_phase_chips - 4321.3) + 5115) % 10230 - 5115) < 1.0
    # (unaided: 1-ms blocks across NH20 sign changes; the peak's Doppler is coarse)
    assert abs(u.doppler_hz - 820.0) <= 750.0
    assert a.cells < 100 < 1000 < u.cells and a.threshold < u.threshold
    # the wrong PRN is not detected
    assert not search(x, FS, 0.0, GPS_L5, 8, 820.0, 0.0, 4320.0, 5.0).detected


@pytest.mark.slow
def test_aiding_detects_where_the_full_search_fails():
    """35 dB-Hz, 10 ms: the aided search (a few cells) detects every trial, the full search (every code
    phase, +/- 2 kHz) most rarely: the same statistic, a threshold for 10^5 times more cells."""
    aided = unaided = 0
    for seed in range(6):
        x = _signal(11, 35.0, 777.7, -1300.0, seed=10 + seed)
        aided += search(x, FS, 0.0, GPS_L5, 11, -1300.0, 0.0, 776.0, 5.0).detected
        unaided += search(x, FS, 0.0, GPS_L5, 11, 0.0, 2000.0).detected
    assert aided == 6 and unaided <= 2


def test_e5a_prediction_from_the_e1_channel():
    """Galileo: the E1 code period is 4 ms (4092 chips), E5a's 1 ms; both start at whole ms of the satellite
    clock, so the E1 code phase modulo 1023 chips gives the E5a one (x 10)."""
    from receiver.gnss.signals_gal import GAL_E1
    from receiver.gnss.signals_gal_e5a import GAL_E5A
    args = (GAL_E1.chip_rate, GAL_E1.carrier_hz, GAL_E1.code_len)
    for ms in range(4):                      # 123.4 chips into any of the 4 ms of the E1 period
        code, dop = predict_from_l1(ms * 1023.0 + 123.4, -2100.0, GAL_E5A, *args)
        assert code == pytest.approx(1234.0) and dop == pytest.approx(-2100.0 * 115 / 154)


def test_e5a_q_found_around_the_prediction():
    """E5a-Q x CS100 (a sign change every few ms): the aided search finds it at the predicted code phase, not
    another PRN's code."""
    from receiver.gnss.signals_gal_e5a import GAL_E5A
    rng = np.random.default_rng(3)
    n = int(FS * 1e-3) * 11
    t = np.arange(n) / FS
    chips = 2222.2 + t * GAL_E5A.chip_rate * (1 + 600.0 / GAL_E5A.carrier_hz)
    x = np.sqrt(2 * 10 ** 4.5 / FS) * GAL_E5A.code(5)[np.floor(chips).astype(np.int64) % 10230] * \
        GAL_E5A.secondary(5)[(17 + (chips // 10230).astype(np.int64)) % 100] * np.exp(2j * np.pi * 600.0 * t)
    x = (x + rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64)
    r = search(x, FS, 0.0, GAL_E5A, 5, 600.0, 0.0, 2221.0, 5.0)
    assert r.detected and abs(((r.code_phase_chips - 2222.2) + 5115) % 10230 - 5115) < 1.0
    assert not search(x, FS, 0.0, GAL_E5A, 6, 600.0, 0.0, 2221.0, 5.0).detected
