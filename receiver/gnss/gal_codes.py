"""Galileo E1 Open Service ranging codes (Galileo OS SIS ICD issue 1.1, 2010).

Primary codes (ICD section 3.4.2, Annex C.7 / C.8): E1-B (data component) and E1-C (pilot component) are
memory codes of 4092 chips at 1.023 Mcps (4 ms), 50 codes each, one per PRN (code number = SVID, ICD
Table 23).  They are shipped in ``receiver/gnss/data/gal_e1_codes.txt``, extracted from the ICD's hexadecimal
print-out by ``scripts/tools/gal_e1_codes_from_icd.py``: 1023 hex digits per code, the first chip in time is
the most significant bit of the first digit.

Secondary code (ICD Tables 19 and 21): E1-C carries CS25_1, 25 chips (one per primary-code period: 100 ms),
the same for every satellite; hex 380AD90 with three fill zeros.

Logic levels (ICD Table 10): logic 1 -> -1, logic 0 -> +1.

Sub-carriers (ICD section 2.3.3): E1-B = alpha sc(1.023 MHz) + beta sc(6.138 MHz), E1-C = alpha sc(1.023) -
beta sc(6.138), alpha = sqrt(10/11), beta = sqrt(1/11), sc_X(t) = sgn(sin(2 pi R_X t)).  The receiver's
replicas use the BOC(1,1) part alone (``boc11``): see docs/galileo.md.
"""
from __future__ import annotations

from functools import lru_cache
from importlib.resources import files

import numpy as np

E1_HZ = 1575.42e6
E1_CHIP_RATE = 1.023e6
E1_CODE_LEN = 4092
E1_PERIOD_S = 4e-3
E1B_SYMBOL_RATE = 250.0          # symbols/s: one I/NAV symbol per 4-ms code period
CS25_LEN = 25
GAL_PRNS = tuple(range(1, 51))
CBOC_ALPHA = float(np.sqrt(10.0 / 11.0))
CBOC_BETA = float(np.sqrt(1.0 / 11.0))

_DATA = "gal_e1_codes.txt"


def _hex_bits(h: str, n: int) -> np.ndarray:
    """Hex digits -> n bits (0/1 uint8), the first digit's most significant bit first."""
    b = np.frombuffer(bytes.fromhex(h if len(h) % 2 == 0 else h + "0"), np.uint8)
    return np.unpackbits(b)[:n].copy()


@lru_cache(maxsize=None)
def _table() -> dict:
    text = files("receiver.gnss").joinpath("data", _DATA).read_text()
    out = {}
    for line in text.splitlines():
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if parts[0] == "CS25":
            out["CS25"] = parts[1]
        else:
            out[(parts[0], int(parts[1]))] = parts[2]
    return out


def code_hex(component: str, prn: int) -> str:
    """The ICD's 1023 hex digits of the E1-B (component "B") or E1-C ("C") code of `prn` (1..50)."""
    if component not in ("B", "C"):
        raise ValueError(f"Galileo E1 component must be 'B' or 'C', got {component!r}")
    if prn not in GAL_PRNS:
        raise ValueError(f"Galileo E1 PRN must be 1..50, got {prn}")
    return _table()[("E1" + component, prn)]


@lru_cache(maxsize=None)
def e1_code_bits(component: str, prn: int) -> np.ndarray:
    """E1-B / E1-C primary code as 4092 bits (0/1 uint8, read-only), first chip first."""
    out = _hex_bits(code_hex(component, prn), E1_CODE_LEN)
    out.setflags(write=False)
    return out


def e1b_code(prn: int) -> np.ndarray:
    """E1-B primary code as +/-1 float32 chips."""
    return (1.0 - 2.0 * e1_code_bits("B", prn)).astype(np.float32)


def e1c_code(prn: int) -> np.ndarray:
    """E1-C primary code as +/-1 float32 chips."""
    return (1.0 - 2.0 * e1_code_bits("C", prn)).astype(np.float32)


@lru_cache(maxsize=None)
def cs25_bits() -> np.ndarray:
    """The E1-C secondary code CS25_1 as 25 bits (0/1, read-only), first chip first."""
    out = _hex_bits(_table()["CS25"], CS25_LEN)
    out.setflags(write=False)
    return out


def cs25_signs() -> np.ndarray:
    """CS25_1 as +/-1 float32, one value per 4-ms primary-code period."""
    return (1.0 - 2.0 * cs25_bits()).astype(np.float32)


def boc11(chips: np.ndarray) -> np.ndarray:
    """BOC(1,1) (sine phase) of a +/-1 chip sequence: two half-chips per chip, +c then -c
    (sc(t) = sgn(sin(2 pi 1.023 MHz t)) is +1 in the first half of each chip), float32 at 2.046 MHz."""
    c = np.asarray(chips, np.float32)
    return np.stack([c, -c], axis=1).reshape(-1)


def cboc(chips: np.ndarray, component: str) -> np.ndarray:
    """CBOC(6,1,1/11) of a +/-1 chip sequence, 12 samples per chip (12.276 MHz): alpha sc_a +/- beta sc_b
    (+ for E1-B, - for E1-C), ICD Eq. 11.  Used to measure what the BOC(1,1) replica loses."""
    if component not in ("B", "C"):
        raise ValueError(f"Galileo E1 component must be 'B' or 'C', got {component!r}")
    k = np.arange(12)
    sc_a = np.where(k < 6, 1.0, -1.0)                 # one 1.023-MHz period per chip
    sc_b = np.where(k % 2 == 0, 1.0, -1.0)            # six 6.138-MHz periods per chip
    sub = CBOC_ALPHA * sc_a + (CBOC_BETA if component == "B" else -CBOC_BETA) * sc_b
    return (np.asarray(chips, np.float64)[:, None] * sub[None, :]).reshape(-1).astype(np.float32)
