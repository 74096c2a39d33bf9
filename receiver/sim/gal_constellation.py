"""Galileo orbits and I/NAV content for the simulator: the nominal constellation file
(data/gal_nominal_constellation.yaml, the format of the nominal GPS file).

The file is re-epoched to the scenario's start in GST (toe = toc = GST seconds of week rounded down to 60 s,
the toe LSB) and every field is quantised to its I/NAV LSB (:func:`receiver.gnss.gal_inav.quantize_gal`), so
the ephemeris a receiver decodes drives exactly the simulated orbit and clock.  The GGTO is broadcast as zero
(valid): the simulated Galileo satellites keep GPS time, so GST = GPS time.
"""
from __future__ import annotations

import math
import os

from ..config import read_yaml
from ..errors import UserError
from ..gnss.gal_codes import GAL_PRNS
from ..gnss.gal_inav import (GST_WEEK_OFFSET, OMEGA_E_GAL, GalEphemeris, Ggto, GstUtc, InavContent, NequickG,
    gst_from_gps, quantize_gal)

NOMINAL_GAL = "data/gal_nominal_constellation.yaml"
SISA_INDEX = 107            # broadcast SISA (ICD issue 1.1 does not define the index; carried, not used)


def _wrap(x):
    return (x + math.pi) % (2.0 * math.pi) - math.pi


def gal_nominal_content(path, gps_week: int, gps_tow: float) -> dict:
    """{PRN: InavContent} of the nominal constellation file re-epoched to (gps_week, gps_tow)."""
    raw = read_yaml(path)
    sats = raw.get("satellites")
    if not isinstance(sats, list) or not sats:
        raise UserError(f"constellation file {path} has no 'satellites' list")
    gwk, gtow = gst_from_gps(gps_week, gps_tow)
    toe = math.floor(gtow / 60.0) * 60.0
    ai = list((raw.get("nequick") or {}).get("ai", (0.0, 0.0, 0.0)))
    try:
        nequick = NequickG(ai0=float(ai[0]), ai1=float(ai[1]), ai2=float(ai[2]))
    except (IndexError, TypeError, ValueError):
        raise UserError(f"constellation file {path}: nequick.ai must be three numbers") from None
    utc = GstUtc(a0=0.0, a1=0.0, dt_ls=18, tot=math.floor(gtow / 3600.0) * 3600.0 % 604800.0,
                 wnot=gwk % 256, wn_lsf=gwk % 256, dn=7, dt_lsf=18)
    ggto = Ggto(a0g=0.0, a1g=0.0, t0g=math.floor(gtow / 3600.0) * 3600.0, wn0g=gwk % 64)
    out = {}
    for k, s in enumerate(sats):
        try:
            prn = int(s["prn"])
            if prn not in GAL_PRNS:
                raise ValueError
            iod = (int(toe // 600) + 7 * prn) % 1024
            eph = GalEphemeris(
                prn=prn, week=gwk + GST_WEEK_OFFSET, toe=toe, toc=toe,
                af0=float(s.get("af0", 0.0)), af1=float(s.get("af1", 0.0)), af2=0.0, tgd=float(s.get("tgd", 0.0)),
                iode=iod, iodc=iod, sqrt_a=float(s["sqrt_a"]), e=float(s["e"]), i0=math.radians(float(s["i0_deg"])),
                omega0=_wrap(math.radians(float(s["raan_deg"])) + OMEGA_E_GAL * toe),
                omega=math.radians(float(s["omega_deg"])), m0=math.radians(float(s["m0_deg"])),
                delta_n=0.0, idot=0.0, omega_dot=float(s.get("omega_dot", 0.0)), cuc=0.0, cus=0.0, crc=0.0,
                crs=0.0, cic=0.0, cis=0.0, health=0, ura_index=SISA_INDEX,
                bgd_e1e5a=float(s.get("bgd_e1e5a", 0.0)))
        except (KeyError, TypeError, ValueError):
            raise UserError(f"constellation file {path}: satellite entry {k + 1} is incomplete or invalid "
                            "(needs prn 1..50, sqrt_a, e, i0_deg, raan_deg, omega_deg, m0_deg)") from None
        out[prn] = InavContent(quantize_gal(eph), nequick, utc, ggto)
    return out


def source_name(path) -> str:
    """The truth file's name of the nominal Galileo constellation read from ``path``."""
    return f"gal_nominal:{os.path.basename(path)}"
