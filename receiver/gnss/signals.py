"""Signal definitions: physical constants, GPS L1 C/A codes.

Everything here is pure numpy and has no dependency on other receiver modules.
"""
from functools import lru_cache

import numpy as np

C_LIGHT = 299792458.0            # speed of light, m/s (IS-GPS-200)
OMEGA_E = 7.2921151467e-5        # Earth rotation rate, rad/s (WGS-84)
MU_GPS = 3.986005e14             # Earth's gravitational constant, m^3/s^2 (IS-GPS-200)
F_REL = -4.442807633e-10         # relativistic clock constant, s/sqrt(m)

# GPS L1 C/A
L1_HZ = 1575.42e6
CA_CHIP_RATE = 1.023e6
CA_CODE_LEN = 1023
CA_PERIOD_S = 1e-3
LNAV_BIT_S = 20e-3
LAMBDA_L1 = C_LIGHT / L1_HZ

# G2 tap pairs (phase selector) for PRN 1..32, IS-GPS-200 Table 3-Ia
_G2_TAPS = {
    1: (2, 6), 2: (3, 7), 3: (4, 8), 4: (5, 9), 5: (1, 9), 6: (2, 10), 7: (1, 8), 8: (2, 9),
    9: (3, 10), 10: (2, 3), 11: (3, 4), 12: (5, 6), 13: (6, 7), 14: (7, 8), 15: (8, 9),
    16: (9, 10), 17: (1, 4), 18: (2, 5), 19: (3, 6), 20: (4, 7), 21: (5, 8), 22: (6, 9),
    23: (1, 3), 24: (4, 6), 25: (5, 7), 26: (6, 8), 27: (7, 9), 28: (8, 10), 29: (1, 6),
    30: (2, 7), 31: (3, 8), 32: (4, 9),
}
GPS_PRNS = tuple(range(1, 33))
# QZSS L1 C/A (IS-QZSS-PNT, Table 3.2.2-2): the GPS C/A generator with the G2 sequence delayed by these
# numbers of chips, PRN 193..202 (satellites J01..J10)
QZSS_G2_DELAY = {193: 339, 194: 208, 195: 711, 196: 189, 197: 263, 198: 537, 199: 663, 200: 942,
                 201: 173, 202: 900}
QZSS_PRNS = tuple(sorted(QZSS_G2_DELAY))
L1CA_PRNS = GPS_PRNS + QZSS_PRNS


@lru_cache(maxsize=None)
def _g_sequences():
    """G1 and G2 (IS-GPS-200 Figure 3-9), 1023 chips each from the all-ones state (read-only)."""
    g1, g2 = [1] * 10, [1] * 10
    o1 = np.empty(CA_CODE_LEN, np.uint8)
    o2 = np.empty(CA_CODE_LEN, np.uint8)
    for i in range(CA_CODE_LEN):
        o1[i], o2[i] = g1[9], g2[9]
        f1 = g1[2] ^ g1[9]
        f2 = g2[1] ^ g2[2] ^ g2[5] ^ g2[7] ^ g2[8] ^ g2[9]
        g1 = [f1] + g1[:9]
        g2 = [f2] + g2[:9]
    o1.setflags(write=False)
    o2.setflags(write=False)
    return o1, o2


@lru_cache(maxsize=None)
def ca_code_bits(prn: int) -> np.ndarray:
    """C/A code of a GPS PRN (1..32) or a QZSS PRN (193..202) as 1023 bits (0/1, uint8), first chip first."""
    g1, g2 = _g_sequences()
    if prn in QZSS_G2_DELAY:
        out = g1 ^ np.roll(g2, QZSS_G2_DELAY[prn])
        out.setflags(write=False)
        return out
    if prn not in _G2_TAPS:
        raise ValueError(f"L1 C/A PRN must be 1..32 (GPS) or 193..202 (QZSS), got {prn}")
    t1, t2 = _G2_TAPS[prn]
    # the G2 register shifts one stage per chip: stage s at chip i holds the G2 output (stage 10) of chip
    # i + 10 - s (the sequence is periodic from the all-ones state); the phase selector XORs stages t1, t2
    i = np.arange(CA_CODE_LEN)
    out = g1 ^ g2[(i + 10 - t1) % CA_CODE_LEN] ^ g2[(i + 10 - t2) % CA_CODE_LEN]
    out.setflags(write=False)
    return out


def ca_code(prn: int) -> np.ndarray:
    """C/A code as +/-1 float32 chips (bit 0 -> +1, bit 1 -> -1)."""
    return (1.0 - 2.0 * ca_code_bits(prn)).astype(np.float32)


def sample_code(code: np.ndarray, chip_rate: float, fs: float, n: int,
                code_phase_chips: float = 0.0) -> np.ndarray:
    """Sample a periodic code at rate fs: n samples starting at code_phase_chips."""
    idx = code_phase_chips + np.arange(n) * (chip_rate / fs)
    return code[np.floor(idx).astype(np.int64) % len(code)]


class SignalDef:
    """What acquisition, tracking and the simulator need to know about one signal.

    All signals here have a 1 ms primary-code period (``code_len`` chips at ``chip_rate``).  The data
    structure is given per PRN: ``bit_ms(prn)`` code periods per data symbol and ``secondary(prn)``, an
    optional +/-1 overlay code (one value per code period) that repeats every data symbol.
    """
    name = "gps_l1ca"
    system = "G"                 # RINEX system letter, used in labels
    carrier_hz = L1_HZ
    chip_rate = CA_CHIP_RATE
    code_len = CA_CODE_LEN
    code_period_s = CA_PERIOD_S  # primary-code period (1 ms here and for B1I; Galileo E1: 4 ms)
    prns = L1CA_PRNS             # GPS 1..32 and QZSS 193..202 (same signal, same LNAV message)

    def code(self, prn: int) -> np.ndarray:
        """Primary code as +/-1 float32 chips."""
        return ca_code(prn)

    def bit_ms(self, prn: int) -> int:
        """Data-bit length in ms (20 for LNAV)."""
        return round(LNAV_BIT_S * 1e3)

    def secondary(self, prn: int):
        """+/-1 overlay code per code period (length bit_ms), or None."""
        return None

    def short_symbols(self, prn: int) -> bool:
        """The sign of the signal can change every code period or two (an overlay code, or symbols shorter
        than 10 ms: B1I's NH x D1 and D2): Doppler estimators must not integrate across code periods
        coherently, nor difference the phase of consecutive periods (a sign change reads as 500 Hz)."""
        return self.secondary(prn) is not None or self.bit_ms(prn) < 10

    def samples_to_period_start(self, code_phase_chips: float, chips_per_sample: float) -> int:
        """Samples from a block's first sample (code phase ``code_phase_chips``) to the next code period's
        first chip: where 1-ms blocks holding one symbol each begin."""
        return int(round(((self.code_len - code_phase_chips) % self.code_len) / chips_per_sample))


GPS_L1CA = SignalDef()
