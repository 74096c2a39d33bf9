"""Satellite names: (system letter, PRN) <-> RINEX 3 labels ``G05``, ``J01``, ``C12``.

A run over one signal keys its channels by the signal's PRN numbers (``SignalDef.prns``); a run over several
signals (``signals: [gps_l1ca, bds_b1i]``, run-file ``system`` ``M``) by satellite keys (:func:`sat_key`).
The L1 C/A signal carries GPS (PRN 1..32) and QZSS (PRN 193..202) satellites: QZSS PRN 193 is RINEX
``J01`` (PRN - 192).  BeiDou B1I PRNs are ``Cnn``, Galileo E1 PRNs ``Enn``; in an epoch combining systems BeiDou PRN
p is 400 + p and Galileo PRN p is 300 + p.  ``system``
is the signal's RINEX letter
(``SignalDef.system``).
"""
from __future__ import annotations

QZSS_FIRST_PRN = 193
#: in an epoch combining systems (scripts/combined_pvt.py) BeiDou PRN p is satellite BDS_KEY + p
BDS_KEY = 400
#: ... and Galileo PRN p (1-50) is satellite GAL_KEY + p
GAL_KEY = 300

SYSTEM_NAMES = {"G": "GPS", "J": "QZSS", "C": "BeiDou", "E": "Galileo"}


#: the run-file ``system`` of a run over several signals (satellite keys as in an epoch combining systems)
MIXED = "M"


def sat_key(signal_system: str, prn: int) -> int:
    """The satellite key of PRN ``prn`` of a signal whose RINEX letter is ``signal_system`` in a run or epoch
    combining systems: BeiDou PRN p -> BDS_KEY + p; Galileo PRN p -> GAL_KEY + p; GPS and QZSS keep their PRN
    (1-32, 193-202)."""
    if signal_system == "C":
        return BDS_KEY + prn
    return GAL_KEY + prn if signal_system == "E" else prn


def split_key(key: int) -> tuple[str, int]:
    """(RINEX letter of the signal, signal PRN) of a satellite key (:func:`sat_key`): ("C", 12), ("E", 11) or
    ("G", 5); QZSS keys are signal "G" (L1 C/A) PRNs 193-202."""
    if key > BDS_KEY:
        return "C", key - BDS_KEY
    return ("E", key - GAL_KEY) if GAL_KEY < key <= GAL_KEY + 50 else ("G", key)


def sat_system(prn: int, system: str = "G") -> str:
    """The RINEX system letter of a satellite of a signal whose letter is ``system`` (``M``: a run over several
    signals, satellites keyed by :func:`sat_key`)."""
    if system in ("G", MIXED) and prn > BDS_KEY:
        return "C"
    if system == MIXED and GAL_KEY < prn <= GAL_KEY + 50:
        return "E"
    if system in ("G", MIXED) and prn >= QZSS_FIRST_PRN:
        return "J"
    return "G" if system == MIXED else system


def sat_label(prn: int, system: str = "G") -> str:
    """RINEX 3 satellite label: G05, J01 (PRN 193), C12."""
    letter = sat_system(prn, system)
    if letter == "J":
        prn = prn - QZSS_FIRST_PRN + 1
    elif letter == "C" and prn > BDS_KEY:
        prn -= BDS_KEY
    elif letter == "E" and prn > GAL_KEY:
        prn -= GAL_KEY
    return f"{letter}{prn:02d}"


def parse_label(label: str) -> tuple[str, int]:
    """(system letter, signal PRN) of a label: ``J01`` -> ("J", 193), ``C12`` -> ("C", 12)."""
    letter, num = label[0].upper(), int(label[1:])
    if letter == "J":
        return "J", num + QZSS_FIRST_PRN - 1
    return letter, num
