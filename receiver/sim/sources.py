"""Simulator set-up and per-satellite sources: which signals and satellites a scenario holds, their
ephemerides and broadcast ionosphere, and what each satellite transmits (LNAV bits, BeiDou D1/D2 through
receiver.gnss.bds_nav, Galileo E1-B/E1-C symbols) and at what C/N0, with scintillation.

receiver.sim.simulate builds these once per scenario (``_Simulator``) and drives them block by block.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from ..errors import UserError
from ..gnss.ephemeris import IonoUtc
from ..gnss.lnav import encode_subframes
from ..gnss.registry import get_signal
from ..gnss.satid import sat_key
from ..gnss.time import WEEK_S
from ..suggest import check_list_item
from .constellation import load_constellation, quantize_iono
from .scenario import resolve_path
from .scintillation import Scintillation

_FRAME_MS = 30000
_WEEK_FRAMES = int(WEEK_S) // 30


class Overlap:
    """Wrap a stream ``take(n)`` so that consecutive blocks share their boundary grid point."""

    def __init__(self, take):
        self._take = take
        self._last = None

    def get(self, n_steps):
        """The next n_steps + 1 grid points (the first is the previous block's last)."""
        if self._last is None:
            cur = self._take(n_steps + 1)
        else:
            new = self._take(n_steps)
            cur = tuple(np.concatenate(([l], v)) for l, v in zip(self._last, new))
        self._last = tuple(v[-1] for v in cur)
        return cur


class LnavBits:
    """LNAV bits of one satellite, frame by frame, as data signs per code period (ms) of satellite time."""

    def __init__(self, eph, iono, week, page18_every_frame, enabled):
        self.eph, self.iono, self.week = eph, iono, week
        self.page18 = page18_every_frame
        self.enabled = enabled
        self._frames = {}

    def _frame(self, f):
        bits = self._frames.get(f)
        if bits is None:
            wk = self.week + f // _WEEK_FRAMES
            tow = (f % _WEEK_FRAMES) * 30.0
            bits = encode_subframes(self.eph, self.iono, tow, wk, page18_every_frame=self.page18)
            self._frames[f] = bits
            for old in [k for k in self._frames if k < f - 1]:
                del self._frames[old]
        return bits

    def signs(self, ms_abs0, count):
        """+1/-1 (float32) for the code periods starting at satellite-time ms ms_abs0 .. +count-1."""
        if not self.enabled:
            return np.ones(count, np.float32)
        ms = ms_abs0 + np.arange(count, dtype=np.int64)
        frames = ms // _FRAME_MS
        out = np.empty(count, np.float32)
        for f in np.unique(frames):
            sel = frames == f
            bit = (ms[sel] - f * _FRAME_MS) // 20
            out[sel] = 1.0 - 2.0 * self._frame(int(f))[bit].astype(np.float32)
        return out


class GalSymbols:
    """Galileo E1 symbols of one satellite per 4-ms code period of satellite time: the E1-B I/NAV symbols
    (receiver.gnss.gal_inav.InavStream) and the E1-C CS25 chips."""

    def __init__(self, content, gps_week, enabled):
        from ..gnss.gal_codes import cs25_signs
        from ..gnss.gal_inav import GST_WEEK_OFFSET, InavStream
        self.stream = InavStream(content, gps_week - GST_WEEK_OFFSET)     # GGTO zero: GST = GPS time
        self.enabled = enabled
        self.cs25 = cs25_signs()

    def signs(self, period0, count):
        """(E1-B symbols, E1-C secondary chips), +/-1 float32, for code periods period0 .. +count-1 of the
        week (4-ms periods since the start of the GPS week of the scenario)."""
        k = np.int64(period0) + np.arange(count, dtype=np.int64)
        sym = self.stream.signs(period0, count) if self.enabled else np.ones(count, np.float32)
        return sym, self.cs25[k % 25]


class Cn0Model:
    """Nominal C/N0 (dB-Hz) per satellite and grid point."""

    def __init__(self, cfg):
        self.mode = cfg.mode
        self.dbhz, self.horizon = cfg.dbhz, cfg.horizon_dbhz
        try:
            self.per_prn = {int(k): float(v) for k, v in (cfg.per_prn or {}).items()}
        except (TypeError, ValueError):
            raise UserError("config key 'cn0.per_prn' must map PRN numbers to dB-Hz values") from None
        self.schedules = []
        for i, item in enumerate(cfg.schedule or []):
            key = f"cn0.schedule[{i}]"
            check_list_item(item, key, ("t_s", "dbhz"), ("prns", "t_s", "dbhz"), "t_s and dbhz lists")
            try:
                t = np.asarray(item["t_s"], dtype=float).ravel()
                v = np.asarray(item["dbhz"], dtype=float).ravel()
                prns = None if item.get("prns") is None else {int(p) for p in item["prns"]}
            except (TypeError, ValueError):
                raise UserError(f"config key '{key}' must hold numbers") from None
            if t.size == 0 or t.size != v.size or np.any(np.diff(t) < 0):
                raise UserError(f"config key '{key}': t_s and dbhz need the same (non-zero) length, "
                                "t_s increasing")
            self.schedules.append((prns, t, v))
        if self.mode == "schedule" and not self.schedules:
            raise UserError("config key 'cn0.schedule' must not be empty when cn0.mode is 'schedule'")

    def __call__(self, prn, t_rel, el_deg):
        """C/N0 (dB-Hz) of satellite prn at receiver times t_rel (s since the start), elevations el_deg."""
        if prn in self.per_prn:
            return np.full(t_rel.shape, self.per_prn[prn])
        if self.mode == "elevation":
            e = np.clip(el_deg, 0.0, 90.0) / 90.0
            return self.horizon + (self.dbhz - self.horizon) * e
        if self.mode == "schedule":
            for prns, t, v in self.schedules:
                if prns is None or prn in prns:
                    return np.interp(t_rel, t, v)
        return np.full(t_rel.shape, self.dbhz)



# ------------------------------------------------------------------------------------------ set-up
def select_signals(sc):
    """The scenario's signals: (signals (registry entries, the first at frontend.if_hz), multi (several
    signals in one recording), gal (a Galileo E1 recording), bds_src (BeiDou orbits from
    constellation.source)).  An unsupported combination is a UserError."""
    con, atm = sc.constellation, sc.atmosphere
    names = list(sc.signals or []) or [sc.signal]
    multi = len(names) > 1
    if multi and (len(set(names)) < len(names) or "gps_l1ca" not in names or
                  not set(names) <= {"gps_l1ca", "bds_b1i", "gal_e1"} or con.source not in ("embedded", "rinex")):
        raise UserError("config key 'signals': a recording of several signals is gps_l1ca with bds_b1i and/or "
                        "gal_e1 (any order) with constellation.source embedded or rinex (GPS; BeiDou: "
                        "constellation.bds_file; Galileo: constellation.gal_file)")
    if not multi and names[0] not in ("gps_l1ca", "bds_b1i", "gal_e1"):
        raise UserError(f"config key 'signals': unknown signal {names[0]!r}")
    signals = [get_signal(n) for n in names]
    bds_src = con.source in ("bds_nominal", "bds_rinex")
    if bds_src and names[0] != "bds_b1i":
        raise UserError(f"constellation.source '{con.source}' needs signal: bds_b1i")
    gal = names[0] == "gal_e1" and not multi
    # (an E1 + E5a recording may have a Klobuchar ionosphere: the dual-frequency fix needs no broadcast model)
    if gal and (con.source != "embedded" or (atm.ionosphere != "none" and not sc.e5a.enabled)):
        raise UserError("signal gal_e1: the Galileo orbits come from constellation.gal_file (leave "
                        "constellation.source at embedded) and the ionosphere must be none (Galileo "
                        "broadcasts NeQuick-G, not the simulator's Klobuchar model): set atmosphere.ionosphere: "
                        "none (or e5a.enabled with atmosphere.klobuchar_alpha/beta: an E1 + E5a recording)")
    return signals, multi, gal, bds_src


def load_ephemerides(con, week, t_ref, duration, gal, bds_src):
    """The constellation of the scenario: (cons, gal_content).  cons has ``source`` (a name for the truth
    file), ``ephemerides`` ({prn: ephemeris}) and ``iono_utc`` (the broadcast Klobuchar set or None);
    gal_content holds the Galileo I/NAV content per PRN (None for other signals)."""
    gal_content = None
    if gal:                                 # Galileo orbits + I/NAV content (sim/gal_constellation.py)
        from .gal_constellation import gal_nominal_content
        from .gal_constellation import source_name as gal_source_name
        path = resolve_path(con.gal_file, "constellation file")
        gal_content = gal_nominal_content(path, week, t_ref)
        b_ephs, b_iono = {p: c.eph for p, c in gal_content.items()}, None
    elif bds_src:                           # BeiDou orbits + D1/D2 messages (sim/bds_constellation.py)
        from .bds_constellation import bds_nominal_ephemerides, bds_rinex_ephemerides, source_name
        if con.source == "bds_nominal":
            path = resolve_path(con.bds_file, "constellation file")
            b_ephs, b_iono = bds_nominal_ephemerides(path, week, t_ref)
        else:
            if not con.rinex:
                raise UserError("constellation.source is 'bds_rinex' but constellation.rinex is empty")
            path = resolve_path(con.rinex, "RINEX file")
            b_ephs, b_iono = bds_rinex_ephemerides(path, week, t_ref + duration / 2.0)
    else:
        cons = load_constellation(con.source, resolve_path(con.rinex, "RINEX file") if con.rinex else None,
                                  resolve_path(con.nominal_file, "constellation file"), week, t_ref,
                                  t_ref + duration / 2.0,
                                  resolve_path(con.qzss_file, "constellation file") if con.qzss else None)
        return cons, gal_content
    cons = SimpleNamespace(source=gal_source_name(path) if gal else source_name(path, con.source),
                           ephemerides=b_ephs, iono_utc=quantize_iono(b_iono) if b_iono is not None else None)
    return cons, gal_content


def broadcast_iono(atm, iono_b, week, t_ref):
    """The broadcast ionosphere/UTC set with the scenario's Klobuchar overrides (atmosphere.klobuchar_*,
    quantised to their LSBs); a Klobuchar ionosphere without coefficients is a UserError."""
    if atm.klobuchar_alpha is not None or atm.klobuchar_beta is not None:
        base = iono_b or IonoUtc(wnt=week, dt_ls=18, tot=math.floor(t_ref / 4096.0) * 4096.0)
        iono_b = quantize_iono(IonoUtc(**{**base.__dict__,
                                          "alpha": tuple(atm.klobuchar_alpha or base.alpha),
                                          "beta": tuple(atm.klobuchar_beta or base.beta)}))
    if atm.ionosphere == "klobuchar" and iono_b is None:
        raise UserError("atmosphere.ionosphere is 'klobuchar' but the RINEX file has no ION ALPHA/BETA: "
                        "set atmosphere.klobuchar_alpha/beta or atmosphere.ionosphere: none")
    return iono_b


def multi_gal_content(con, signals, multi, week, t_ref):
    """The Galileo I/NAV content per PRN of a recording of several signals with gal_e1 (else None)."""
    if not multi or "gal_e1" not in [g.name for g in signals]:
        return None
    from .gal_constellation import gal_nominal_content
    return gal_nominal_content(resolve_path(con.gal_file, "constellation file"), week, t_ref)


def chosen_ephemerides(con, cons, multi, week, t_ref, signals=(), gal_multi=None) -> dict:
    """{key: ephemeris} of the satellites the scenario asks for (constellation.prns / exclude_prns); a
    recording of several signals adds the nominal BeiDou constellation (with bds_b1i), keyed 400 + PRN, and
    the nominal Galileo one (``gal_multi``: with gal_e1), keyed 300 + PRN."""
    ephs = dict(cons.ephemerides)
    if multi and (not signals or "bds_b1i" in [g.name for g in signals]):
        from .bds_constellation import bds_nominal_ephemerides
        b_multi, _ = bds_nominal_ephemerides(resolve_path(con.bds_file, "constellation file"), week, t_ref)
        ephs.update({sat_key("C", p): e for p, e in b_multi.items()})
    if gal_multi:
        ephs.update({sat_key("E", p): c.eph for p, c in gal_multi.items()})
    if con.prns:
        missing = [p for p in con.prns if p not in ephs]
        if missing:
            raise UserError(f"constellation.prns: no ephemeris for PRN {missing[0]} in {cons.source}")
        ephs = {p: e for p, e in ephs.items() if p in con.prns}
    for p in con.exclude_prns:
        ephs.pop(p, None)
    return ephs


def scintillation_streams(sci, prns, seed, grid_s) -> dict:
    """{prn: Overlap stream of (amplitude, phase)} for the scintillated satellites (scintillation.prns,
    per_prn overrides); empty when scintillation is off."""
    if not sci.enabled:
        return {}
    per = {}
    for k, v in (sci.per_prn or {}).items():
        if not isinstance(v, dict) or set(v) - {"s4", "sigma_phi_rad", "tau0_s"}:
            raise UserError(f"config key 'scintillation.per_prn.{k}' must be a mapping of "
                            "s4, sigma_phi_rad, tau0_s")
        per[int(k)] = v
    out = {}
    for prn in prns:
        if sci.prns and prn not in sci.prns and prn not in per:
            continue
        o = per.get(prn, {})
        try:
            s4, sp, t0 = (float(o.get("s4", sci.s4)), float(o.get("sigma_phi_rad", sci.sigma_phi_rad)),
                          float(o.get("tau0_s", sci.tau0_s)))
        except (TypeError, ValueError):
            s4 = -1.0
        if not (0.0 <= s4 < 1.0 and sp >= 0.0 and t0 > 0.0):
            raise UserError(f"config key 'scintillation.per_prn.{prn}': need 0 <= s4 < 1, "
                            "sigma_phi_rad >= 0, tau0_s > 0")
        rng = np.random.default_rng(np.random.SeedSequence([seed, 3, prn]))
        out[prn] = Overlap(Scintillation(s4, sp, t0, grid_s, rng, sci.window_s).take)
    return out


def nav_sources(sc, prns, sat_sig, ephs, gal_content, iono_b, week, gal, bds_src, multi, gal_multi=None) -> dict:
    """{key: navigation-data source} per satellite: ``signs(period0, count)`` gives its data symbols
    (Galileo: E1-B symbols and E1-C secondary chips) per code period of satellite time; ``gal_multi``: the
    Galileo content of a recording of several signals (:func:`multi_gal_content`)."""
    nav = {}
    for p in prns:
        sig, q, _ = sat_sig[p]
        if gal:
            nav[p] = GalSymbols(gal_content[p], week, sc.navigation.data)
        elif sig.system == "E":                 # a Galileo satellite of a recording of several signals
            nav[p] = GalSymbols(gal_multi[q], week, sc.navigation.data)
        elif bds_src or (multi and sig.system == "C"):
            from ..gnss.bds_nav import BdsNavBits
            from ..gnss.signals_bds import is_geo
            nav[p] = BdsNavBits(ephs[p], iono_b, week, is_geo(q), sc.navigation.data)
        else:
            nav[p] = LnavBits(ephs[p], iono_b, week, sc.navigation.page18_every_frame, sc.navigation.data)
    return nav
