"""GPS L5 ranging codes (IS-GPS-705 section 3.2.1): I5 (data) and Q5 (pilot) primary codes and the
Neuman-Hofman secondary codes.

Each primary code is 10230 chips at 10.23 Mcps (1 ms): the modulo-2 sum of two 13-stage maximal-length
sequences, both clocked at 10.23 MHz and restarted at every 1-ms epoch:

    XA(X) = 1 + X^9 + X^10 + X^12 + X^13     initial state all ones; short-cycled: reset to all ones after
                                              8190 chips (one chip before its natural 8191-chip period)
    XB(X) = 1 + X + X^3 + X^4 + X^6 + X^7 + X^8 + X^12 + X^13    free-running over the 10230 chips

The satellite-specific code is XA XOR XBi, where XBi is the XB sequence started from a PRN-specific initial
state: the all-ones state advanced by the "XB code advance" of IS-GPS-705 Table 3-Ia (a number of XB clock
cycles, one for I5 and one for Q5 per PRN; ``XB_ADVANCE_I5``/``XB_ADVANCE_Q5`` below).  Stage 13 is the
output; logic 0 is sent as +1.  The ICD prints the initial XB state in the octal/binary notation of the first
13 XB chips, rightmost bit first out; since XA starts all ones, those 13 chips are the complement of the code's
first 13 chips (``first_chips_octal``).

Provenance of the PRN tables (checked 2026-12-02, helper l5icd): ``XB_ADVANCE_I5``/``XB_ADVANCE_Q5`` (64
values) are NOT verified against ICD text.  They were entered from excerpts of other public projects that quote
IS-GPS-705 Table 3-Ia, which the project's rules do not accept as a source for code tables.  A search of the
stored ICD transcripts
    IS-GPS-705D  https://vdocuments.site/revision-record-gps-the-global-positioning-system-gps-directorate-smcgp.html
    IS-GPS-705E  https://pdfslide.net/documents/interface-specification-is-gps-705e-management-gps-iii-terminology-and-space-service.html
    IS-GPS-705A  https://docslib.org/doc/3415295/is-gps-705a-jun-2010
returned only their front matter, never the Table 3-Ia rows, so no advance (and no printed initial XB
state) could be compared with the ICD.  What is checked (tests/unit/gnss/test_gnss_l5_codes.py): the register
definitions above, that the 64 advances are distinct and give near-balanced codes with sharp autocorrelation and
low cross-correlation (a wrong advance would still pass those), and that a few advances reproduce initial XB
states that came from the same kind of secondary quotation.  TODO: compare all 64 advances and initial states
with Table 3-Ia of an official IS-GPS-705 PDF (gps.gov) before relying on a particular PRN.

Secondary codes (IS-GPS-705 3.3.2.3): NH10 = 0000110101 on I5 (one bit per 1-ms period, under the 100-sps
symbols), NH20 = 00000100110101001110 on Q5 (20 ms).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

L5_HZ = 1176.45e6
L5_CHIP_RATE = 10.23e6
L5_CODE_LEN = 10230
XA_SHORT_CYCLE = 8190
_NSTAGE = 13
_XA_TAPS = (9, 10, 12, 13)
_XB_TAPS = (1, 3, 4, 6, 7, 8, 12, 13)

#: XB code advance (chips) for GPS PRN 1..32, I5 and Q5, as in IS-GPS-705 Table 3-Ia; NOT yet verified against
#: the ICD's text (see "Provenance" in the module docstring)
XB_ADVANCE_I5 = (266, 365, 804, 1138, 1509, 1559, 1756, 2084, 2170, 2303, 2527, 2687, 2930, 3471, 3940, 4132,
                 4332, 4924, 5343, 5443, 5641, 5816, 5898, 5918, 5955, 6243, 6345, 6477, 6518, 6875, 7168, 7187)
XB_ADVANCE_Q5 = (1701, 323, 5292, 2020, 5429, 7136, 1041, 5947, 4315, 148, 535, 1939, 5206, 5910, 3595, 5135,
                 6082, 6990, 3546, 1523, 4548, 4484, 1893, 3961, 7106, 5299, 4660, 276, 4389, 3783, 1591, 1601)
L5_PRNS = tuple(range(1, 33))

NH10 = (0, 0, 0, 0, 1, 1, 0, 1, 0, 1)
NH20 = (0, 0, 0, 0, 0, 1, 0, 0, 1, 1, 0, 1, 0, 1, 0, 0, 1, 1, 1, 0)


def _run(taps, state, n):
    """Run a 13-stage Fibonacci register n clocks from ``state`` (stages 1..13, a list of 0/1): the output
    of each clock is stage 13 before the shift; the XOR of the tap stages enters stage 1.  Returns
    (outputs, final state)."""
    reg = list(state)
    out = np.empty(n, np.uint8)
    for i in range(n):
        out[i] = reg[_NSTAGE - 1]
        fb = 0
        for t in taps:
            fb ^= reg[t - 1]
        reg = [fb] + reg[:-1]
    return out, reg


@lru_cache(maxsize=None)
def xa_sequence() -> np.ndarray:
    """The XA chips of one 1-ms period (10230), with the reset to all ones after chip 8190 (read-only)."""
    first, _ = _run(_XA_TAPS, [1] * _NSTAGE, XA_SHORT_CYCLE)
    out = np.concatenate([first, first[:L5_CODE_LEN - XA_SHORT_CYCLE]])
    out.setflags(write=False)
    return out


@lru_cache(maxsize=None)
def _xb_long() -> np.ndarray:
    """The XB sequence from the all-ones state over its full 8191-chip period (read-only)."""
    out, _ = _run(_XB_TAPS, [1] * _NSTAGE, 2 ** _NSTAGE - 1)
    out.setflags(write=False)
    return out


def xb_initial_state(advance: int) -> tuple:
    """The XB register (stages 1..13) after ``advance`` clocks from all ones: the ICD's initial XB state."""
    _, reg = _run(_XB_TAPS, [1] * _NSTAGE, advance)
    return tuple(reg)


