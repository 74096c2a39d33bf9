"""GPS L5 I5/Q5 codes against IS-GPS-705's register definitions (the PRN table is the test suite's own: see
tests/conftest.py and receiver/gnss/l5_codes.py)."""
import numpy as np
import pytest

from receiver.gnss.l5_codes import (L5_CODE_LEN, L5_PRNS, NH10, NH20, XB_TABLE_ENV, _XB_TAPS,
                                    _run, first_chips_octal, l5_code, l5_code_bits, nh_signs, xa_sequence,
                                    xb_advances, xb_initial_state)
from receiver.errors import UserError
from receiver.gnss.registry import get_signal

def test_signal_entry():
    sig = get_signal("gps_l5")
    assert sig.carrier_hz == 1176.45e6 and sig.chip_rate == 10.23e6 and sig.code_len == 10230
    assert sig.prns == tuple(range(1, 33)) and sig.bit_ms(1) == 20 and sig.short_symbols(1)
    assert np.array_equal(sig.code(7), l5_code(7, "Q")) and np.array_equal(sig.data_code(7), l5_code(7, "I"))
    assert sig.samples_to_period_start(0.0, 0.5) == 0


def test_xa_short_cycle_and_xb_maximal():
    xa = xa_sequence()
    # XA restarts from all ones after 8190 chips: chips 8190.. repeat chips 0..
    assert np.array_equal(xa[8190:], xa[:L5_CODE_LEN - 8190])
    # the first 13 XA chips from the all-ones state are ones
    assert xa[:13].all()
    # XB is maximal length: its state returns to all ones after 8191 clocks and not before
    out, reg = _run(_XB_TAPS, [1] * 13, 8191)
    assert reg == [1] * 13 and out.sum() == 4096          # 2^12 ones in an m-sequence of degree 13


@pytest.mark.parametrize("comp", ["I", "Q"])
def test_first_chips_are_the_complement_of_the_initial_state(comp):
    """ICD note to Table 3-Ia: the first 13 XB chips (rightmost bit first out) are the complement of the
    code's first 13 chips, because XA starts all ones; every PRN 1-32."""
    for prn in L5_PRNS:
        state = xb_initial_state(xb_advances()["IQ".index(comp)][prn - 1])
        first13 = l5_code_bits(prn, comp)[:13]
        assert np.array_equal(first13, 1 - np.array(state[::-1], np.uint8)), prn
        assert int(first_chips_octal(prn, comp), 8) == int("".join(map(str, first13)), 2)


def test_table_comes_from_the_named_file_or_a_one_line_error(monkeypatch, tmp_path):
    """No table shipped: without GNSSRX_L5_XB_TABLE a one-line error says what is needed; a short or
    malformed file is refused; a complete one is read."""
    from receiver.gnss import l5_codes
    monkeypatch.delenv(XB_TABLE_ENV)
    with pytest.raises(UserError, match="IS-GPS-705 Table 3-Ia") as e:
        xb_advances()
    assert "\n" not in str(e.value)
    bad = tmp_path / "bad.csv"
    bad.write_text("prn,i5_advance,q5_advance\n1,266,1701\n")
    monkeypatch.setenv(XB_TABLE_ENV, str(bad))
    with pytest.raises(UserError, match="each PRN 1..32"):
        l5_codes._read_table(str(bad))
    good = tmp_path / "good.csv"
    good.write_text("".join(f"{p},{10 * p},{5000 + p}\n" for p in range(1, 33)))
    monkeypatch.setenv(XB_TABLE_ENV, str(good))
    i5, q5 = xb_advances()
    assert i5[6] == 70 and q5[31] == 5032


def test_balance_and_correlation_bounds():
    """All 64 codes (I5, Q5 of PRN 1-32): near-balanced, sharp autocorrelation, low cross-correlation
    (worst even cross-correlation of these XA/XB codes stays under about -26 dB)."""
    codes = np.array([l5_code(p, c) for c in "IQ" for p in L5_PRNS], np.float64)
    assert np.all(np.abs(codes.sum(axis=1)) < 20)
    f = np.fft.rfft(codes, axis=1)
    auto = np.fft.irfft(f * f.conj(), n=L5_CODE_LEN, axis=1) / L5_CODE_LEN
    assert np.allclose(auto[:, 0], 1.0)
    assert np.abs(auto[:, 1:]).max() < 0.04
    worst = 0.0
    for i in range(len(codes)):
        x = np.fft.irfft(f[i][None, :] * f[i + 1:].conj(), n=L5_CODE_LEN, axis=1) / L5_CODE_LEN
        if len(x):
            worst = max(worst, np.abs(x).max())
    assert worst < 0.05


def test_neuman_hofman_codes():
    assert NH10 == (0, 0, 0, 0, 1, 1, 0, 1, 0, 1)
    assert "".join(map(str, NH20)) == "00000100110101001110"
    assert np.array_equal(nh_signs(10), 1 - 2 * np.array(NH10, np.float32))
    assert nh_signs(20).shape == (20,)


def test_bad_prn():
    with pytest.raises(ValueError):
        l5_code_bits(33, "Q")
