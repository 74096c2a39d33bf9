"""NMEA 0183 sentences (GGA, RMC, GSA, GSV) for every fix of a run.

* Talker: GP for a GPS-only fix, GB for BeiDou only, GA for Galileo only, GN when the fix mixes systems
  (GPS + QZSS on L1 C/A, GPS + Galileo + BeiDou); GSV sentences carry the satellites' own system's talker
  (GP for GPS and QZSS, whose PRNs 193..202 are their NMEA IDs; GB for BeiDou, IDs = PRN 1..63; GA for
  Galileo, IDs = PRN 1..36 as NMEA 4.10 numbers them); a mixed fix has one GSA per system with the NMEA
  4.10 system ID (1 GPS, 3 Galileo, 4 BeiDou) appended.

* Times are UTC (GPS time of the fix minus the leap seconds broadcast in the LNAV message, or the built-in
  table), to 0.01 s.
* GGA: there is no geoid model in gnssrx, so the geoid separation is written as 0.0 and the altitude field
  holds the ellipsoidal (WGS-84) height: altitude + separation is the ellipsoidal height as the standard
  defines it.  Fix quality 1 (GPS SPS); the age/station fields are empty.
* RMC: speed over ground (knots) and course (degrees true) from the Doppler velocity; mode indicator A.
* GSA: automatic mode, 3D fix, the PRNs used in the fix (up to 12), PDOP/HDOP/VDOP.
* GSV: the tracked satellites of that epoch with elevation, azimuth (integer degrees) and C/N0 (dB-Hz).
"""
from __future__ import annotations

import math

import numpy as np

from ..gnss.geodesy import enu_matrix
from ..gnss.satid import sat_label, sat_system
from ..runfile.reader import RunData

KNOTS_PER_MPS = 3600.0 / 1852.0
_TALKER = {"G": "GP", "C": "GB", "J": "GQ", "E": "GA"}
_NMEA_SYS = {"G": "G", "J": "G", "C": "C", "E": "E"}     # QZSS satellites are reported with GPS (IDs 193..)
_NMEA_SYS_ID = {"G": 1, "E": 3, "C": 4}                  # NMEA 4.10 GNSS system ID of GSA


def _nmea_id(prn: int, system: str = "G") -> int:
    """NMEA satellite ID of a run's satellite ``prn`` (key of a run over several signals): the PRN of its own
    system (GPS 1..32, QZSS 193..202, BeiDou 1..63, Galileo 1..36)."""
    return int(sat_label(prn, system)[1:]) if sat_system(prn, system) in ("C", "E") else prn


def checksum(body: str) -> str:
    """Two-digit hex XOR of the characters between '$' and '*'."""
    c = 0
    for ch in body.encode("ascii"):
        c ^= ch
    return f"{c:02X}"


def sentence(body: str) -> str:
    """``$body*hh``: the sentence with its checksum (no line end)."""
    return f"${body}*{checksum(body)}"


