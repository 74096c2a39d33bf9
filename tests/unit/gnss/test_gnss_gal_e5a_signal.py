"""The gal_e5a signal definition (E5a-Q pilot, E5a-I data): rates from ICD Table 4 / 13, codes and secondary
codes from receiver.gnss.gal_e5a_codes; in the signal registry as gal_e5a."""
import numpy as np

from receiver.gnss import gal_e5a_codes as G
from receiver.gnss.registry import SIGNAL_NAMES, get_signal
from receiver.gnss.signals_gal_e5a import E5A_I_SYMBOL_PERIODS, E5A_OVER_E1, GAL_E5A


def test_signal_definition():
    s = GAL_E5A
    assert s.name == "gal_e5a" and s.system == "E"
    assert s.carrier_hz == 1176.45e6 and s.chip_rate == 10.23e6 and s.code_len == 10230
    assert np.isclose(s.code_len / s.chip_rate, 1e-3) and s.code_period_s == 1e-3
    assert np.isclose(E5A_OVER_E1, 115 / 154)
    assert s.prns == tuple(p for p in range(1, 51) if p not in (37, 38, 39))
    assert np.array_equal(s.code(3), G.e5a_q_code(3)) and np.array_equal(s.data_code(3), G.e5a_i_code(3))
    # tiered codes of ICD Table 13: E5a-Q 100 ms (CS100 per PRN), E5a-I 20 ms (CS20_1, one F/NAV symbol)
    assert s.bit_ms(5) == 100 and len(s.secondary(5)) == 100
    assert np.array_equal(s.secondary(5), G.e5a_q_secondary(5))
    assert not np.array_equal(s.secondary(5), s.secondary(6))
    assert s.data_bit_ms(5) == 20 == E5A_I_SYMBOL_PERIODS and np.array_equal(s.data_secondary(9), G.e5a_i_secondary())
    assert s.short_symbols(5)
    assert "gal_e5a" in SIGNAL_NAMES and get_signal("gal_e5a") is GAL_E5A      # the second band of gal_e1
