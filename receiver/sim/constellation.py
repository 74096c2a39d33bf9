"""Ephemeris sources for the simulator: a RINEX navigation file or the embedded nominal constellation.

Whatever the source, the simulator uses exactly the ephemeris it broadcasts: every field is quantised to
its LNAV LSB (:func:`quantize_ephemeris`) before it drives the satellite orbit and clock, so that a receiver
decoding the simulated subframes computes the same satellite positions as the truth.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace

import numpy as np

from ..config import read_yaml
from ..errors import UserError
from ..gnss.ephemeris import Ephemeris, IonoUtc, select
from ..gnss.lnav import EPH_LSB, IONO_LSB
from ..gnss.rinex import read_rinex_nav
from ..gnss.time import WEEK_S

#: fields of Ephemeris that are broadcast as scaled integers (floats in SI units)
_SCALED = ("toe", "toc", "af0", "af1", "af2", "tgd", "sqrt_a", "e", "i0", "omega0", "omega", "m0",
           "delta_n", "idot", "omega_dot", "cuc", "cus", "crc", "crs", "cic", "cis")
_ANGLES = ("i0", "omega0", "omega", "m0")      # signed semicircle fields, kept in [-pi, pi)


def _round_to(value: float, lsb: float) -> float:
    return float(np.round(value / lsb) * lsb)


def _wrap_pi(x: float) -> float:
    return (x + math.pi) % (2.0 * math.pi) - math.pi


def quantize_ephemeris(eph: Ephemeris) -> Ephemeris:
    """The ephemeris as a receiver decodes it from LNAV subframes 1-3 (every field on its LSB grid)."""
    vals = {}
    for name in _SCALED:
        v = float(getattr(eph, name))
        if name in _ANGLES:
            v = _wrap_pi(v)
        vals[name] = _round_to(v, EPH_LSB[name])
    vals["aodo"] = int(round(eph.aodo / 900.0)) * 900
    return replace(eph, **vals)


def quantize_iono(iono: IonoUtc) -> IonoUtc:
    """Klobuchar / UTC parameters as decoded from subframe 4 page 18."""
    return replace(iono,
                   alpha=tuple(_round_to(a, IONO_LSB[f"alpha{k}"]) for k, a in enumerate(iono.alpha)),
                   beta=tuple(_round_to(b, IONO_LSB[f"beta{k}"]) for k, b in enumerate(iono.beta)),
                   a0=_round_to(iono.a0, IONO_LSB["a0"]), a1=_round_to(iono.a1, IONO_LSB["a1"]),
                   tot=_round_to(iono.tot, IONO_LSB["tot"]))


@dataclass
class Constellation:
    """Per-PRN ephemeris used for the whole run, and the broadcast ionosphere/UTC parameters."""
    ephemerides: dict            # prn -> Ephemeris (quantised)
    iono_utc: IonoUtc | None     # broadcast in subframe 4 page 18 (quantised), None when unknown
    source: str                  # "embedded:<path>" or "rinex:<path>"


def _deg(x):
    return math.radians(float(x))


def nominal_ephemerides(path, week: int, tow_s: float) -> tuple[dict, IonoUtc]:
    """Re-epoch the nominal constellation file to (week, tow_s): toe = toc = tow rounded down to 16 s.

    raan_deg is the Earth-fixed longitude of the ascending node at toe, hence
    omega0 = raan + OMEGA_E * toe (IS-GPS-200: Omega(tk) = omega0 + (omega_dot - OMEGA_E) tk - OMEGA_E toe).
    """
    from ..gnss.signals import OMEGA_E
    raw = read_yaml(path)
    sats = raw.get("satellites")
    if not isinstance(sats, list) or not sats:
        raise UserError(f"constellation file {path} has no 'satellites' list")
    toe = math.floor(tow_s / 16.0) * 16.0
    out = {}
    for k, s in enumerate(sats):
        try:
            prn = int(s["prn"])
            if not (1 <= prn <= 32 or 193 <= prn <= 202):          # GPS or QZSS (L1 C/A)
                raise ValueError
            iodc = (int(toe // 16) + 37 * prn) % 1024
            eph = Ephemeris(
                prn=prn, week=int(week), toe=toe, toc=toe,
                af0=float(s.get("af0", 0.0)), af1=float(s.get("af1", 0.0)), af2=float(s.get("af2", 0.0)),
                tgd=float(s.get("tgd", 0.0)), iode=iodc & 0xFF, iodc=iodc,
                sqrt_a=float(s["sqrt_a"]), e=float(s["e"]), i0=_deg(s["i0_deg"]),
                omega0=_wrap_pi(_deg(s["raan_deg"]) + OMEGA_E * toe), omega=_deg(s["omega_deg"]),
                m0=_deg(s["m0_deg"]), delta_n=float(s.get("delta_n", 0.0)), idot=float(s.get("idot", 0.0)),
                omega_dot=float(s.get("omega_dot", 0.0)), cuc=float(s.get("cuc", 0.0)),
                cus=float(s.get("cus", 0.0)), crc=float(s.get("crc", 0.0)), crs=float(s.get("crs", 0.0)),
                cic=float(s.get("cic", 0.0)), cis=float(s.get("cis", 0.0)), health=0, ura_index=0,
                fit_interval=0, code_on_l2=1, l2p_flag=0, aodo=0, tx_time=toe)
        except (KeyError, TypeError, ValueError):
            raise UserError(f"constellation file {path}: satellite entry {k + 1} is incomplete or invalid "
                            "(needs prn 1..32 or 193..202, sqrt_a, e, i0_deg, raan_deg, omega_deg, m0_deg)") from None
        out[prn] = quantize_ephemeris(eph)
    iu = raw.get("iono_utc") or {}
    try:
        iono = IonoUtc(alpha=tuple(float(a) for a in iu.get("alpha", (0.0,) * 4)),
                       beta=tuple(float(b) for b in iu.get("beta", (0.0,) * 4)),
                       a0=float(iu.get("a0", 0.0)), a1=float(iu.get("a1", 0.0)),
                       tot=math.floor(tow_s / 4096.0) * 4096.0, wnt=int(week),
                       dt_ls=int(iu.get("dt_ls", 18)))
        if len(iono.alpha) != 4 or len(iono.beta) != 4:
            raise ValueError
    except (TypeError, ValueError, AttributeError):
        raise UserError(f"constellation file {path}: iono_utc needs 4 alpha and 4 beta values") from None
    return out, quantize_iono(iono)


def rinex_ephemerides(path, week: int, tow_s: float) -> tuple[dict, IonoUtc | None]:
    """The healthy ephemeris of each PRN whose toe is nearest to (week, tow_s), within 4 h."""
    ephs, iono = read_rinex_nav(path)
    out = {}
    for prn, lst in sorted(ephs.items()):
        eph = select(lst, tow_s, week=week)
        if eph is not None:
            out[prn] = quantize_ephemeris(eph)
    if not out:
        raise UserError(f"RINEX file {path} has no healthy GPS ephemeris within 4 h of week {week} "
                        f"TOW {tow_s:.0f}")
    return out, (quantize_iono(iono) if iono is not None else None)


def load_constellation(source: str, rinex_path: str | None, nominal_path: str, week: int,
                       start_tow_s: float, mid_tow_s: float, qzss_path: str | None = None) -> Constellation:
    """Ephemerides for the run.

    The embedded constellation is re-epoched at the start (week, start_tow_s); RINEX sets are picked by
    the run's middle, mid_tow_s (seconds of `week`, may exceed a week).  ``qzss_path``: a nominal QZSS
    file whose satellites (PRN 193..202) are added, re-epoched the same way.
    """
    if qzss_path:
        con = load_constellation(source, rinex_path, nominal_path, week, start_tow_s, mid_tow_s)
        qz, _ = nominal_ephemerides(qzss_path, week, start_tow_s)
        return Constellation({**con.ephemerides, **qz}, con.iono_utc,
                             con.source + f"+embedded:{os.path.basename(qzss_path)}")
    if source == "rinex":
        wk = week + int(mid_tow_s // WEEK_S)
        tow = mid_tow_s % WEEK_S
        if not rinex_path:
            raise UserError("constellation.source is 'rinex' but constellation.rinex is empty")
        ephs, iono = rinex_ephemerides(rinex_path, wk, tow)
        return Constellation(ephs, iono, f"rinex:{os.path.basename(rinex_path)}")
    ephs, iono = nominal_ephemerides(nominal_path, week, start_tow_s)
    return Constellation(ephs, iono, f"embedded:{os.path.basename(nominal_path)}")
