"""Galileo E5a ranging codes (Galileo OS SIS ICD issue 1.1, 2010): E5a-I (data, F/NAV) and E5a-Q (pilot)
primary codes, and their secondary codes.

Primary codes (ICD sections 3.3 and 3.4.1, Table 14): 10230 chips at 10.23 Mcps (1 ms), 50 codes per component
(code number = SVID, ICD Table 22).  Each is the XOR, with zero shift, of the outputs of two 14-stage
linear feedback shift registers, both reset to their start values after 10230 clocks (the m-sequences are
16383 chips long: truncated).  Register i (stages c_1..c_14) outputs c_14; its feedback, the XOR of the stages
j whose tap a_j is 1, enters c_1 as every stage moves on by one (Fibonacci form, ICD Figure 10).

* taps (octal, Table 14), E5a-I and E5a-Q alike: register 1 40503, register 2 50661; bit j of the binary value
  (j = 0 at the LSB, not used) is a_j, so register 1 taps stages 1, 6, 8, 14 and register 2 stages
  4, 5, 7, 8, 12, 14;
* register 1 starts all ones for every code; register 2 starts from the code's octal start value of Table 15
  (E5a-I) / Table 16 (E5a-Q), bit j-1 of the binary value = stage j (so the first chip is the start value's
  bit 13 XOR 1).

These facts are shipped in ``receiver/gnss/data/gal_e5a_codes.txt``, extracted from the ICD's text by
``scripts/tools/gal_e5a_codes_from_icd.py``, with the ICD's printed first 24 chips of every code (hex) against
which the tests check the generated codes; the tests also compare all 10230 chips of all 100 codes with the
ICD's Annex C print-out when the PDF is at hand.

Secondary codes (ICD Tables 19 and 21): E5a-I carries CS20_1 (hex 842E9, 20 chips, one per 1-ms period, the
same for every satellite: one F/NAV symbol at 50 sps lasts 20 ms); E5a-Q carries CS100_n for code number n
(100 chips, 100 ms).  Issue 1.1 does not print CS100_37, CS100_38 and CS100_39 (Table 19 goes from CS100_36 to
CS100_40; its SVID allocation, Table 24, stops at 36): asking for those is a one-line error.

Conventions, as in :mod:`receiver.gnss.l5_codes` (GPS L5, the same chip rate and carrier): ``*_bits`` are
logic values 0/1 (uint8, read-only, cached per PRN), the ``e5a_*_code`` / ``*_secondary`` functions give signal
levels as +/-1 float32 with logic 1 -> -1 and logic 0 -> +1 (ICD Table 10).
"""
from __future__ import annotations

from functools import lru_cache
from importlib.resources import files

import numpy as np

from ..errors import UserError
from .gal_codes import GAL_PRNS

E5A_HZ = 1176.45e6
E5A_CHIP_RATE = 10.23e6
E5A_CODE_LEN = 10230
E5A_PERIOD_S = 1e-3
E5A_I_SYMBOL_RATE = 50.0          # F/NAV symbols/s on E5a-I (ICD Table 4): 20 code periods per symbol
CS20_LEN = 20
CS100_LEN = 100
NSTAGE = 14
MSEQ_LEN = 2 ** NSTAGE - 1        # 16383

_DATA = "gal_e5a_codes.txt"


def tap_stages(octal: str) -> tuple[int, ...]:
    """Feedback taps of the ICD's octal notation (Table 14) as the stages j = 1..14 whose a_j is 1."""
    v = int(octal, 8)
    return tuple(j for j in range(1, NSTAGE + 1) if (v >> j) & 1)


def start_stages(octal: str) -> tuple[int, ...]:
    """A register start value of the ICD's octal notation (Tables 15 / 16) as (s_1, ..., s_14), s_j = bit j-1."""
    v = int(octal, 8)
    if v >> NSTAGE or v == 0:
        raise ValueError(f"start value {octal} is not a non-zero 14-bit value")
    return tuple((v >> (j - 1)) & 1 for j in range(1, NSTAGE + 1))


@lru_cache(maxsize=None)
def _table() -> dict:
    text = files("receiver.gnss").joinpath("data", _DATA).read_text()
    out: dict = {"cs100": {}}
    for line in text.splitlines():
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if parts[0] == "TAPS":
            out[("taps", parts[1][-1])] = (parts[2], parts[3])
        elif parts[0] in ("E5AI", "E5AQ"):
            out[(parts[0][-1], int(parts[1]))] = (parts[2], parts[3])
        elif parts[0] == "CS20":
            out["cs20"] = parts[1]
        elif parts[0] == "CS100":
            out["cs100"][int(parts[1])] = parts[2]
    return out


def _check(prn: int, component: str) -> None:
    if component not in ("I", "Q"):
        raise ValueError(f"Galileo E5a component must be 'I' or 'Q', got {component!r}")
    if prn not in GAL_PRNS:
        raise ValueError(f"Galileo E5a PRN must be 1..50, got {prn}")


def register_taps(component: str) -> tuple[str, str]:
    """The octal feedback taps (register 1, register 2) of E5a-I ("I") or E5a-Q ("Q"), ICD Table 14."""
    _check(1, component)
    return _table()[("taps", component)]


def start_value(prn: int, component: str) -> str:
    """The octal start value of base register 2 for code `prn` of E5a-I / E5a-Q (ICD Table 15 / 16)."""
    _check(prn, component)
    return _table()[(component, prn)][0]