def _advance(prn: int, component: str) -> int:
    table = {"I": XB_ADVANCE_I5, "Q": XB_ADVANCE_Q5}[component]
    if prn not in L5_PRNS:
        raise ValueError(f"GPS L5 PRN must be 1..32, got {prn}")
    return table[prn - 1]


@lru_cache(maxsize=None)
def l5_code_bits(prn: int, component: str = "Q") -> np.ndarray:
    """I5 (``component="I"``) or Q5 (``"Q"``) primary code of GPS ``prn`` as 10230 bits (0/1, uint8)."""
    adv = _advance(prn, component)
    xb = _xb_long()
    idx = (adv + np.arange(L5_CODE_LEN)) % xb.size          # XB runs on from the advanced state
    out = xa_sequence() ^ xb[idx]
    out.setflags(write=False)
    return out


def l5_code(prn: int, component: str = "Q") -> np.ndarray:
    """I5 or Q5 code as +/-1 float32 chips (bit 0 -> +1)."""
    return (1.0 - 2.0 * l5_code_bits(prn, component)).astype(np.float32)


def bits_octal(bits) -> str:
    """A bit string as octal digits, the first bit most significant (len(bits) need not be a multiple of 3:
    the leading digit holds the remainder, as in the ICD's 13-bit notation)."""
    v = 0
    for b in bits:
        v = 2 * v + int(b)
    return format(v, "o")


def first_chips_octal(prn: int, component: str = "Q", n: int = 13) -> str:
    """The first n chips of a code in octal (first chip most significant)."""
    return bits_octal(l5_code_bits(prn, component)[:n])


def nh_signs(length: int) -> np.ndarray:
    """NH10 (``length=10``) or NH20 (20) as +/-1 float32 per 1-ms code period."""
    code = {10: NH10, 20: NH20}[length]
    return (1.0 - 2.0 * np.array(code, np.float32)).astype(np.float32)
