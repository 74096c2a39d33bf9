"""GPS broadcast ephemeris (IS-GPS-200 LNAV) and satellite position/velocity/clock.

All quantities are SI: metres, seconds, radians.  Angles broadcast in semicircles are
stored in radians, converted with the ICD value of pi (``GPS_PI``).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Iterable, Sequence

import numpy as np

from .signals import F_REL, MU_GPS, OMEGA_E
from .time import HALF_WEEK, WEEK_S, wrap_week_seconds

GPS_PI = 3.1415926535898          # value of pi used by IS-GPS-200 for semicircle conversion


@dataclass
class Ephemeris:
    """One LNAV ephemeris + clock set of one satellite.

    ``week`` is the full (continuous) GPS week of ``toe``; ``toe``/``toc`` are seconds of
    that week.  ``tx_time`` (optional, not compared) is the transmission time of the message
    (GPS seconds of week of the start of subframe 1), NaN when unknown.
    """
    prn: int
    week: int
    toe: float
    toc: float
    af0: float
    af1: float
    af2: float
    tgd: float
    iode: int
    iodc: int
    sqrt_a: float
    e: float
    i0: float
    omega0: float
    omega: float
    m0: float
    delta_n: float
    idot: float
    omega_dot: float
    cuc: float
    cus: float
    crc: float
    crs: float
    cic: float
    cis: float
    health: int = 0
    ura_index: int = 0
    fit_interval: int = 0
    code_on_l2: int = 1
    l2p_flag: int = 0
    aodo: int = 0
    tx_time: float = field(default=float("nan"), compare=False)


@dataclass
class IonoUtc:
    """Klobuchar ionosphere coefficients and GPS-UTC parameters (subframe 4 page 18).

    alpha: s, s/semicircle, s/semicircle^2, s/semicircle^3; beta: s, s/semicircle, ...
    a0 (s), a1 (s/s), tot (s of week), wnt (full week when known), dt_ls (s),
    wn_lsf (week), dn (day number 1..7), dt_lsf (s).  None = not known.
    """
    alpha: tuple = (0.0, 0.0, 0.0, 0.0)
    beta: tuple = (0.0, 0.0, 0.0, 0.0)
    a0: float = 0.0
    a1: float = 0.0
    tot: float = 0.0
    wnt: int = 0
    dt_ls: int = 0
    wn_lsf: int | None = None
    dn: int | None = None
    dt_lsf: int | None = None
    ref_hz: float = 1575.42e6   # the carrier whose delay the model gives: GPS L1; a BeiDou D1/D2 set B1I


_FLOAT_FIELDS = ("toe", "toc", "af0", "af1", "af2", "tgd", "sqrt_a", "e", "i0", "omega0", "omega",
                 "m0", "delta_n", "idot", "omega_dot", "cuc", "cus", "crc", "crs", "cic", "cis")


def _params(eph):
    """Ephemeris or sequence of Ephemeris -> dict of float arrays (shape () or (n,))."""
    if isinstance(eph, Ephemeris):
        return {k: np.float64(getattr(eph, k)) for k in _FLOAT_FIELDS}
    ephs = list(eph)
    return {k: np.array([getattr(x, k) for x in ephs], dtype=float) for k in _FLOAT_FIELDS}


def _clock(p, t):
    """Polynomial clock offset/drift at GPS time t (s of week), without relativity/TGD."""
    dt = wrap_week_seconds(t - p["toc"])
    bias = p["af0"] + p["af1"] * dt + p["af2"] * dt * dt
    drift = p["af1"] + 2.0 * p["af2"] * dt
    return bias, drift


def _orbit(p, t, mu=MU_GPS):
    """Keplerian orbit at GPS time t (s of week). Returns pos, vel (ECEF at t), E, Edot.  ``mu``: the
    gravitational constant of the system's ICD (GPS by default; Galileo's differs)."""
    a = p["sqrt_a"] ** 2
    e = p["e"]
    n0 = np.sqrt(mu / a ** 3)
    n = n0 + p["delta_n"]
    tk = wrap_week_seconds(t - p["toe"])
    mk = p["m0"] + n * tk
    # Kepler's equation M = E - e sin E, Newton iterations until converged
    ek = np.array(mk, dtype=float, copy=True)
    for _ in range(30):
        f = ek - e * np.sin(ek) - mk
        step = f / (1.0 - e * np.cos(ek))
        ek = ek - step
        if np.all(np.abs(step) < 1e-15):
            break
    sin_e, cos_e = np.sin(ek), np.cos(ek)
    one_m_ecos = 1.0 - e * cos_e
    nu = np.arctan2(np.sqrt(1.0 - e * e) * sin_e, cos_e - e)
    phi = nu + p["omega"]
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    du = p["cus"] * s2 + p["cuc"] * c2
    dr = p["crs"] * s2 + p["crc"] * c2
    di = p["cis"] * s2 + p["cic"] * c2
    u = phi + du
    r = a * one_m_ecos + dr
    inc = p["i0"] + p["idot"] * tk + di
    big_omega = p["omega0"] + (p["omega_dot"] - OMEGA_E) * tk - OMEGA_E * p["toe"]

    # time derivatives
    e_dot = n / one_m_ecos
    phi_dot = np.sqrt(1.0 - e * e) * e_dot / one_m_ecos
    u_dot = phi_dot * (1.0 + 2.0 * (p["cus"] * c2 - p["cuc"] * s2))
    r_dot = a * e * sin_e * e_dot + 2.0 * phi_dot * (p["crs"] * c2 - p["crc"] * s2)
    i_dot = p["idot"] + 2.0 * phi_dot * (p["cis"] * c2 - p["cic"] * s2)
    om_dot = p["omega_dot"] - OMEGA_E

    cu, su = np.cos(u), np.sin(u)
    xp, yp = r * cu, r * su
    xp_dot = r_dot * cu - r * u_dot * su
    yp_dot = r_dot * su + r * u_dot * cu
    co, so = np.cos(big_omega), np.sin(big_omega)
    ci, si = np.cos(inc), np.sin(inc)
    x = xp * co - yp * ci * so
    y = xp * so + yp * ci * co
    z = yp * si
    vx = xp_dot * co - yp_dot * ci * so + yp * si * so * i_dot - y * om_dot
    vy = xp_dot * so + yp_dot * ci * co - yp * si * co * i_dot + x * om_dot
    vz = yp_dot * si + yp * ci * i_dot
    pos = np.stack([x, y, z], axis=-1)
    vel = np.stack([vx, vy, vz], axis=-1)
    return pos, vel, ek, e_dot


def sat_state(eph, t_tx):
    """Satellite position, velocity and clock at transmission time.

    eph: an Ephemeris, or a sequence of n Ephemeris (then t_tx broadcasts against (n,)).
    t_tx: GPS seconds of week of transmission *as read by the satellite clock* (scalar or array).

    Returns (pos [...,3] m, vel [...,3] m/s, clk_bias s, clk_drift s/s), the position and
    velocity in the ECEF frame at the (true) time of transmission t = t_tx - clk_bias.
    clk_bias = af0 + af1 dt + af2 dt^2 + F e sqrt(A) sin(E) - TGD (L1 C/A user), so the true
    transmit time is t_tx - clk_bias.  No Earth-rotation correction is applied here.
    """
    bds = _bds_split(eph)
    if bds is not None:                   # BeiDou ephemerides: their class's state (bds_ephemeris.py)
        return _mixed_state(eph, t_tx, bds)
    return kepler_state(_params(eph), t_tx, MU_GPS, F_REL)


def kepler_state(p, t_tx, mu, f_rel):
    """:func:`sat_state` of the parameters ``p`` (:func:`_params`) with the gravitational constant ``mu`` and
    relativistic constant ``f_rel`` of a system whose orbit and clock model are GPS's (Galileo: its own mu
    and F, the same Earth rotation rate)."""
    t_sv = np.asarray(t_tx, dtype=float)
    t = t_sv
    rel = 0.0
    for _ in range(3):
        bias_poly, _ = _clock(p, t)
        t = t_sv - (bias_poly - p["tgd"] + rel)
        pos, vel, ek, e_dot = _orbit(p, t, mu)
        rel = f_rel * p["e"] * p["sqrt_a"] * np.sin(ek)
    bias_poly, drift_poly = _clock(p, t)
    pos, vel, ek, e_dot = _orbit(p, t, mu)
    rel = f_rel * p["e"] * p["sqrt_a"] * np.sin(ek)
    rel_dot = f_rel * p["e"] * p["sqrt_a"] * np.cos(ek) * e_dot
    clk_bias = bias_poly + rel - p["tgd"]
    clk_drift = drift_poly + rel_dot
    return pos, vel, clk_bias, clk_drift


def _bds_split(eph):
    """None when every ephemeris is a GPS/QZSS one, else the boolean mask of those of another system (True
    for a single one).  Such ephemeris classes (receiver.gnss.bds_ephemeris.BdsEphemeris) bring their own
    ``state(ephs, t_tx)`` with sat_state's signature."""
    if isinstance(eph, Ephemeris):
        return True if hasattr(type(eph), "state") else None
    mask = np.array([hasattr(type(x), "state") for x in eph], bool)
    return mask if mask.any() else None


