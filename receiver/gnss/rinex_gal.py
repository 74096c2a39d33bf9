"""RINEX 3.04 / 3.05 Galileo navigation records and header lines (used by :mod:`receiver.gnss.rinex`).

Record (``Enn``, the layout of the RINEX 3.04 / 3.05 Galileo navigation data record): epoch = toc in GST,
af0 af1 af2; then IODnav Crs delta_n M0 / Cuc e Cus sqrt(A) / toe Cic Omega0 Cis / i0 Crc omega Omega_dot /
IDOT, data sources, GAL week, spare / SISA (m), SV health, BGD E5a/E1, BGD E5b/E1 / transmission time.  The
GAL week is continuous and aligned with the GPS week (GST week + 1024), as
:class:`receiver.gnss.gal_inav.GalEphemeris` keeps it; GST seconds of week run with GPS seconds of week, so
the GPS calendar routines give the GST calendar.

* Data sources: gnssrx decodes I/NAV on E1-B with the (E1, E5b) clock, written as bits 0 and 9 (513).  On
  reading, records without an I/NAV bit (F/NAV, the (E1, E5a) clock) are skipped: an E1 single-frequency
  user applies the I/NAV clock with BGD(E1, E5b); repeated records of one batch (same toe and IODnav, e.g.
  from E1-B and E5b-I) are read once.
* Health: bit 0 E1-B DVS, bits 1-2 E1-B HS, bits 6 / 7-8 E5b DVS / HS (GalEphemeris.health is bits 0-2).
* SISA: metres in the file, the index in ``GalEphemeris.ura_index`` (table of the OS SIS ICD issue 1.2 and
  later; issue 1.1 leaves it to a future update).
* Header: ``IONOSPHERIC CORR`` ``GAL`` (NeQuick-G ai0, ai1, ai2), ``TIME SYSTEM CORR`` ``GAUT`` (GST-UTC a0,
  a1, tot, week) and ``GPGA`` (the GST-GPS offset a0g, a1g, t0g, week), weeks continuous GPS-aligned.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .gal_inav import GST_WEEK_OFFSET, GalEphemeris, Ggto, GstUtc, NequickG
from .rinex_text import _d12, _d19, _hdr, _header_values, _nav_lines
from .time import WEEK_S, calendar_from_gps_time, gps_time_from_calendar

#: I/NAV E1-B data with the (E1, E5b) clock: RINEX 3 Galileo "data sources" bits 0 and 9
GAL_INAV_E1B_SOURCE = (1 << 0) | (1 << 9)
_INAV_BITS = (1 << 0) | (1 << 2)         # I/NAV E1-B or E5b-I (bit 1 alone is F/NAV: the E5a clock)


def sisa_m_from_index(idx: int) -> float:
    """Galileo SISA (m) of a SISA index (OS SIS ICD issue 1.2 and later, table "SISA index values": 0-49
    1 cm steps from 0, 50-74 2 cm from 0.5 m, 75-99 4 cm from 1 m, 100-125 16 cm from 2 m); -1.0 for
    255 (NAPA, no accuracy prediction available) and the spare indices 126-254."""
    idx = int(idx)
    if 0 <= idx <= 49:
        return idx * 0.01
    if 50 <= idx <= 74:
        return 0.5 + (idx - 50) * 0.02
    if 75 <= idx <= 99:
        return 1.0 + (idx - 75) * 0.04
    if 100 <= idx <= 125:
        return 2.0 + (idx - 100) * 0.16
    return -1.0


def sisa_index_from_m(sisa_m: float) -> int:
    """SISA index of a SISA in metres as RINEX writes it (the nearest index of the ICD table; 255 NAPA
    for a negative, unknown or larger-than-6 m value)."""
    if not np.isfinite(sisa_m) or sisa_m < 0 or sisa_m > 6.0 + 0.08:
        return 255
    return min(range(126), key=lambda k: abs(sisa_m_from_index(k) - sisa_m))


def gal_from_values(prn, epoch, v):
    """Galileo record (RINEX 3.04/3.05: epoch = toc in GST; toe in GST seconds of week; the GAL week is
    continuous and aligned with the GPS week; SISA in metres; health bits 0 E1-B DVS, 1-2 E1-B HS,
    6 E5b DVS, 7-8 E5b HS; BGD E5a/E1 then BGD E5b/E1).  None for an F/NAV record (data sources without
    an I/NAV bit): its clock is the (E1, E5a) one, not the one an E1 single-frequency user applies."""
    source = int(round(v[20]))
    if source and not source & _INAV_BITS:
        return None
    y, mo, d, h, mi, s = epoch
    _, toc = gps_time_from_calendar(y, mo, d, h, mi, s)      # GST calendar -> GST seconds of week
    health = int(round(v[24]))
    iod = int(round(v[3]))
    return GalEphemeris(
        prn=prn, week=int(round(v[21])), toe=v[11], toc=toc, af0=v[0], af1=v[1], af2=v[2], tgd=v[26],
        iode=iod, iodc=iod, sqrt_a=v[10], e=v[8], i0=v[15], omega0=v[13], omega=v[17], m0=v[6],
        delta_n=v[5], idot=v[19], omega_dot=v[18], cuc=v[7], cus=v[9], crc=v[16], crs=v[4], cic=v[12],
        cis=v[14], health=health & 0b111, ura_index=sisa_index_from_m(v[23]), bgd_e1e5a=v[25],
        e5b_hs=(health >> 7) & 0b11, e5b_dvs=(health >> 6) & 1,
        tx_time=v[27] if abs(v[27]) < 0.9e9 else float("nan"))


def gal_record(e) -> list:
    """RINEX 3.04 Galileo navigation record of an I/NAV E1-B ephemeris (layout: :func:`gal_from_values`;
    data sources = :data:`GAL_INAV_E1B_SOURCE`; an unknown transmission time is written 0.9999E+09)."""
    dtoc = e.toc - e.toe
    toc_week = e.week + (1 if dtoc < -WEEK_S / 2 else -1 if dtoc > WEEK_S / 2 else 0)
    t = calendar_from_gps_time(toc_week, e.toc)                   # GST calendar (GST weeks run with GPS's)
    sec = t.second + t.microsecond * 1e-6
    out = [f"E{e.prn:02d} {t.year:04d} {t.month:02d} {t.day:02d} {t.hour:02d} {t.minute:02d} "
           f"{int(round(sec)):02d}" + _d19(e.af0) + _d19(e.af1) + _d19(e.af2) + "\n"]
    tx = e.tx_time if np.isfinite(e.tx_time) else 0.9999e9
    health = (e.health & 0b111) | (int(e.e5b_dvs) & 1) << 6 | (int(e.e5b_hs) & 0b11) << 7
    rows = [(e.iode, e.crs, e.delta_n, e.m0), (e.cuc, e.e, e.cus, e.sqrt_a), (e.toe, e.cic, e.omega0, e.cis),
            (e.i0, e.crc, e.omega, e.omega_dot), (e.idot, GAL_INAV_E1B_SOURCE, e.week, 0.0),
            (sisa_m_from_index(e.ura_index), health, e.bgd_e1e5a, e.tgd), (tx,)]
    for row in rows:
        out.append("    " + "".join(_d19(float(v)) for v in row) + "\n")
    return out


def gal_header_lines(gal) -> list:
    """IONOSPHERIC CORR GAL (NeQuick-G ai0..ai2), TIME SYSTEM CORR GAUT (GST-UTC) and GPGA (GST-GPS,
    the GGTO) lines of ``gal`` = {"nequick": NequickG, "utc": GstUtc, "ggto": Ggto, "gst_week": week of
    reference} (any may be absent; the 8-bit / 6-bit broadcast weeks become continuous GPS-aligned weeks
    next to ``gst_week``)."""
    out = []
    ref = gal.get("gst_week")
    nq, utc, gg = gal.get("nequick"), gal.get("utc"), gal.get("ggto")
    if nq is not None:
        out.append(_hdr("GAL  " + "".join(_d12(v) for v in (nq.ai0, nq.ai1, nq.ai2, 0.0)), "IONOSPHERIC CORR"))
    if utc is not None and ref is not None:
        wk = full_week(utc.wnot, 256, ref) + GST_WEEK_OFFSET
        out.append(_hdr(f"GAUT {utc.a0:17.10E}{utc.a1:16.9E}{int(utc.tot):7d}{wk:5d}", "TIME SYSTEM CORR"))
    if gg is not None and gg.valid and ref is not None:
        wk = full_week(gg.wn0g, 64, ref) + GST_WEEK_OFFSET
        out.append(_hdr(f"GPGA {gg.a0g:17.10E}{gg.a1g:16.9E}{int(gg.t0g):7d}{wk:5d}", "TIME SYSTEM CORR"))
    return out


def full_week(truncated: int, modulus: int, ref_week: int) -> int:
    """The week nearest to ``ref_week`` whose value modulo ``modulus`` is ``truncated``."""
    return ref_week + ((int(truncated) - ref_week + modulus // 2) % modulus) - modulus // 2


def read_gal_header(path) -> dict:
    """The Galileo parameters of a RINEX 3 navigation file's header: {"nequick": NequickG, "utc": GstUtc,
    "ggto": Ggto} for the lines present (IONOSPHERIC CORR GAL, TIME SYSTEM CORR GAUT / GPGA; the
    continuous weeks become the 8-bit / 6-bit broadcast ones).  UserError as :func:`read_rinex_nav`."""
    path = Path(path)
    lines, version = _nav_lines(path, ("E",))
    h, _ = _header_values(path, lines, version, ("E",))
    out = {}
    if "gal" in h:
        out["nequick"] = NequickG(*h["gal"])
    if "gaut" in h:
        a0, a1, tot, wk = h["gaut"]
        dt_ls = (h["leap"] or (0,))[0] or 0
        out["utc"] = GstUtc(a0=a0, a1=a1, dt_ls=int(dt_ls), tot=float(tot), wnot=(wk - GST_WEEK_OFFSET) % 256)
    if "gpga" in h:
        a0, a1, t0, wk = h["gpga"]
        out["ggto"] = Ggto(a0g=a0, a1g=a1, t0g=float(t0), wn0g=(wk - GST_WEEK_OFFSET) % 64)
    return out
