"""LEO constellation: TLE reading/writing and SGP4 propagation to Earth-fixed coordinates.

Frames and time
---------------
* SGP4 (``sgp4`` package, Vallado's implementation) returns positions/velocities in the TEME frame
  (True Equator, Mean Equinox of date) in km and km/s.
* TEME is turned into an Earth-fixed frame by one rotation about z by the Greenwich Mean Sidereal Time
  (IAU-1982 expression, the one SGP4 itself uses), evaluated at UT1 = UTC + dut1 (``dut1_s``, default 0):

      r_ecef = R3(gmst) r_teme,         v_ecef = R3(gmst) v_teme - omega_e x r_ecef

  The result is the pseudo-Earth-fixed frame (PEF).  Polar motion (< 15 m at the surface, < 20 m at
  LEO altitude) is ignored, so PEF is used as ECEF/WGS-84.  With the default dut1 = 0 the rotation angle
  is off by at most 0.9 s of Earth rotation (~0.45 km along-track at LEO radius): immaterial here because
  the simulator and the solvers use the same propagation, but pass the IERS dut1 when positioning with
  real measurements.
* Times are UTC ``numpy.datetime64`` values; leap seconds inside a propagation span are not handled.
* No light-time correction is applied: the satellite state is taken at the reception time (the
  simulator and the solvers share this model; the error it causes in real data is ~ a few Hz).
"""
from __future__ import annotations

import datetime as _dt
import math
import os
from dataclasses import dataclass

import numpy as np
from sgp4.api import SatrecArray, Satrec, WGS72

from ..errors import UserError
from ..gnss.signals import OMEGA_E

MU_WGS72_KM3_S2 = 398600.8          # gravitational parameter used by SGP4 (WGS-72)
R_EARTH_WGS72_KM = 6378.135


# --------------------------------------------------------------------------------------------------
# Time helpers
# --------------------------------------------------------------------------------------------------
def to_datetime64(t) -> np.ndarray:
    """UTC times (ISO strings, datetime, datetime64, or arrays of them) to datetime64[us] array."""
    try:
        arr = np.asarray(t)
        if arr.dtype.kind in "OUS":
            flat = [(_parse_one(v)) for v in arr.ravel()]
            return np.array(flat, dtype="datetime64[us]").reshape(arr.shape)
        return arr.astype("datetime64[us]")
    except (ValueError, TypeError) as exc:
        raise UserError(f"cannot read time {t!r}: {exc}") from None


def _parse_one(v):
    if isinstance(v, _dt.datetime):
        if v.tzinfo is not None:
            v = v.astimezone(_dt.timezone.utc).replace(tzinfo=None)
        return np.datetime64(v, "us")
    if isinstance(v, bytes):
        v = v.decode()
    if isinstance(v, str):
        s = v.strip().replace(" ", "T")
        if s.endswith("Z"):
            s = s[:-1]
        return np.datetime64(s, "us")
    return np.datetime64(v, "us")


def julian_date(t) -> tuple[np.ndarray, np.ndarray]:
    """UTC datetime64 array to a (whole, fraction) Julian date pair (whole part ends in .5)."""
    t = to_datetime64(t)
    us = (t - np.datetime64("1970-01-01T00:00:00", "us")).astype(np.int64)
    day = np.floor_divide(us, 86_400_000_000)
    frac = (us - day * 86_400_000_000) / 86_400e6
    return 2440587.5 + day.astype(float), frac


def gmst_rad(jd_whole, jd_frac, dut1_s: float = 0.0) -> np.ndarray:
    """Greenwich mean sidereal time (IAU 1982), radians in [0, 2 pi), at UT1 = UTC + dut1."""
    jd_whole = np.asarray(jd_whole, float)
    frac = np.asarray(jd_frac, float) + dut1_s / 86400.0
    days = jd_whole - 2451545.0                      # half-integer, exact
    t = (days + frac) / 36525.0                      # Julian centuries of UT1 since J2000
    # 876600 h * 3600 s/h * T  ==  86400 s * days: keep only its fractional day to avoid round-off
    sec = (67310.54841 + 86400.0 * (np.mod(days, 1.0) + frac)
           + 8640184.812866 * t + 0.093104 * t * t - 6.2e-6 * t ** 3)
    return np.mod(sec, 86400.0) * (2.0 * math.pi / 86400.0)