def _latlon(value: float, is_lat: bool):
    hemi = ("N" if value >= 0 else "S") if is_lat else ("E" if value >= 0 else "W")
    minutes = round(abs(value) * 60.0, 7)
    deg = int(minutes // 60)
    minutes -= deg * 60
    width = 2 if is_lat else 3
    return f"{deg:0{width}d}{minutes:010.7f}", hemi


def _num(v, fmt: str) -> str:
    return format(v, fmt) if v is not None and np.isfinite(v) else ""


def _hms(t) -> str:
    return f"{t.hour:02d}{t.minute:02d}{t.second:02d}.{t.microsecond // 10000:02d}"


def _utc(run: RunData, week: int, tow: float):
    cs = round(tow * 100.0)                    # round to 0.01 s before converting
    return run.utc(week, cs / 100.0)


def gga(t, lat, lon, h, n_sats, hdop, talker="GP") -> str:
    """GGA sentence: UTC time t (datetime), lat/lon (deg), ellipsoidal height h (m, geoid separation 0),
    satellites used, HDOP."""
    la, ns = _latlon(lat, True)
    lo, ew = _latlon(lon, False)
    return sentence(f"{talker}GGA,{_hms(t)},{la},{ns},{lo},{ew},1,{min(int(n_sats), 99):02d},{_num(hdop, '.2f')},"
                    f"{_num(h, '.3f')},M,0.0,M,,")


def rmc(t, lat, lon, speed_mps, course_deg, talker="GP") -> str:
    """RMC sentence: UTC time t (datetime), lat/lon (deg), speed over ground (m/s, written in knots) and course
    (deg true); None leaves the field empty."""
    la, ns = _latlon(lat, True)
    lo, ew = _latlon(lon, False)
    spd = _num(speed_mps * KNOTS_PER_MPS if speed_mps is not None else None, ".3f")
    crs = _num(course_deg, ".2f")
    date = f"{t.day:02d}{t.month:02d}{t.year % 100:02d}"
    return sentence(f"{talker}RMC,{_hms(t)},A,{la},{ns},{lo},{ew},{spd},{crs},{date},,,A")


def gsa(prns_used, pdop, hdop, vdop, talker="GP") -> str:
    """GSA sentence (automatic, 3D fix): the first 12 of the sorted satellite IDs used, PDOP/HDOP/VDOP."""
    prns = [f"{int(p):02d}" for p in sorted(prns_used)[:12]]
    prns += [""] * (12 - len(prns))
    return sentence(f"{talker}GSA,A,3,{','.join(prns)},{_num(pdop, '.2f')},{_num(hdop, '.2f')},{_num(vdop, '.2f')}")


def gsv(sats, talker="GP") -> list:
    """sats: list of (prn, elevation_deg, azimuth_deg, cn0_dbhz); one sentence per 4 satellites."""
    n = len(sats)
    total = max(1, math.ceil(n / 4))
    out = []
    for k in range(total):
        parts = [f"{talker}GSV,{total},{k + 1},{n:02d}"]
        for prn, el, az, cn0 in sats[4 * k:4 * k + 4]:
            el_s = f"{int(round(el)):02d}" if np.isfinite(el) else ""
            az_s = f"{int(round(az)) % 360:03d}" if np.isfinite(az) else ""
            sn_s = f"{min(max(int(round(cn0)), 0), 99):02d}" if np.isfinite(cn0) else ""
            parts.append(f"{int(prn):02d},{el_s},{az_s},{sn_s}")
        out.append(sentence(",".join(parts)))
    return out


def nmea_lines(run: RunData) -> list:
    """All sentences of a run without line ends: GGA, RMC, GSA and GSV for every fix with a finite position.
    Fills the observables' missing azimuth/elevation in place (:meth:`RunData.fill_azel`)."""
    fx, obs = run.fixes, run.obs
    run.fill_azel()
    o_time = obs["time_s"] if len(obs) else np.zeros(0)
    o_order = np.argsort(o_time, kind="stable")
    o_sorted = o_time[o_order]
    lines = []
    for i in range(len(fx)):
        f = fx[i]
        if not np.all(np.isfinite(f["ecef"])):
            continue
        t = _utc(run, int(f["gps_week"]), float(f["gps_tow"]))
        lat, lon, h = float(f["lat_deg"]), float(f["lon_deg"]), float(f["height_m"])
        v = np.asarray(f["velocity_ecef"], float)
        if np.all(np.isfinite(v)):
            e, n, _ = enu_matrix(lat, lon) @ v
            speed = float(math.hypot(e, n))
            course = float(math.degrees(math.atan2(e, n)) % 360.0)
        else:
            speed = course = None
        lo, hi = np.searchsorted(o_sorted, [f["time_s"] - 1e-6, f["time_s"] + 1e-6])
        rows = o_order[lo:hi]
        rows = rows[np.argsort(obs["prn"][rows])] if len(rows) else rows
        used = [int(obs["prn"][r]) for r in rows if obs["used_in_fix"][r]]
        letters = {sat_system(p, run.system) for p in used} or {run.system}
        talker = "GN" if len(letters) > 1 else _TALKER.get(next(iter(letters)), "GN")
        lines.append(gga(t, lat, lon, h, f["n_sats"], float(f["hdop"]), talker))
        lines.append(rmc(t, lat, lon, speed, course, talker))
        # GSA: one per system when several (NMEA 4.10, system ID appended); GSV: per system, own talker
        groups = {}
        for p in used:
            groups.setdefault(_NMEA_SYS.get(sat_system(p, run.system), "G"), []).append(_nmea_id(p, run.system))
        for letter, ids in (sorted(groups.items()) if len(groups) > 1
                            else [(None, [_nmea_id(p, run.system) for p in used])]):
            line = gsa(ids, float(f["pdop"]), float(f["hdop"]), float(f["vdop"]), talker)
            if letter is not None:
                line = sentence(line[1:line.index("*")] + f",{_NMEA_SYS_ID[letter]}")
            lines.append(line)
        by_sys = {}
        for r in rows:
            p = int(obs["prn"][r])
            by_sys.setdefault(_NMEA_SYS.get(sat_system(p, run.system), "G"), []).append(
                (_nmea_id(p, run.system), float(obs["elevation_deg"][r]), float(obs["azimuth_deg"][r]),
                 float(obs["cn0_dbhz"][r])))
        for letter in sorted(by_sys):
            lines.extend(gsv(by_sys[letter], _TALKER[letter]))
    return lines


def write_nmea(path, run: RunData) -> dict:
    """Write the run's sentences to `path` (CRLF line ends); returns {"sentences": count, "fixes": GGA count}."""
    lines = nmea_lines(run)
    with open(path, "w", newline="") as fh:
        fh.write("".join(ln + "\r\n" for ln in lines))
    return {"sentences": len(lines), "fixes": sum(1 for ln in lines if ln[3:7] == "GGA,")}
