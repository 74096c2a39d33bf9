"""RINEX navigation files: GPS / QZSS, BeiDou and Galileo broadcast ephemerides (reader 2.x/3.x, writer 3.04).

A reader call takes the records of the systems it asks for (GPS + QZSS, BeiDou, or Galileo); records of other
systems in RINEX 3 mixed files are skipped.  Galileo records: :mod:`receiver.gnss.rinex_gal`.
"""
from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np

from ..errors import UserError
from .ephemeris import Ephemeris, IonoUtc
from .rinex_gal import gal_from_values, gal_header_lines, gal_record
from .rinex_text import (_SYSTEM_NAME, _d12, _d19, _fixed, _hdr, _header_values, _nav_lines, _num,  # noqa: F401
                         _records)
from .time import WEEK_S, calendar_from_gps_time, gps_time_from_calendar

# URA index -> upper bound of the URA (m), IS-GPS-200 20.3.3.3.1.3
_URA_BOUNDS = (2.40, 3.40, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0, 96.0, 192.0, 384.0, 768.0,
               1536.0, 3072.0, 6144.0)
# nominal URA value (m) written for each index
_URA_NOMINAL = (2.0, 2.8, 4.0, 5.7, 8.0, 11.3, 16.0, 32.0, 64.0, 128.0, 256.0, 512.0,
                1024.0, 2048.0, 4096.0, 6144.0)


def ura_index_from_m(ura_m: float) -> int:
    """URA (m) as written in RINEX -> 4-bit URA index (15 when unknown/huge)."""
    if not np.isfinite(ura_m) or ura_m < 0:
        return 15
    for i, b in enumerate(_URA_BOUNDS):
        if ura_m <= b:
            return i
    return 15


def ura_m_from_index(idx: int) -> float:
    """Nominal URA (m) of a 4-bit URA index (clipped to 0..15), the value written to RINEX."""
    return _URA_NOMINAL[min(max(int(idx), 0), 15)]


def _eph_from_values(prn, epoch, v, path):
    """v: the 31 values of a record (af0, af1, af2, then 7 broadcast-orbit lines x 4)."""
    y, mo, d, h, mi, s = epoch
    _, toc = gps_time_from_calendar(y, mo, d, h, mi, s)
    week = int(round(v[21]))
    tx = v[27]
    fit_hours = v[28]
    return Ephemeris(
        prn=prn, week=week, toe=v[11], toc=toc,
        af0=v[0], af1=v[1], af2=v[2], tgd=v[25],
        iode=int(round(v[3])), iodc=int(round(v[26])),
        sqrt_a=v[10], e=v[8], i0=v[15], omega0=v[13], omega=v[17], m0=v[6],
        delta_n=v[5], idot=v[19], omega_dot=v[18],
        cuc=v[7], cus=v[9], crc=v[16], crs=v[4], cic=v[12], cis=v[14],
        health=int(round(v[24])), ura_index=ura_index_from_m(v[23]),
        fit_interval=1 if fit_hours > 4.0 else 0,
        code_on_l2=int(round(v[20])), l2p_flag=int(round(v[22])), aodo=0,
        tx_time=float("nan") if abs(tx) >= 0.9e9 else tx,
    )


def _bds_from_values(prn, epoch, v):
    """BeiDou record (RINEX 3: epoch = toc in BDT; toe, week, transmission time in BDT)."""
    from .bds_ephemeris import BdsEphemeris
    y, mo, d, h, mi, s = epoch
    _, toc = gps_time_from_calendar(y, mo, d, h, mi, s)      # BDT calendar -> BDT seconds of week
    return BdsEphemeris(
        prn=prn, week=int(round(v[21])), toe=v[11], toc=toc, af0=v[0], af1=v[1], af2=v[2], tgd=v[25],
        iode=int(round(v[3])), iodc=int(round(v[28])), sqrt_a=v[10], e=v[8], i0=v[15], omega0=v[13],
        omega=v[17], m0=v[6], delta_n=v[5], idot=v[19], omega_dot=v[18], cuc=v[7], cus=v[9], crc=v[16],
        crs=v[4], cic=v[12], cis=v[14], health=int(round(v[24])), ura_index=ura_index_from_m(v[23]),
        tgd2=v[26], tx_time=v[27] if abs(v[27]) < 0.9e9 else float("nan"))