def teme_to_ecef(r_teme, v_teme, jd_whole, jd_frac, dut1_s: float = 0.0):
    """Rotate TEME position/velocity (..., 3) to the Earth-fixed (PEF) frame.

    Any consistent length unit; times broadcast against the leading axes of r_teme.
    """
    theta = gmst_rad(jd_whole, jd_frac, dut1_s)
    c, s = np.cos(theta), np.sin(theta)
    r = np.asarray(r_teme, float)
    v = np.asarray(v_teme, float)
    rx = c * r[..., 0] + s * r[..., 1]
    ry = -s * r[..., 0] + c * r[..., 1]
    vx = c * v[..., 0] + s * v[..., 1] + OMEGA_E * ry
    vy = -s * v[..., 0] + c * v[..., 1] - OMEGA_E * rx
    return (np.stack([rx, ry, r[..., 2]], axis=-1), np.stack([vx, vy, v[..., 2]], axis=-1))


# --------------------------------------------------------------------------------------------------
# TLE text
# --------------------------------------------------------------------------------------------------
def tle_checksum(line: str) -> int:
    """Modulo-10 checksum of the first 68 columns (digits count their value, '-' counts 1)."""
    total = 0
    for ch in line[:68]:
        if ch.isdigit():
            total += int(ch)
        elif ch == "-":
            total += 1
    return total % 10


def _exp_field(value: float) -> str:
    """TLE 'assumed decimal point' exponent field, 8 columns: ' 12345-4' == 0.12345e-4."""
    if value == 0.0:
        return " 00000-0"
    sign = "-" if value < 0 else " "
    mant, exp = abs(value), 0
    while mant >= 1.0:
        mant /= 10.0
        exp += 1
    while mant < 0.1:
        mant *= 10.0
        exp -= 1
    digits = int(round(mant * 1e5))
    if digits >= 100000:
        digits //= 10
        exp += 1
    if not -9 <= exp <= 9:
        raise ValueError(f"value {value} out of TLE exponent range")
    return f"{sign}{digits:05d}{'-' if exp < 0 else '+'}{abs(exp)}"


@dataclass
class TLE:
    """Mean elements of one satellite, in TLE units (degrees, revolutions/day)."""
    name: str
    satnum: int
    epoch: np.datetime64            # UTC
    inclination_deg: float
    raan_deg: float
    eccentricity: float
    argp_deg: float
    mean_anomaly_deg: float
    mean_motion_rev_day: float
    bstar: float = 0.0
    ndot_2: float = 0.0             # first derivative of mean motion / 2, rev/day^2
    nddot_6: float = 0.0            # second derivative / 6, rev/day^3
    intl_designator: str = ""
    element_number: int = 999
    rev_number: int = 0

    def lines(self) -> tuple[str, str]:
        """The two 69-column TLE lines with valid checksums."""
        ep = to_datetime64(self.epoch)
        year = int(str(ep.astype("datetime64[Y]")))
        start = np.datetime64(f"{year:04d}-01-01T00:00:00", "us")
        doy = 1.0 + (ep - start).astype(np.int64) / 86400e6
        if not 0 <= self.satnum <= 99999:
            raise ValueError("satellite number must fit 5 digits")
        ndot = f"{self.ndot_2:.8f}".replace("0.", ".", 1) if self.ndot_2 >= 0 else \
            "-" + f"{-self.ndot_2:.8f}".replace("0.", ".", 1)
        l1 = (f"1 {self.satnum:05d}U {self.intl_designator:<8.8s} {year % 100:02d}{doy:012.8f} "
              f"{ndot:>10s} {_exp_field(self.nddot_6)} {_exp_field(self.bstar)} 0 "
              f"{self.element_number % 10000:4d}")
        ecc = f"{self.eccentricity:.7f}"[2:]
        l2 = (f"2 {self.satnum:05d} {self.inclination_deg % 360:8.4f} {self.raan_deg % 360:8.4f} "
              f"{ecc} {self.argp_deg % 360:8.4f} {self.mean_anomaly_deg % 360:8.4f} "
              f"{self.mean_motion_rev_day:11.8f}{self.rev_number % 100000:5d}")
        assert len(l1) == 68 and len(l2) == 68, (l1, l2)
        return l1 + str(tle_checksum(l1)), l2 + str(tle_checksum(l2))


