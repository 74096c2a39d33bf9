"""BeiDou B1I open-service signal (BDS-SIS-ICD-B1I): constants, ranging codes, NH code, data structure.

Ranging code (ICD section 4.3): the modulo-2 sum of two 11-stage maximal-length sequences G1 and G2,
clocked at 2.046 Mcps, truncated to 2046 chips (the registers are reset every 1 ms):

    G1(X) = 1 + X + X^7 + X^8 + X^9 + X^10 + X^11
    G2(X) = 1 + X + X^2 + X^3 + X^4 + X^5 + X^8 + X^9 + X^11
    initial phase of both registers (stages 1..11): 01010101010

The satellite-specific code is G1 (output of stage 11) XOR a phase-shifted G2 formed by the modulo-2 sum of
two G2 stages for ranging code numbers 1-37 (ICD v2.0 Table 4-2) or three for 38-63 (added by ICD v3.0 for
BDS-3; ``G2_PHASE`` below).  Logic 0 is transmitted as +1, logic 1 as -1.

Navigation message: D1 (MEO/IGSO, ranging code numbers 6-58) at 50 bps with the 20-bit Neumann-Hoffman
secondary code at 1 kbps; D2 (GEO, numbers 1-5 and 59-63) at 500 bps, no secondary code.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .signals import SignalDef

B1I_HZ = 1561.098e6
B1I_CHIP_RATE = 2.046e6
B1I_CODE_LEN = 2046
B1I_GEO_PRNS = (1, 2, 3, 4, 5, 59, 60, 61, 62, 63)
#: Neumann-Hoffman code on D1 (first bit first), ICD section 5.2.1
NH_CODE = (0, 0, 0, 0, 0, 1, 0, 0, 1, 1, 0, 1, 0, 1, 0, 0, 1, 1, 1, 0)
D1_BIT_MS = 20               # 50 bps
D2_BIT_MS = 2                # 500 bps

_G1_TAPS = (1, 7, 8, 9, 10, 11)              # feedback stages of G1
_G2_TAPS = (1, 2, 3, 4, 5, 8, 9, 11)         # feedback stages of G2
_INIT = (0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 0)    # stages 1..11

#: G2 phase assignment: the G2 stages added modulo 2, per ranging code number.  1-37: two stages (ICD v2.0
#: Table 4-2).  38-63: three stages (ICD v3.0, BDS-3), in the table's ascending order; the ICD v3.0 table itself
#: was not available here: these were identified from a public table of G2 delays (the offset into the G2
#: sequence where each code's phase-shifted G2 starts), each of whose 26 entries for 38-63 is the delay of exactly
#: one three-stage sum and whose entries for 1-37 are those of the two-stage sums above
#: (tests/test_bds.py checks both representations agree)
G2_PHASE = {
    1: (1, 3), 2: (1, 4), 3: (1, 5), 4: (1, 6), 5: (1, 8), 6: (1, 9), 7: (1, 10), 8: (1, 11),
    9: (2, 7), 10: (3, 4), 11: (3, 5), 12: (3, 6), 13: (3, 8), 14: (3, 9), 15: (3, 10), 16: (3, 11),
    17: (4, 5), 18: (4, 6), 19: (4, 8), 20: (4, 9), 21: (4, 10), 22: (4, 11), 23: (5, 6), 24: (5, 8),
    25: (5, 9), 26: (5, 10), 27: (5, 11), 28: (6, 8), 29: (6, 9), 30: (6, 10), 31: (6, 11), 32: (8, 9),
    33: (8, 10), 34: (8, 11), 35: (9, 10), 36: (9, 11), 37: (10, 11),
    38: (1, 2, 7), 39: (1, 3, 4), 40: (1, 3, 6), 41: (1, 3, 8), 42: (1, 3, 10), 43: (1, 3, 11), 44: (1, 4, 5),
    45: (1, 4, 9), 46: (1, 5, 6), 47: (1, 5, 8), 48: (1, 5, 10), 49: (1, 5, 11), 50: (1, 6, 9), 51: (1, 8, 9),
    52: (1, 9, 10), 53: (1, 9, 11), 54: (2, 3, 7), 55: (2, 5, 7), 56: (2, 7, 9), 57: (3, 4, 5), 58: (3, 4, 9),
    59: (3, 5, 6), 60: (3, 5, 8), 61: (3, 5, 10), 62: (3, 5, 11), 63: (3, 6, 9),
}
B1I_PRNS = tuple(sorted(G2_PHASE))


def _lfsr(taps, n, out_stages):
    """Run an 11-stage Fibonacci register n steps from _INIT; per step, the XOR of `out_stages`
    (1-based) is output before the shift; the feedback (XOR of `taps`) enters stage 1."""
    reg = list(_INIT)
    out = np.empty(n, np.uint8)
    for i in range(n):
        v = 0
        for s in out_stages:
            v ^= reg[s - 1]
        out[i] = v
        fb = 0
        for t in taps:
            fb ^= reg[t - 1]
        reg = [fb] + reg[:-1]
    return out


@lru_cache(maxsize=None)
def b1i_code_bits(prn: int) -> np.ndarray:
    """B1I ranging code of ranging code number `prn` as 2046 bits (0/1), first chip first."""
    if prn not in G2_PHASE:
        raise ValueError(f"BDS B1I PRN must be 1..63, got {prn}")
    g1 = _lfsr(_G1_TAPS, B1I_CODE_LEN, (11,))
    g2 = _lfsr(_G2_TAPS, B1I_CODE_LEN, G2_PHASE[prn])
    out = g1 ^ g2
    out.setflags(write=False)
    return out


def b1i_code(prn: int) -> np.ndarray:
    """B1I code as +/-1 float32 chips (bit 0 -> +1)."""
    return (1.0 - 2.0 * b1i_code_bits(prn)).astype(np.float32)


def first_chips_octal(prn: int, n: int = 12) -> str:
    """The first n chips (n multiple of 3) as octal digits, first chip = most significant bit."""
    bits = b1i_code_bits(prn)[:n]
    return "".join(str(4 * bits[i] + 2 * bits[i + 1] + bits[i + 2]) for i in range(0, n, 3))


def nh_signs() -> np.ndarray:
    """The NH code as +/-1 float32 per code period."""
    return (1.0 - 2.0 * np.array(NH_CODE, np.float32)).astype(np.float32)


def is_geo(prn: int) -> bool:
    """True for the GEO satellites (PRN 1-5, 59-63): D2 message at 500 bps, no NH code."""
    return prn in B1I_GEO_PRNS


class B1ISignal(SignalDef):
    """BeiDou B1I (``bds_b1i``, system C): 2046-chip code at 2.046 Mcps on 1561.098 MHz; MEO/IGSO send D1
    under the NH code, GEO satellites D2."""
    name = "bds_b1i"
    system = "C"
    carrier_hz = B1I_HZ
    chip_rate = B1I_CHIP_RATE
    code_len = B1I_CODE_LEN
    prns = B1I_PRNS

    def code(self, prn: int) -> np.ndarray:
        """B1I ranging code of `prn` as +/-1 float32 chips."""
        return b1i_code(prn)

    def bit_ms(self, prn: int) -> int:
        """Data bit length (ms): 20 for D1, 2 for D2 (GEO)."""
        return D2_BIT_MS if is_geo(prn) else D1_BIT_MS

    def secondary(self, prn: int):
        """The NH code (+/-1 per 1-ms code period, 20 long) for MEO/IGSO; None for GEO."""
        return None if is_geo(prn) else nh_signs()


BDS_B1I = B1ISignal()


def data_signs(prn: int, first_ms: int, count: int, rng_seed: int = 0, data: bool = True) -> np.ndarray:
    """+/-1 per code period (ms) of satellite time first_ms .. first_ms+count-1: NH x D1 bits (PRN > 5)
    or D2 bits (GEO: 1-5, 59-63).  The message bits are pseudo-random (a fixed function of PRN, seed and bit index;
    navigation decoding of B1I is not modelled).  data=False: no message (NH only for D1)."""
    ms = np.int64(first_ms) + np.arange(count, dtype=np.int64)
    bit_ms = D2_BIT_MS if is_geo(prn) else D1_BIT_MS
    out = np.ones(count, np.float32)
    if data:
        bit = ms // bit_ms
        h = (bit * np.int64(0x9E3779B1) + np.int64(prn) * np.int64(0x85EBCA77)
             + np.int64(rng_seed) * np.int64(0xC2B2AE3D)) & np.int64(0xFFFFFFFF)
        h = (h ^ (h >> 15)) * np.int64(0x2C1B3C6D) & np.int64(0xFFFFFFFF)
        h = h ^ (h >> 12)
        out *= (1.0 - 2.0 * ((h >> 7) & 1)).astype(np.float32)
    if not is_geo(prn):
        out *= nh_signs()[ms % 20]
    return out
