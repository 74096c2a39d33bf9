"""Galileo E5a signal definition (Galileo OS SIS ICD issue 1.1), as a QPSK signal on its own at 1176.45 MHz
(ICD section 2.3.1.2: E5a and E5b may be received apart): the receiver would track the E5a-Q pilot (10230
chips at 10.23 Mcps, 1 ms, under its 100-ms CS100 secondary code); E5a-I (F/NAV at 50 sps under CS20_1) is
there for the simulator.  Codes are in :mod:`receiver.gnss.gal_e5a_codes`.

In the signal registry as ``gal_e5a``: tracked as the second band of Galileo E1 (``signals: [gal_e1, gal_e5a]``
with the E5a file in ``input.signal_files``; receiver/dualband.py), aided by the E1 channels.
"""
from __future__ import annotations

import numpy as np

from .gal_e5a_codes import (
    CS20_LEN,
    CS100_LEN,
    E5A_CHIP_RATE,
    E5A_CODE_LEN,
    E5A_HZ,
    E5A_PERIOD_S,
    E5A_I_SYMBOL_RATE,
    e5a_i_code,
    e5a_i_secondary,
    e5a_q_code,
    e5a_q_prns,
    e5a_q_secondary,
)
from .signals import SignalDef

#: E5a / L1 (= E1) carrier ratio: code phase rates and Doppler of the same satellite scale by it (115/154)
E5A_OVER_E1 = E5A_HZ / 1575.42e6
#: code periods per F/NAV symbol on E5a-I (50 sps, 1-ms periods): the CS20_1 length
E5A_I_SYMBOL_PERIODS = round(1.0 / (E5A_I_SYMBOL_RATE * E5A_PERIOD_S))


class GalE5aSignal(SignalDef):
    """Galileo E5a (``gal_e5a``, system E) as it would be tracked: the E5a-Q pilot.  ``bit_ms`` is the CS100
    length (the pilot carries no data symbols; the 100-ms secondary-code period plays the part of a bit),
    ``secondary`` is CS100 of the PRN.  ``prns`` leaves out the code numbers without a CS100 code in the
    ICD (37..39).  ``data_code`` / ``data_bit_ms`` / ``data_secondary`` describe E5a-I."""
    name = "gal_e5a"
    system = "E"
    carrier_hz = E5A_HZ
    chip_rate = E5A_CHIP_RATE
    code_len = E5A_CODE_LEN
    code_period_s = E5A_PERIOD_S
    prns = e5a_q_prns()
    component = "Q"

    def code(self, prn: int) -> np.ndarray:
        """E5a-Q (pilot) primary code as +/-1 float32 chips."""
        return e5a_q_code(prn)

    def data_code(self, prn: int) -> np.ndarray:
        """E5a-I (data) primary code as +/-1 float32 chips."""
        return e5a_i_code(prn)

    def bit_ms(self, prn: int) -> int:
        """100: the CS100 period on E5a-Q."""
        return CS100_LEN

    def secondary(self, prn: int):
        """CS100 of ``prn``, +/-1 per 1-ms code period."""
        return e5a_q_secondary(prn)

    def data_bit_ms(self, prn: int) -> int:
        """20: one F/NAV symbol (50 sps) on E5a-I, the CS20_1 length."""
        return CS20_LEN

    def data_secondary(self, prn: int):
        """CS20_1 on E5a-I, +/-1 per 1-ms code period (the same for every PRN)."""
        return e5a_i_secondary()


GAL_E5A = GalE5aSignal()
