"""BeiDou orbits for the simulator: the nominal constellation file (data/bds_nominal_constellation.yaml).

The file has the format of the nominal GPS file (Earth-fixed node longitude and mean anomaly at toe); it
is re-epoched to the scenario's start in BDT (toe = toc = BDT seconds of week rounded down to 8 s, the toe
LSB) and every field is quantised to its D1/D2 LSB (:func:`receiver.gnss.bds_nav.quantize_bds`), so the
ephemeris a receiver decodes drives exactly the simulated orbit and clock.
"""
from __future__ import annotations

import math
import os

from ..config import read_yaml
from ..errors import UserError
from ..gnss.bds_ephemeris import OMEGA_E_BDS, BdsEphemeris
from ..gnss.bds_nav import bdt_from_gps, quantize_bds
from ..gnss.signals_bds import B1I_PRNS
from ..gnss.ephemeris import IonoUtc

NOMINAL_BDS = "data/bds_nominal_constellation.yaml"


def _wrap(x):
    return (x + math.pi) % (2.0 * math.pi) - math.pi


def bds_nominal_ephemerides(path, gps_week: int, gps_tow: float) -> tuple[dict, IonoUtc]:
    """(prn -> BdsEphemeris, IonoUtc) of the nominal BeiDou constellation file, re-epoched to the scenario's start
    (GPS week and seconds of week) in BDT and quantised to the broadcast LSBs; a bad file is a UserError."""
    raw = read_yaml(path)
    sats = raw.get("satellites")
    if not isinstance(sats, list) or not sats:
        raise UserError(f"constellation file {path} has no 'satellites' list")
    wk, sow = bdt_from_gps(gps_week, gps_tow)
    toe = math.floor(sow / 8.0) * 8.0
    out = {}
    for k, s in enumerate(sats):
        try:
            prn = int(s["prn"])
            if not 1 <= prn <= 63:
                raise ValueError
            aode = (int(toe // 3600) + prn) % 32
            eph = BdsEphemeris(
                prn=prn, week=wk, toe=toe, toc=toe, af0=float(s.get("af0", 0.0)), af1=float(s.get("af1", 0.0)),
                af2=0.0, tgd=float(s.get("tgd", 0.0)), iode=aode, iodc=aode, sqrt_a=float(s["sqrt_a"]),
                e=float(s["e"]), i0=math.radians(float(s["i0_deg"])),
                omega0=_wrap(math.radians(float(s["raan_deg"])) + OMEGA_E_BDS * toe),
                omega=math.radians(float(s["omega_deg"])), m0=math.radians(float(s["m0_deg"])),
                delta_n=0.0, idot=0.0, omega_dot=float(s.get("omega_dot", 0.0)), cuc=0.0, cus=0.0, crc=0.0,
                crs=0.0, cic=0.0, cis=0.0, health=0, ura_index=0, tgd2=0.0)
        except (KeyError, TypeError, ValueError):
            raise UserError(f"constellation file {path}: satellite entry {k + 1} is incomplete or invalid "
                            "(needs prn 1..63, sqrt_a, e, i0_deg, raan_deg, omega_deg, m0_deg)") from None
        out[prn] = quantize_bds(eph)
    iu = raw.get("iono_utc") or {}
    iono = IonoUtc(alpha=tuple(float(a) for a in iu.get("alpha", (0.0,) * 4)),
                   beta=tuple(float(b) for b in iu.get("beta", (0.0,) * 4)), wnt=int(gps_week), dt_ls=18)
    return out, iono


def source_name(path, kind="bds_nominal") -> str:
    """Label of the ephemeris source for the truth file: ``<kind>:<file name>``."""
    return f"{kind}:{os.path.basename(path)}"


def bds_rinex_ephemerides(path, gps_week: int, gps_tow: float) -> tuple[dict, IonoUtc | None]:
    """Per BeiDou PRN the healthy RINEX 3 record whose toe is nearest to (gps_week, gps_tow) in BDT, within
    4 h, quantised to its D1/D2 LSBs.  The ionosphere: the file's GPSA/GPSB (else BDSA/BDSB) lines."""
    from ..gnss.ephemeris import select
    from ..gnss.rinex import read_rinex_nav
    ephs, iono = read_rinex_nav(path, systems=("C",))
    wk, sow = bdt_from_gps(gps_week, gps_tow)
    out = {}
    for prn, lst in sorted(ephs.items()):
        e = select(lst, sow, week=wk)
        if e is not None and prn in B1I_PRNS:
            out[prn] = quantize_bds(e)
    if not out:
        raise UserError(f"RINEX file {path} has no healthy BeiDou ephemeris (PRN 1-63) within 4 h of BDT week "
                        f"{wk} SOW {sow:.0f}")
    return out, iono
