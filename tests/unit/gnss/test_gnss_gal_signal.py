"""The gal_e1 signal definition: registry entry, 4-ms codes, E1-B symbols, CS25 on E1-C, BOC(1,1) replicas and
what the BOC(1,1) replica loses against the transmitted CBOC(6,1,1/11)."""
import numpy as np
import pytest

from receiver.gnss import gal_codes as G
from receiver.gnss.registry import get_signal


def test_registry_entry():
    s = get_signal("gal_e1")
    assert s.name == "gal_e1" and s.system == "E"
    assert s.carrier_hz == 1575.42e6 and s.chip_rate == 1.023e6 and s.code_len == 4092
    assert np.isclose(s.code_len / s.chip_rate, 4e-3) and s.code_period_s == 4e-3
    assert s.prns == tuple(range(1, 51))
    assert s.bit_ms(11) == 4                                   # 250 sym/s on E1-B
    assert np.array_equal(s.secondary(11), G.cs25_signs())     # CS25 on the pilot, same for every PRN
    assert np.array_equal(s.code(3), G.e1c_code(3)) and np.array_equal(s.data_code(3), G.e1b_code(3))
    assert s.short_symbols(3)
    # the 1-ms signals keep their period
    assert get_signal("gps_l1ca").code_period_s == 1e-3 and get_signal("bds_b1i").code_period_s == 1e-3


def _circ_corr(a, b):
    return np.fft.irfft(np.fft.rfft(a) * np.conj(np.fft.rfft(b)), n=len(a)) / len(a)


def test_boc11_replica_correlation_shape():
    """BOC(1,1) auto-correlation: main peak 1 at zero lag, zero at +/-1/4 chip... read at half-chip
    steps: -1/2 at +/-1/2 chip (the side peaks acquisition must not lock to), ~0 beyond one chip."""
    s = get_signal("gal_e1")
    fs = 8 * 1.023e6                                          # 8 samples per chip
    x = s.sample_replica(7, fs, 8 * 4092).astype(np.float64)
    r = _circ_corr(x, x)
    assert np.isclose(r[0], 1.0)
    assert r[4] == pytest.approx(-0.5, abs=0.02) and r[-4] == pytest.approx(-0.5, abs=0.02)   # +/- 1/2 chip
    assert r[2] == pytest.approx(0.25, abs=0.02)               # 1/4 chip: zero crossing at 1/3 chip
    assert np.abs(r[9:-9]).max() < 0.07                        # beyond one chip: code sidelobes only
    # a code phase is in primary-code chips
    y = s.sample_replica(7, fs, 8 * 4092, code_phase_chips=100.0).astype(np.float64)
    assert np.argmax(_circ_corr(x, y)) == 800


def _boc11_loss_db(bandwidth_hz):
    """C/N0 lost by correlating the (ideally band-limited) CBOC E1-B signal with a BOC(1,1) replica instead of
    the matched CBOC replica, white noise in the band."""
    chips = np.concatenate([G.e1b_code(p) for p in range(1, 5)])
    x = np.fft.fft(G.cboc(chips, "B").astype(np.float64))
    r = np.fft.fft(np.repeat(G.boc11(chips), 6).astype(np.float64))
    f = np.fft.fftfreq(len(chips) * 12, 1.0 / (12 * 1.023e6))
    m = np.abs(f) <= bandwidth_hz / 2
    snr_boc = np.abs(np.sum(x[m] * np.conj(r[m]))) ** 2 / np.sum(np.abs(r[m]) ** 2)
    return 10 * np.log10(snr_boc / np.sum(np.abs(x[m]) ** 2))


def test_cboc_approximation_cost():
    # full band: the BOC(6,1) component's 1/11 of the power is lost, 10 log10(10/11) = -0.41 dB
    assert _boc11_loss_db(np.inf) == pytest.approx(10 * np.log10(10 / 11), abs=1e-3)
    # a front end narrower than the BOC(6,1) lobes (+/-6.1 MHz) removes that component anyway
    assert -0.03 < _boc11_loss_db(4e6) <= 0.0
    assert -0.05 < _boc11_loss_db(8e6) < _boc11_loss_db(4e6)


def test_config_accepts_gal_e1_with_the_vector_loop():
    from receiver.schema import load_receiver_config, run_signals
    cfg = load_receiver_config(None, [("signal", "gal_e1"), ("acquisition.prns", [11, 12])])
    assert run_signals(cfg) == ["gal_e1"] and cfg.acquisition.prns == [11, 12]
    assert run_signals(load_receiver_config(None, [("signals", ["gps_l1ca", "gal_e1", "bds_b1i"])])) == \
        ["gps_l1ca", "gal_e1", "bds_b1i"]
    # the vector loops track Galileo E1 channels (tests/system/test_vector_galileo_run.py)
    assert load_receiver_config(None, [("signal", "gal_e1"), ("vector.enabled", True)]).vector.enabled
    cfg = load_receiver_config(None, [])
    assert cfg.signal == "gps_l1ca"