def _iono_utc(h: dict) -> IonoUtc | None:
    """The GPS-style iono/UTC set of a header (:func:`_header_values`), None when it has none."""
    if h["alpha"] is None and h["beta"] is None and h["gput"] is None:
        return None
    a0, a1, tot, wnt = h["gput"] or (None, None, None, None)
    dt_ls, dt_lsf, wn_lsf, dn = h["leap"] or (None, None, None, None)
    return IonoUtc(alpha=h["alpha"] or (0.0,) * 4, beta=h["beta"] or (0.0,) * 4,
                   a0=a0 or 0.0, a1=a1 or 0.0, tot=float(tot or 0), wnt=int(wnt or 0),
                   dt_ls=int(dt_ls or 0), wn_lsf=wn_lsf, dn=dn, dt_lsf=dt_lsf)


def _record_values(rec, version: float):
    """(satellite letter, PRN, epoch tuple, the 31 values) of one record of the GPS/BeiDou/Galileo layout
    (ValueError / IndexError when it is malformed); QZSS Jnn is PRN 192 + nn."""
    head = rec[0]
    if version < 3:
        letter, prn = "G", int(head[0:2])
        yy = int(head[3:5])
        year = yy + (2000 if yy < 80 else 1900)
        epoch = (year, int(head[6:8]), int(head[9:11]), int(head[12:14]), int(head[15:17]), float(head[17:22]))
        vals = _fixed(head, 22, 19, 3)
        orbit_start = 3
    else:
        letter = head[0].upper()
        prn = int(head[1:3]) + (192 if letter == "J" else 0)
        epoch = (int(head[4:8]), int(head[9:11]), int(head[12:14]), int(head[15:17]),
                 int(head[18:20]), float(head[21:23]))
        vals = _fixed(head, 23, 19, 3)
        orbit_start = 4
    if len(rec) < 8:
        raise ValueError(f"record has {len(rec)} lines, expected 8")
    for ln in rec[1:8]:
        vals += _fixed(ln.ljust(orbit_start + 76), orbit_start, 19, 4)
    return letter, prn, epoch, vals


def _nav_records(path: Path, body, version: float, systems):
    """The ephemerides of the records of ``systems`` in a navigation file's body, in file order."""
    if version < 3:
        recs = _records(body, lambda ln: ln[:3].strip() != "")
    else:
        recs = _records(body, lambda ln: ln[:1] != " ")
    for rec in recs:
        head = rec[0]
        if version >= 3 and head[0].upper() not in systems:     # other systems' records (other layouts)
            continue
        try:
            letter, prn, epoch, vals = _record_values(rec, version)
            if letter == "C":
                eph = _bds_from_values(prn, epoch, vals)
            elif letter == "E":
                eph = gal_from_values(prn, epoch, vals)
            else:
                eph = _eph_from_values(prn, epoch, vals, path)
        except (ValueError, IndexError) as exc:
            what = "Galileo" if head[:1].upper() == "E" else "GPS"
            raise UserError(f"{path}: bad {what} navigation record '{head.strip()[:23]}': {exc}") from None
        if eph is not None:
            yield eph


def read_rinex_nav(path, systems=("G", "J")):
    """Read a RINEX 2.x or 3.x navigation file: GPS and QZSS records (QZSS Jnn as PRN 192 + nn), or with
    ``systems=("C",)`` the BeiDou records of a RINEX 3 file (:class:`BdsEphemeris`, BDT), or with
    ``systems=("E",)`` its Galileo I/NAV records (:class:`GalEphemeris`, layout and conventions in
    :mod:`receiver.gnss.rinex_gal`).

    Returns (dict prn -> list of Ephemeris sorted by (week, toe), IonoUtc or None).
    Raises UserError when the file is missing or has no usable record of those systems.
    """
    path = Path(path)
    lines, version = _nav_lines(path, systems)
    h, end = _header_values(path, lines, version, systems)
    iono = _iono_utc(h)
    out: dict[int, list[Ephemeris]] = {}
    seen = set()
    for eph in _nav_records(path, lines[end + 1:], version, systems):
        if getattr(eph, "system", "G") == "E":         # one record per batch (files repeat I/NAV batches)
            key = (eph.prn, eph.week, eph.toe, eph.iode)
            if key in seen:
                continue
            seen.add(key)
        out.setdefault(eph.prn, []).append(eph)
    if not out:
        if "C" in systems or "E" in systems:
            letter = "C" if "C" in systems else "E"
            raise UserError(f"{path}: no usable {_SYSTEM_NAME[letter]} navigation records (RINEX 3 "
                            f"'{letter}nn' records needed)")
        raise UserError(f"{path}: no usable GPS navigation records (header only, no GPS records, or records "
                        f"not in the RINEX {version:g} layout the header declares)")
    for prn in out:
        out[prn].sort(key=lambda e: (e.week, e.toe))
    return out, iono