def format_tle_file(tles) -> str:
    """Three-line (name + 2 lines) TLE text."""
    out = []
    for t in tles:
        l1, l2 = t.lines()
        out += [t.name[:24], l1, l2]
    return "\n".join(out) + "\n"


def mean_motion_from_altitude(alt_km: float) -> float:
    """Circular-orbit mean motion (rev/day) at the given altitude above the WGS-72 equatorial radius."""
    a = R_EARTH_WGS72_KM + alt_km
    return math.sqrt(MU_WGS72_KM3_S2 / a ** 3) * 86400.0 / (2.0 * math.pi)


def walker_star_tles(epoch, n_planes=6, per_plane=11, inclination_deg=86.4, altitude_km=780.0,
                     raan0_deg=0.0, raan_spacing_deg=31.6, phase_offset_deg=None,
                     eccentricity=2e-4, argp_deg=90.0, bstar=2.0e-5, first_satnum=90001,
                     name_prefix="IRIDIUM-SYN") -> list[TLE]:
    """Iridium-like Walker-star constellation (near-polar planes spread over ~180 deg of RAAN).

    Neighbouring planes are phased by half the in-plane spacing (default), as in Iridium.
    """
    n = mean_motion_from_altitude(altitude_km)
    spacing = 360.0 / per_plane
    if phase_offset_deg is None:
        phase_offset_deg = spacing / 2.0
    ep = to_datetime64(epoch)
    year = int(str(ep.astype("datetime64[Y]")))
    out = []
    for p in range(n_planes):
        for s in range(per_plane):
            k = p * per_plane + s
            # argument of latitude u = argp + M; choose M so that u is evenly spread
            u = (s * spacing + p * phase_offset_deg) % 360.0
            out.append(TLE(
                name=f"{name_prefix} P{p + 1}S{s + 1:02d}", satnum=first_satnum + k, epoch=ep,
                inclination_deg=inclination_deg, raan_deg=(raan0_deg + p * raan_spacing_deg) % 360.0,
                eccentricity=eccentricity, argp_deg=argp_deg,
                mean_anomaly_deg=(u - argp_deg) % 360.0, mean_motion_rev_day=n, bstar=bstar,
                intl_designator=f"{year % 100:02d}{900 + p:03d}{chr(ord('A') + s)}",
                element_number=1, rev_number=1))
    return out


# --------------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------------
def _check_line(path, lineno, line, number):
    if len(line) < 69 or line[0] != str(number) or line[1] != " ":
        raise UserError(f"{path}:{lineno}: not a TLE line {number} (need 69 columns starting "
                        f"'{number} ')")
    if not line[68].isdigit() or int(line[68]) != tle_checksum(line):
        raise UserError(f"{path}:{lineno}: TLE checksum mismatch (column 69 is {line[68]!r}, "
                        f"computed {tle_checksum(line)})")