def _mixed_state(eph, t_tx, mask):
    """sat_state of ephemerides of which ``mask`` marks those with a ``state`` of their own: each class's
    satellites through its own function (BeiDou, Galileo), the rest through the GPS one."""
    if mask is True:
        return type(eph).state(eph, t_tx)
    ephs = list(eph)
    fns = [type(x).state if m else sat_state for x, m in zip(ephs, mask.tolist())]
    groups = list(dict.fromkeys(fns))
    if len(groups) == 1:
        return groups[0](ephs, t_tx)
    t = np.broadcast_to(np.asarray(t_tx, float), (len(ephs),))
    pos, vel = np.empty((len(ephs), 3)), np.empty((len(ephs), 3))
    bias, drift = np.empty(len(ephs)), np.empty(len(ephs))
    for fn in groups:
        idx = np.array([i for i, f in enumerate(fns) if f is fn], int)
        r = fn([ephs[i] for i in idx], t[idx])
        pos[idx], vel[idx], bias[idx], drift[idx] = r
    return pos, vel, bias, drift


def earth_rotation(pos, travel_time_s):
    """Rotate ECEF positions at transmission into the ECEF frame at reception (Sagnac).

    pos (...,3) m, travel_time_s (...) s.  The frame rotates by OMEGA_E * tau about z.
    """
    pos = np.asarray(pos, dtype=float)
    theta = OMEGA_E * np.asarray(travel_time_s, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    x, y, z = pos[..., 0], pos[..., 1], pos[..., 2]
    return np.stack(np.broadcast_arrays(c * x + s * y, -s * x + c * y, z), axis=-1)


def select(ephs: Iterable[Ephemeris] | None, t: float, week: int | None = None,
           max_age_s: float = 4 * 3600.0):
    """The healthy ephemeris whose toe is nearest to time t (within max_age_s), or None.

    t: GPS seconds of week.  When ``week`` (full GPS week of t) is given the comparison uses
    absolute GPS time (week*604800 + s); otherwise the time difference is wrapped to +/-half
    a week.
    """
    if not ephs:
        return None
    best, best_dt = None, None
    for eph in ephs:
        if eph.health != 0:
            continue
        if week is not None:
            dt = abs((week - eph.week) * WEEK_S + (t - eph.toe))
        else:       # wrap_week_seconds of a scalar with Python floats (the same floor modulo; ~10x cheaper)
            dt = abs((float(t - eph.toe) + HALF_WEEK) % WEEK_S - HALF_WEEK)
        if dt <= max_age_s and (best_dt is None or dt < best_dt):
            best, best_dt = eph, dt
    return best


def ephemeris_fields() -> Sequence[str]:
    """Names of the compared Ephemeris fields (for tests / writers)."""
    return [f.name for f in fields(Ephemeris) if f.compare]