def read_rinex_nav_for(path, letters):
    """The records of a navigation file for a run over the signals whose RINEX letters are ``letters``
    (``["G"]``, ``["E"]``, ``["G", "E", "C"]``, ...): one letter gives that system's records keyed by PRN
    (G: GPS + QZSS); several give each system's records keyed by satellite key
    (:func:`receiver.gnss.satid.sat_key`: Galileo 300 + p, BeiDou 400 + p), a further system without records
    contributing none.  Returns (ephemerides, the Klobuchar set of the first system that has one).
    UserError as :func:`read_rinex_nav` (for the first system)."""
    from .satid import sat_key
    letters = list(letters)
    pick = [(letter,) if letter in ("C", "E") else ("G", "J") for letter in letters]
    if len(letters) == 1:
        return read_rinex_nav(path, systems=pick[0])
    ephs, iono = {}, None
    for i, (letter, systems) in enumerate(zip(letters, pick)):
        try:
            e, io = read_rinex_nav(path, systems=systems)
        except UserError:
            if i == 0:
                raise
            continue
        ephs.update({sat_key(letter, p): lst for p, lst in e.items()})
        iono = iono if iono is not None else io
    return ephs, iono


def _bds_record(e) -> list:
    """RINEX 3.04 BeiDou navigation record (epoch = toc in BDT; toe, week and transmission time in BDT).
    The Klobuchar set goes into the GPSA/GPSB header lines: gnssrx applies the broadcast BeiDou alpha/beta
    with the GPS Klobuchar model (the simulator does the same), and readers such as RTKLIB take those lines
    for their Klobuchar correction."""
    from .bds_ephemeris import BDT_WEEK_OFFSET
    t = calendar_from_gps_time(e.week + BDT_WEEK_OFFSET, e.toc)      # BDT calendar (same epoch layout)
    sec = t.second + t.microsecond * 1e-6
    out = [f"C{e.prn:02d} {t.year:04d} {t.month:02d} {t.day:02d} {t.hour:02d} {t.minute:02d} "
           f"{int(round(sec)):02d}" + _d19(e.af0) + _d19(e.af1) + _d19(e.af2) + "\n"]
    tx = e.tx_time if np.isfinite(e.tx_time) else e.toe
    rows = [(e.iode, e.crs, e.delta_n, e.m0), (e.cuc, e.e, e.cus, e.sqrt_a), (e.toe, e.cic, e.omega0, e.cis),
            (e.i0, e.crc, e.omega, e.omega_dot), (e.idot, 0.0, e.week, 0.0),
            (ura_m_from_index(e.ura_index), e.health, e.tgd, e.tgd2), (tx, e.iodc)]
    for row in rows:
        out.append("    " + "".join(_d19(float(v)) for v in row) + "\n")
    return out


def _gps_record(e, system: str) -> list:
    """RINEX 3.04 GPS / QZSS navigation record (epoch = toc, in the week of toc)."""
    from .satid import sat_label
    dtoc = e.toc - e.toe
    toc_week = e.week + (1 if dtoc < -WEEK_S / 2 else -1 if dtoc > WEEK_S / 2 else 0)
    t = calendar_from_gps_time(toc_week, e.toc)
    sec = t.second + t.microsecond * 1e-6
    out = [f"{sat_label(e.prn, system)} {t.year:04d} {t.month:02d} {t.day:02d} {t.hour:02d} "
           f"{t.minute:02d} {int(round(sec)):02d}" + _d19(e.af0) + _d19(e.af1) + _d19(e.af2) + "\n"]
    tx = e.tx_time if np.isfinite(e.tx_time) else 0.9999e9
    rows = [
        (e.iode, e.crs, e.delta_n, e.m0),
        (e.cuc, e.e, e.cus, e.sqrt_a),
        (e.toe, e.cic, e.omega0, e.cis),
        (e.i0, e.crc, e.omega, e.omega_dot),
        (e.idot, e.code_on_l2, e.week, e.l2p_flag),
        (ura_m_from_index(e.ura_index), e.health, e.tgd, e.iodc),
        (tx, 6.0 if e.fit_interval else 4.0),
    ]
    for row in rows:
        out.append("    " + "".join(_d19(float(v)) for v in row) + "\n")
    return out


