"""GPS L5 signal definition (IS-GPS-705): the receiver tracks the Q5 pilot (10230 chips at 10.23 Mcps, 1 ms,
under the 20-ms NH20 secondary code); I5 (the CNAV data channel, 100 sps under NH10) is generated for the
simulator.  Codes are in :mod:`receiver.gnss.l5_codes`.
"""
from __future__ import annotations

import numpy as np

from .l5_codes import L5_CHIP_RATE, L5_CODE_LEN, L5_HZ, L5_PRNS, l5_code, nh_signs
from .signals import SignalDef

#: L5 / L1 carrier ratio: code phase rates and Doppler of the same satellite scale by it (115/154)
L5_OVER_L1 = L5_HZ / 1575.42e6


class L5Signal(SignalDef):
    """GPS L5 (``gps_l5``, system G) as tracked here: the Q5 pilot.  ``bit_ms`` is the NH20 length (the
    pilot carries no data symbols; the 20-ms frame of NH20 plays the part of a bit), ``secondary`` is NH20."""
    name = "gps_l5"
    system = "G"
    carrier_hz = L5_HZ
    chip_rate = L5_CHIP_RATE
    code_len = L5_CODE_LEN
    prns = L5_PRNS
    component = "Q"

    def code(self, prn: int) -> np.ndarray:
        """Q5 (pilot) primary code as +/-1 float32 chips."""
        return l5_code(prn, "Q")

    def data_code(self, prn: int) -> np.ndarray:
        """I5 (data) primary code as +/-1 float32 chips."""
        return l5_code(prn, "I")

    def bit_ms(self, prn: int) -> int:
        """20: the NH20 period on Q5."""
        return 20

    def secondary(self, prn: int):
        """NH20, +/-1 per 1-ms code period."""
        return nh_signs(20)


GPS_L5 = L5Signal()
