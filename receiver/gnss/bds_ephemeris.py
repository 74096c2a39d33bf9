"""BeiDou broadcast ephemeris (BDS-SIS-ICD-B1I section 5.2.4) and the satellite state in BDCS.

Constants (ICD): mu = 3.986004418e14 m^3/s^2 (CGCS2000), Omega_e = 7.2921150e-5 rad/s, pi = 3.1415926535898,
F = -2 sqrt(mu) / c^2.  ``toe``/``toc``/``week`` of a :class:`BdsEphemeris` are BDT (BDT = GPST - 14 s,
BDT week = GPS week - 1356); :func:`bds_sat_state` takes the GPS time of transmission like
:func:`receiver.gnss.ephemeris.sat_state` (which hands BeiDou ephemerides to it).

MEO/IGSO: the usual Keplerian algorithm with Omega_k = Omega0 + (Omega_dot - Omega_e) t_k - Omega_e toe.
GEO (PRN 1..5 and 59..63): Omega_k = Omega0 + Omega_dot t_k - Omega_e toe (no Earth rotation over t_k),
the position (X_GK, Y_GK, Z_GK) in that frame is rotated by R_X(-5 deg) and then R_Z(Omega_e t_k):
    [X, Y, Z] = R_Z(Omega_e t_k) R_X(-5 deg) [X_GK, Y_GK, Z_GK],
    R_X(phi) = [[1, 0, 0], [0, cos phi, sin phi], [0, -sin phi, cos phi]],
    R_Z(phi) = [[cos phi, sin phi, 0], [-sin phi, cos phi, 0], [0, 0, 1]].
Clock (B1I user): dt = a0 + a1 (t - toc) + a2 (t - toc)^2 + F e sqrt(A) sin E - TGD1.
Velocities are central differences of the position over +/-5 ms (error well below 1 mm/s).
CGCS2000 and WGS-84 are treated as the same frame (centimetre level).
(A list mixing BeiDou and GPS ephemerides: each gets its own algorithm.)
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .ephemeris import Ephemeris
from .signals import C_LIGHT
from .signals_bds import B1I_GEO_PRNS
from .time import wrap_week_seconds

MU_BDS = 3.986004418e14
OMEGA_E_BDS = 7.2921150e-5
BDS_PI = 3.1415926535898
F_REL_BDS = -2.0 * np.sqrt(MU_BDS) / C_LIGHT ** 2
BDT_GPS_OFFSET_S = 14            # GPST - BDT
BDT_WEEK_OFFSET = 1356           # GPS week of BDT week 0
GEO_PRNS = B1I_GEO_PRNS          # geostationary: the GEO orbit case (ICD 5.2.4.12)
_COS5, _SIN5 = np.cos(np.radians(-5.0)), np.sin(np.radians(-5.0))


@dataclass
class BdsEphemeris(Ephemeris):
    """A BeiDou D1/D2 ephemeris.  Times in BDT (``week`` = BDT week number, ``toe``/``toc`` = BDT seconds
    of week); ``tgd`` = TGD1 (B1I), ``iode`` = AODE, ``iodc`` = AODC, ``health`` = SatH1, ``ura_index`` =
    URAI."""
    tgd2: float = 0.0
    system: str = "C"

    @property
    def geo(self) -> bool:
        """True for a GEO satellite (PRN 1-5, 59-63: the GEO orbit case of ICD 5.2.4.12)."""
        return self.prn in GEO_PRNS

    @staticmethod
    def state(ephs, t_tx):
        """receiver.gnss.ephemeris.sat_state hands BeiDou ephemerides here."""
        return bds_sat_state(ephs, t_tx)


def _position(e, t_bdt, geo):
    """ECEF positions (n, 3) at BDT seconds of week t_bdt (n,), and the eccentric anomaly."""
    a = e["sqrt_a"] ** 2
    n = np.sqrt(MU_BDS / a ** 3) + e["delta_n"]
    tk = wrap_week_seconds(t_bdt - e["toe"])
    mk = e["m0"] + n * tk
    ek = np.array(mk, float, copy=True)
    for _ in range(30):
        step = (ek - e["e"] * np.sin(ek) - mk) / (1.0 - e["e"] * np.cos(ek))
        ek = ek - step
        if np.all(np.abs(step) < 1e-15):
            break
    nu = np.arctan2(np.sqrt(1.0 - e["e"] ** 2) * np.sin(ek), np.cos(ek) - e["e"])
    phi = nu + e["omega"]
    s2, c2 = np.sin(2 * phi), np.cos(2 * phi)
    u = phi + e["cus"] * s2 + e["cuc"] * c2
    r = a * (1.0 - e["e"] * np.cos(ek)) + e["crs"] * s2 + e["crc"] * c2
    inc = e["i0"] + e["idot"] * tk + e["cis"] * s2 + e["cic"] * c2
    xp, yp = r * np.cos(u), r * np.sin(u)
    if geo:
        om = e["omega0"] + e["omega_dot"] * tk - OMEGA_E_BDS * e["toe"]
    else:
        om = e["omega0"] + (e["omega_dot"] - OMEGA_E_BDS) * tk - OMEGA_E_BDS * e["toe"]
    co, so, ci, si = np.cos(om), np.sin(om), np.cos(inc), np.sin(inc)
    x = xp * co - yp * ci * so
    y = xp * so + yp * ci * co
    z = yp * si
    if geo:
        # R_X(-5 deg)
        y, z = _COS5 * y + _SIN5 * z, -_SIN5 * y + _COS5 * z
        # R_Z(Omega_e t_k)
        c, s = np.cos(OMEGA_E_BDS * tk), np.sin(OMEGA_E_BDS * tk)
        x, y = c * x + s * y, -s * x + c * y
    return np.stack([x, y, z], axis=-1), ek


_FIELDS = ("toe", "toc", "af0", "af1", "af2", "tgd", "sqrt_a", "e", "i0", "omega0", "omega", "m0",
           "delta_n", "idot", "omega_dot", "cuc", "cus", "crc", "crs", "cic", "cis")


def bds_sat_state(eph, t_tx):
    """Like receiver.gnss.ephemeris.sat_state for BdsEphemeris (one, or a sequence of n): t_tx is the GPS
    seconds of week of transmission read by the satellite clock.  Returns (pos, vel, clk_bias, clk_drift)."""
    single = isinstance(eph, BdsEphemeris)
    ephs = [eph] if single else list(eph)
    t_sv = np.atleast_1d(np.asarray(t_tx, float)).ravel() - BDT_GPS_OFFSET_S
    if len(ephs) == 1 and t_sv.size > 1:
        ephs = ephs * t_sv.size
    t_sv = np.broadcast_to(t_sv, (len(ephs),)).copy()
    p = {k: np.array([getattr(x, k) for x in ephs], float) for k in _FIELDS}
    geo = np.array([x.geo for x in ephs])

    def pos_at(t):
        out = np.empty((len(ephs), 3))
        ek = np.empty(len(ephs))
        for g in (False, True):
            sel = geo == g
            if sel.any():
                out[sel], ek[sel] = _position({k: v[sel] for k, v in p.items()}, t[sel], g)
        return out, ek

    def clock(t):
        dt = wrap_week_seconds(t - p["toc"])
        return p["af0"] + p["af1"] * dt + p["af2"] * dt * dt, p["af1"] + 2 * p["af2"] * dt

    t = t_sv
    rel = 0.0
    for _ in range(3):
        b, _ = clock(t)
        t = t_sv - (b - p["tgd"] + rel)
        _, ek = pos_at(t)
        rel = F_REL_BDS * p["e"] * p["sqrt_a"] * np.sin(ek)
    b, d = clock(t)
    pos, ek = pos_at(t)
    h = 5e-3
    vel = (pos_at(t + h)[0] - pos_at(t - h)[0]) / (2 * h)
    rel = F_REL_BDS * p["e"] * p["sqrt_a"] * np.sin(ek)
    n = np.sqrt(MU_BDS / p["sqrt_a"] ** 6) + p["delta_n"]
    rel_dot = F_REL_BDS * p["e"] * p["sqrt_a"] * np.cos(ek) * n / (1 - p["e"] * np.cos(ek))
    bias, drift = b + rel - p["tgd"], d + rel_dot
    if single and np.ndim(t_tx) == 0:
        return pos[0], vel[0], float(bias[0]), float(drift[0])
    return pos, vel, bias, drift