def _record_system(e, system: str) -> str:
    """The RINEX letter of an ephemeris: its class' ``system`` (C, E), else from the PRN (G or J)."""
    from .satid import sat_system
    own = getattr(e, "system", "G")
    return own if own in ("C", "E") else sat_system(e.prn, system)


def _header_lines(iono: IonoUtc | None, gal: dict | None) -> list:
    """The correction lines of a navigation file's header: the GPS Klobuchar / GPS-UTC / leap-second
    set of ``iono`` and the Galileo lines of ``gal`` (:func:`receiver.gnss.rinex_gal.gal_header_lines`)."""
    g = gal_header_lines(gal) if gal else []
    out = []
    if iono is not None:
        out.append(_hdr("GPSA " + "".join(_d12(v) for v in iono.alpha), "IONOSPHERIC CORR"))
        out.append(_hdr("GPSB " + "".join(_d12(v) for v in iono.beta), "IONOSPHERIC CORR"))
    out += [ln for ln in g if "IONOSPHERIC CORR" in ln]
    if iono is not None:
        out.append(_hdr(f"GPUT {iono.a0:17.10E}{iono.a1:16.9E}{int(iono.tot):7d}{int(iono.wnt):5d}",
                        "TIME SYSTEM CORR"))
    out += [ln for ln in g if "IONOSPHERIC CORR" not in ln]
    if iono is not None:
        leap = f"{int(iono.dt_ls):6d}"
        if iono.dt_lsf is not None and iono.wn_lsf is not None and iono.dn is not None:
            leap += f"{int(iono.dt_lsf):6d}{int(iono.wn_lsf):6d}{int(iono.dn):6d}"
        out.append(_hdr(leap, "LEAP SECONDS"))
    elif gal and gal.get("utc") is not None:
        out.append(_hdr(f"{int(gal['utc'].dt_ls):6d}", "LEAP SECONDS"))
    return out


def write_rinex_nav(path, ephs, iono: IonoUtc | None = None, program: str = "gnssrx", system: str = "G",
                    gal: dict | None = None):
    """Write a RINEX 3.04 navigation file: GPS and QZSS records (QZSS PRNs 193.. as J01..), BeiDou
    (:class:`BdsEphemeris`) and Galileo (:class:`GalEphemeris`) ones; several systems make a mixed file.

    ephs: dict prn -> list of Ephemeris, or a flat iterable of Ephemeris.  gal: the Galileo header
    parameters ({"nequick", "utc", "ggto", "gst_week"}, :func:`receiver.gnss.rinex_gal.gal_header_lines`),
    None for none.
    """
    if isinstance(ephs, dict):
        flat = [e for lst in ephs.values() for e in lst]
    else:
        flat = list(ephs)
    flat.sort(key=lambda e: (e.week, e.toc, e.prn))
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%d %H%M%S UTC")
    letters = {_record_system(e, system) for e in flat}
    kind = {frozenset("G"): "G: GPS", frozenset("J"): "J: QZSS", frozenset("C"): "C: BeiDou",
            frozenset("E"): "E: Galileo"}.get(frozenset(letters), "M: MIXED")
    out = [_hdr(f"{3.04:9.2f}" + " " * 11 + f"N: GNSS NAV DATA    {kind}", "RINEX VERSION / TYPE"),
           _hdr(f"{program:<20}{'':<20}{now:<20}", "PGM / RUN BY / DATE")]
    out += _header_lines(iono, gal)
    out.append(_hdr("", "END OF HEADER"))
    for e in flat:
        letter = _record_system(e, system)
        out.extend(_bds_record(e) if letter == "C" else gal_record(e) if letter == "E" else _gps_record(e, system))
    Path(path).write_text("".join(out))