def printed_first_chips(prn: int, component: str) -> str:
    """The ICD's printed first 24 chips (6 hex digits) of code `prn` (Table 15 / 16, "Initial Sequence")."""
    _check(prn, component)
    return _table()[(component, prn)][1]


@lru_cache(maxsize=None)
def _mseq(taps_octal: str) -> tuple[np.ndarray, dict]:
    """One full period (16383 chips, 0/1 uint8) of the register with these taps from the all-ones state, and
    {state: clock index} of every state it passes through (state as the integer sum s_j 2^(j-1))."""
    mask = sum(1 << (j - 1) for j in tap_stages(taps_octal))
    reg = (1 << NSTAGE) - 1
    out = np.empty(MSEQ_LEN, np.uint8)
    where = {}
    for k in range(MSEQ_LEN):
        where[reg] = k
        out[k] = reg >> (NSTAGE - 1)                     # stage 14 is the output
        fb = (reg & mask).bit_count() & 1
        reg = ((reg << 1) | fb) & ((1 << NSTAGE) - 1)    # c_j -> c_j+1, the feedback enters c_1
    if len(where) != MSEQ_LEN or reg != (1 << NSTAGE) - 1:
        raise ValueError(f"taps {taps_octal} do not give a maximal-length sequence")
    out.setflags(write=False)
    return out, where


def register_output(taps_octal: str, start_octal: str, n: int = E5A_CODE_LEN) -> np.ndarray:
    """The first n outputs (0/1 uint8) of a 14-stage register with these taps started from this start value:
    the register's m-sequence read on from the start state."""
    seq, where = _mseq(taps_octal)
    k0 = where[int(start_octal, 8)]
    return seq[(k0 + np.arange(n)) % MSEQ_LEN]


@lru_cache(maxsize=None)
def e5a_code_bits(prn: int, component: str = "Q") -> np.ndarray:
    """E5a-I (``component="I"``) or E5a-Q (``"Q"``) primary code of code number ``prn`` (1..50) as 10230
    logic values (0/1 uint8, read-only), first chip first; cached per PRN and component."""
    _check(prn, component)
    t1, t2 = register_taps(component)
    all_ones = format((1 << NSTAGE) - 1, "o")
    out = register_output(t1, all_ones) ^ register_output(t2, start_value(prn, component))
    out.setflags(write=False)
    return out


def e5a_i_code(prn: int) -> np.ndarray:
    """E5a-I (data) primary code as +/-1 float32 chips (logic 0 -> +1)."""
    return (1.0 - 2.0 * e5a_code_bits(prn, "I")).astype(np.float32)


def e5a_q_code(prn: int) -> np.ndarray:
    """E5a-Q (pilot) primary code as +/-1 float32 chips (logic 0 -> +1)."""
    return (1.0 - 2.0 * e5a_code_bits(prn, "Q")).astype(np.float32)


def bits_hex(bits) -> str:
    """Logic values as hex digits, the first value the most significant bit of the first digit, the last
    digit filled up with zeros (ICD Annex C.2)."""
    b = np.asarray(bits, np.uint8)
    pad = (-b.size) % 4
    b = np.concatenate([b, np.zeros(pad, np.uint8)]).reshape(-1, 4)
    return "".join("0123456789ABCDEF"[v] for v in b @ np.array([8, 4, 2, 1]))


def first_chips_hex(prn: int, component: str = "Q", n: int = 24) -> str:
    """The first n chips of a generated code as hex (ICD notation of Tables 15 / 16 for n = 24)."""
    return bits_hex(e5a_code_bits(prn, component)[:n])


def _hex_bits(h: str, n: int) -> np.ndarray:
    out = np.array([(int(d, 16) >> s) & 1 for d in h for s in (3, 2, 1, 0)], np.uint8)[:n]
    out.setflags(write=False)
    return out


@lru_cache(maxsize=None)
def e5a_i_secondary_bits() -> np.ndarray:
    """CS20_1, the E5a-I secondary code, as 20 logic values (0/1, read-only), first chip first."""
    return _hex_bits(_table()["cs20"], CS20_LEN)


@lru_cache(maxsize=None)
def e5a_q_secondary_bits(prn: int) -> np.ndarray:
    """CS100_prn, the E5a-Q secondary code of code number ``prn``, as 100 logic values (0/1, read-only)."""
    _check(prn, "Q")
    h = _table()["cs100"].get(prn)
    if h is None:
        raise UserError(f"Galileo E5a-Q secondary code CS100_{prn} is not printed in the Galileo OS SIS ICD "
                        "issue 1.1 (Table 19 skips CS100_37..39): no E5a-Q pilot for this PRN")
    return _hex_bits(h, CS100_LEN)


def e5a_q_prns() -> tuple[int, ...]:
    """The code numbers whose E5a-Q pilot is complete (primary and CS100 secondary code): 1..50 without the
    CS100 codes the data file lacks (37, 38, 39 for issue 1.1)."""
    return tuple(p for p in GAL_PRNS if p in _table()["cs100"])


def e5a_i_secondary() -> np.ndarray:
    """CS20_1 as +/-1 float32, one value per 1-ms primary-code period (the same for every satellite)."""
    return (1.0 - 2.0 * e5a_i_secondary_bits()).astype(np.float32)


def e5a_q_secondary(prn: int) -> np.ndarray:
    """CS100_prn as +/-1 float32, one value per 1-ms primary-code period (100 ms)."""
    return (1.0 - 2.0 * e5a_q_secondary_bits(prn)).astype(np.float32)