def parse_tle_text(text: str, source: str = "<text>") -> list[tuple[str, str, str]]:
    """Parse 2-line or 3-line TLE text into (name, line1, line2) triples, validating checksums."""
    lines = [(i + 1, ln.rstrip("\r\n").rstrip()) for i, ln in enumerate(text.splitlines())]
    lines = [(i, ln) for i, ln in lines if ln.strip()]
    out, k = [], 0
    while k < len(lines):
        name = None
        i, ln = lines[k]
        if not ln.startswith("1 "):
            name = ln[2:].strip() if ln.startswith("0 ") else ln.strip()
            k += 1
            if k >= len(lines):
                raise UserError(f"{source}:{i}: name line without TLE lines")
        if k + 1 >= len(lines):
            raise UserError(f"{source}:{lines[k][0]}: incomplete TLE (line 2 missing)")
        (i1, l1), (i2, l2) = lines[k], lines[k + 1]
        _check_line(source, i1, l1, 1)
        _check_line(source, i2, l2, 2)
        if l1[2:7] != l2[2:7]:
            raise UserError(f"{source}:{i2}: satellite number differs between TLE lines 1 and 2")
        out.append((name or f"SAT {l1[2:7].strip()}", l1[:69], l2[:69]))
        k += 2
    if not out:
        raise UserError(f"{source}: no TLEs found")
    return out


def read_tle_file(path) -> list[tuple[str, str, str]]:
    """(name, line1, line2) of every satellite in a TLE file (checksums validated); a missing or non-ASCII file is
    a one-line UserError."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise UserError(f"TLE file not found: {path}")
    try:
        with open(path, encoding="ascii", errors="strict") as fh:
            text = fh.read()
    except UnicodeDecodeError:
        raise UserError(f"TLE file {path} is not ASCII text") from None
    return parse_tle_text(text, path)


def default_tle_path() -> str:
    """The synthetic Iridium-like TLE set shipped with the package (data/, package data)."""
    from ..config import shipped_dir
    return os.path.join(shipped_dir(), "data", "iridium_synthetic.tle")


# --------------------------------------------------------------------------------------------------
# Propagation
# --------------------------------------------------------------------------------------------------
class Constellation:
    """A set of satellites propagated with SGP4 (WGS-72 constants, as the TLE theory requires)."""

    def __init__(self, entries):
        self.names = []
        self.satrecs = []
        for name, l1, l2 in entries:
            try:
                sat = Satrec.twoline2rv(l1, l2, WGS72)
            except Exception as exc:      # the C extension raises assorted types on bad numbers
                raise UserError(f"TLE for {name!r} cannot be read: {exc}") from None
            if sat.error:
                raise UserError(f"TLE for {name!r} rejected by SGP4 (error code {sat.error})")
            self.names.append(name)
            self.satrecs.append(sat)
        self._array = SatrecArray(self.satrecs)

    @classmethod
    def from_file(cls, path=None) -> "Constellation":
        """The constellation of a TLE file (default: the synthetic Iridium-like set shipped with the package)."""
        return cls(read_tle_file(path or default_tle_path()))

    def __len__(self):
        return len(self.satrecs)

    @property
    def satnums(self) -> np.ndarray:
        """NORAD catalogue numbers of the satellites, in order."""
        return np.array([s.satnum for s in self.satrecs])

    def propagate_teme(self, times):
        """TEME position (m), velocity (m/s), error flags; arrays shaped (T, N, 3) / (T, N)."""
        jd, fr = julian_date(np.atleast_1d(times))
        err, r, v = self._array.sgp4(jd, fr)
        return (np.transpose(r, (1, 0, 2)) * 1e3, np.transpose(v, (1, 0, 2)) * 1e3, err.T != 0)

    def propagate_ecef(self, times, dut1_s: float = 0.0):
        """Earth-fixed position (m), velocity (m/s) and SGP4 error flags for all satellites.

        Shapes (T, N, 3), (T, N, 3), (T, N); satellites whose SGP4 run failed have NaN states.
        """
        times = np.atleast_1d(to_datetime64(times))
        jd, fr = julian_date(times)
        r, v, bad = self.propagate_teme(times)
        r, v = teme_to_ecef(r, v, jd[:, None], fr[:, None], dut1_s)
        r[bad] = np.nan
        v[bad] = np.nan
        return r, v, bad
