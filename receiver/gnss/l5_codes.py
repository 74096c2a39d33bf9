"""GPS L5 ranging codes (IS-GPS-705 section 3.2.1): I5 (data) and Q5 (pilot) primary codes and the
Neuman-Hofman secondary codes.

Each primary code is 10230 chips at 10.23 Mcps (1 ms): the modulo-2 sum of two 13-stage maximal-length
sequences, both clocked at 10.23 MHz and restarted at every 1-ms epoch:

    XA(X) = 1 + X^9 + X^10 + X^12 + X^13     initial state all ones; short-cycled: reset to all ones after
                                              8190 chips (one chip before its natural 8191-chip period)
    XB(X) = 1 + X + X^3 + X^4 + X^6 + X^7 + X^8 + X^12 + X^13    free-running over the 10230 chips

The satellite-specific code is XA XOR XBi, where XBi is the XB sequence started from a PRN-specific initial
state: the all-ones state advanced by the "XB code advance" of IS-GPS-705 Table 3-Ia (a number of XB clock
cycles, one for I5 and one for Q5 per PRN; :func:`xb_advances`).  Stage 13 is the
output; logic 0 is sent as +1.  The ICD prints the initial XB state in the octal/binary notation of the first
13 XB chips, rightmost bit first out; since XA starts all ones, those 13 chips are the complement of the code's
first 13 chips (``first_chips_octal``).

The PRN table (the XB code advances of IS-GPS-705 Table 3-Ia) is not shipped: the project takes code tables
from the ICD's own text only, and no copy of IS-GPS-705 was available to transcribe it from (only other
projects' tables, which may not be copied).  Give the table as a CSV file, one line per PRN
``prn,i5_advance,q5_advance`` (chips, transcribed from Table 3-Ia of the official IS-GPS-705), in the
environment variable ``GNSSRX_L5_XB_TABLE``; without it any use of a GPS L5 code is a one-line error.  The
test suite runs the L5 machinery (simulator, aided acquisition, tracking, ionosphere-free fix) on a table of
its own (distinct advances: valid members of the same code family, not the broadcast codes), which checks
that simulator and receiver agree, not that the codes are GPS's.

Secondary codes (IS-GPS-705 3.3.2.3): NH10 = 0000110101 on I5 (one bit per 1-ms period, under the 100-sps
symbols), NH20 = 00000100110101001110 on Q5 (20 ms).
"""
from __future__ import annotations

import os
from functools import lru_cache

import numpy as np

from ..errors import UserError

L5_HZ = 1176.45e6
L5_CHIP_RATE = 10.23e6
L5_CODE_LEN = 10230
XA_SHORT_CYCLE = 8190
_NSTAGE = 13
_XA_TAPS = (9, 10, 12, 13)
_XB_TAPS = (1, 3, 4, 6, 7, 8, 12, 13)

#: environment variable naming the CSV file of Table 3-Ia's XB code advances (see the module docstring)
XB_TABLE_ENV = "GNSSRX_L5_XB_TABLE"
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


@lru_cache(maxsize=None)
def _read_table(path: str) -> tuple[tuple[int, ...], tuple[int, ...]]:
    rows = {}
    try:
        with open(path) as f:
            for line in f:
                line = line.split("#")[0].strip()
                if line and not line.lower().startswith("prn"):
                    prn, i5, q5 = (int(v) for v in line.split(","))
                    rows[prn] = (i5, q5)
    except (OSError, ValueError) as e:
        raise UserError(f"{XB_TABLE_ENV}={path}: cannot read the L5 XB code advances ({e})") from None
    if sorted(rows) != list(L5_PRNS) or not all(0 < a < 2 ** _NSTAGE - 1 for r in rows.values() for a in r):
        raise UserError(f"{XB_TABLE_ENV}={path}: needs one line 'prn,i5_advance,q5_advance' for each PRN 1..32, "
                        "advances 1..8190")
    return tuple(rows[p][0] for p in L5_PRNS), tuple(rows[p][1] for p in L5_PRNS)


def xb_advances() -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The XB code advances (I5, Q5) for PRN 1..32 from the file named by ``GNSSRX_L5_XB_TABLE``."""
    path = os.environ.get(XB_TABLE_ENV)
    if not path:
        raise UserError("GPS L5 codes need the XB code advances of IS-GPS-705 Table 3-Ia, which gnssrx does not "
                        f"ship: set {XB_TABLE_ENV} to a CSV file 'prn,i5_advance,q5_advance' (docs/dual-frequency.md)")
    return _read_table(path)


def _advance(prn: int, component: str) -> int:
    if prn not in L5_PRNS:
        raise ValueError(f"GPS L5 PRN must be 1..32, got {prn}")
    i5, q5 = xb_advances()
    return {"I": i5, "Q": q5}[component][prn - 1]


@lru_cache(maxsize=None)
def l5_code_bits(prn: int, component: str = "Q") -> np.ndarray:
    """I5 (``component="I"``) or Q5 (``"Q"``) primary code of GPS ``prn`` as 10230 bits (0/1, uint8); cached
    per PRN and component for the process (the table file is read once)."""
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
