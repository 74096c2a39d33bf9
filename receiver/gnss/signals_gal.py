"""Galileo E1 Open Service signal definition (Galileo OS SIS ICD issue 1.1): E1-B (data, I/NAV at 250 sym/s)
and E1-C (pilot, CS25 secondary code), 4092-chip primary codes at 1.023 Mcps (4 ms), BOC(1,1) replicas.

The transmitted sub-carrier is CBOC(6,1,1/11) (ICD Eq. 11); the receiver's replica is its BOC(1,1) part (the
in-phase 1.023-MHz sub-carrier, 10/11 of the power): docs/galileo.md says what that costs.  Codes, CS25 and
the sub-carrier helpers are in :mod:`receiver.gnss.gal_codes`.
"""
from __future__ import annotations

import numpy as np

from .gal_codes import (
    CS25_LEN,
    E1_CHIP_RATE,
    E1_CODE_LEN,
    E1_HZ,
    E1_PERIOD_S,
    E1B_SYMBOL_RATE,
    GAL_PRNS,
    boc11,
    cs25_signs,
    e1b_code,
    e1c_code,
)
from .signals import SignalDef, sample_code

#: code periods per I/NAV symbol on E1-B (250 sym/s, 4-ms periods) and per CS25 period on E1-C (25 x 4 ms)
E1B_SYMBOL_PERIODS = round(1.0 / (E1B_SYMBOL_RATE * E1_PERIOD_S))
CS25_PERIOD_S = CS25_LEN * E1_PERIOD_S


class GalE1Signal(SignalDef):
    """Galileo E1 OS.  Unlike the 1-ms signals of :class:`SignalDef`, the primary-code period is 4 ms
    (``code_period_s``); ``bit_ms`` is the E1-B symbol length in ms (4: one symbol per code period), and
    ``secondary`` is the E1-C pilot's CS25 (one value per 4-ms code period, 100 ms long, the same for every
    PRN).  ``code`` is the E1-C (pilot) primary code, ``data_code`` the E1-B one; ``replica`` gives either
    with its BOC(1,1) sub-carrier as half-chips at ``replica_rate`` (2.046 MHz)."""
    name = "gal_e1"
    system = "E"
    carrier_hz = E1_HZ
    chip_rate = E1_CHIP_RATE
    code_len = E1_CODE_LEN
    code_period_s = E1_PERIOD_S
    prns = GAL_PRNS
    subcarrier = "boc11"
    replica_rate = 2 * E1_CHIP_RATE

    def code(self, prn: int) -> np.ndarray:
        """E1-C (pilot) primary code as +/-1 float32 chips."""
        return e1c_code(prn)

    def data_code(self, prn: int) -> np.ndarray:
        """E1-B (data) primary code as +/-1 float32 chips."""
        return e1b_code(prn)

    def replica(self, prn: int, component: str = "C") -> np.ndarray:
        """BOC(1,1) replica of the E1-C ("C") or E1-B ("B") code: 8184 half-chips, +/-1 float32."""
        return boc11(e1c_code(prn) if component == "C" else e1b_code(prn))

    def sample_replica(self, prn: int, fs: float, n: int, code_phase_chips: float = 0.0,
                       component: str = "C") -> np.ndarray:
        """n samples at rate fs of the BOC(1,1) replica starting at code phase ``code_phase_chips``
        (in primary-code chips)."""
        return sample_code(self.replica(prn, component), self.replica_rate, fs, n, 2.0 * code_phase_chips)

    def bit_ms(self, prn: int) -> int:
        """E1-B symbol length in ms (one 4-ms code period)."""
        return round(E1_PERIOD_S * 1e3) * E1B_SYMBOL_PERIODS

    def secondary(self, prn: int):
        """CS25 on the E1-C pilot, +/-1 per 4-ms code period (25 values)."""
        return cs25_signs()

    def short_symbols(self, prn: int) -> bool:
        """True: a symbol or secondary chip per code period (no 20-ms bit synchronisation)."""
        return True                       # 4-ms symbols on E1-B, CS25 chips every 4 ms on E1-C


GAL_E1 = GalE1Signal()
