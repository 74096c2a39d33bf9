"""Read a finished gnssrx run file (HDF5) for the exporters, the report and ``gnssrx info``.

:func:`load_run` returns a :class:`RunData` with the fix table (``/navigation``, as a FIX_DTYPE array), the
observables table (``/observables``, OBS_DTYPE), the decoded ephemerides (``/ephemeris``) and the parsed
configuration.  The Klobuchar/UTC parameters (:meth:`RunData.iono`) are taken, in this order, from a
``/iono_utc`` group (its attributes named like the :class:`IonoUtc` fields) when the file has one, from the
RINEX navigation file of an assisted run (``navigation.ephemeris``, when it can still be read), or by decoding
the LNAV message again from the stored prompt correlator outputs of ``/channels``.

Time helpers turn GPS week/seconds into UTC with the leap seconds broadcast in the message (or the table
below when they were not decoded).
"""
from __future__ import annotations

import datetime as _dt
import math
import os
from dataclasses import dataclass, field

import numpy as np
import yaml

from ..errors import UserError
from ..gnss.ephemeris import Ephemeris, IonoUtc
from ..runfile.writer import FIX_DTYPE, OBS_DTYPE, open_h5
from ..gnss.signals import C_LIGHT

GPS_EPOCH = _dt.datetime(1980, 1, 6)
WEEK_S = 604800.0

# GPS - UTC (s) in force from each UTC date on (the leap seconds inserted since the GPS epoch)
_LEAP_TABLE = (
    (_dt.datetime(1981, 7, 1), 1), (_dt.datetime(1982, 7, 1), 2), (_dt.datetime(1983, 7, 1), 3),
    (_dt.datetime(1985, 7, 1), 4), (_dt.datetime(1988, 1, 1), 5), (_dt.datetime(1990, 1, 1), 6),
    (_dt.datetime(1991, 1, 1), 7), (_dt.datetime(1992, 7, 1), 8), (_dt.datetime(1993, 7, 1), 9),
    (_dt.datetime(1994, 7, 1), 10), (_dt.datetime(1996, 1, 1), 11), (_dt.datetime(1997, 7, 1), 12),
    (_dt.datetime(1999, 1, 1), 13), (_dt.datetime(2006, 1, 1), 14), (_dt.datetime(2009, 1, 1), 15),
    (_dt.datetime(2012, 7, 1), 16), (_dt.datetime(2015, 7, 1), 17), (_dt.datetime(2017, 1, 1), 18),
)


def leap_seconds_at(gps_time: _dt.datetime) -> int:
    """GPS - UTC (s) from the built-in table (used when the message's value is not known)."""
    n = 0
    for since, value in _LEAP_TABLE:
        if gps_time >= since + _dt.timedelta(seconds=value):
            n = value
    return n


def gps_datetime(week: int, tow: float) -> _dt.datetime:
    """GPS week + seconds of week -> naive datetime on the GPS time scale (microsecond resolution)."""
    whole = math.floor(tow)
    return (GPS_EPOCH + _dt.timedelta(days=7 * int(week), seconds=int(whole))
            + _dt.timedelta(microseconds=round((tow - whole) * 1e6)))


def split_gps_time(week: int, tow: float, decimals: int):
    """GPS week + seconds of week -> (datetime to the whole second, fractional seconds rounded to
    ``decimals``) without losing precision (a datetime keeps only microseconds)."""
    whole = math.floor(tow)
    scale = 10 ** decimals
    frac = round((tow - whole) * scale)
    if frac >= scale:
        whole, frac = whole + 1, frac - scale
    t = GPS_EPOCH + _dt.timedelta(days=7 * int(week), seconds=int(whole))
    return t, frac / scale


@dataclass
class RunData:
    path: str
    attrs: dict
    config: dict
    fixes: np.ndarray
    obs: np.ndarray
    ephemerides: list = field(default_factory=list)
    groups: list = field(default_factory=list)
    _iono: object = field(default=None, repr=False)
    _iono_done: bool = field(default=False, repr=False)
    _decoded: tuple | None = field(default=None, repr=False)
    _used: list | None = field(default=None, repr=False)

    @property
    def stem(self) -> str:
        return os.path.splitext(self.path)[0]

    @property
    def name(self) -> str:
        return os.path.splitext(os.path.basename(self.path))[0]

    def cfg(self, dotted: str, default=None):
        node = self.config
        for part in dotted.split("."):
            if not isinstance(node, dict) or part not in node:
                return default
            node = node[part]
        return node

    @property
    def assisted(self) -> bool:
        return bool(self.cfg("navigation.ephemeris"))

    # ----------------------------------------------------------------------------- iono/UTC
    def iono(self) -> IonoUtc | None:
        """Klobuchar + UTC parameters the receiver used (see the module docstring), or None."""
        if not self._iono_done:
            self._iono_done = True
            self._iono = self._stored_iono()
            if self._iono is None and self.assisted:
                rinex = self.assisting_rinex()
                if rinex is not None:
                    self._iono = rinex[1]
            if self._iono is None:
                self._iono = self.decoded()[1]
        return self._iono

    def _stored_iono(self):
        import h5py
        with h5py.File(self.path, "r") as f:
            if "iono_utc" not in f:
                return None
            a = dict(f["iono_utc"].attrs)
        try:
            return IonoUtc(alpha=tuple(float(v) for v in a["alpha"]), beta=tuple(float(v) for v in a["beta"]),
                           a0=float(a.get("a0", 0.0)), a1=float(a.get("a1", 0.0)),
                           tot=float(a.get("tot", 0.0)), wnt=int(a.get("wnt", 0)),
                           dt_ls=int(a.get("dt_ls", 0)),
                           wn_lsf=_opt_int(a.get("wn_lsf")), dn=_opt_int(a.get("dn")),
                           dt_lsf=_opt_int(a.get("dt_lsf")))
        except (KeyError, TypeError, ValueError):
            return None

    def assisting_rinex(self):
        """(ephemerides dict, iono) of the assisted run's RINEX navigation file, or None when unreadable."""
        p = self.cfg("navigation.ephemeris")
        if not p:
            return None
        # the path is relative to the directory the run was started in, which the file does not record:
        # try it as given, next to the run file (and one level up), and beside the input recording
        here = os.path.dirname(os.path.abspath(self.path))
        cands = [p]
        if not os.path.isabs(p):
            cands += [os.path.join(here, p), os.path.join(os.path.dirname(here), p)]
        if self.attrs.get("input_path"):
            cands.append(os.path.join(os.path.dirname(str(self.attrs["input_path"])), os.path.basename(p)))
        from ..gnss.rinex import read_rinex_nav
        for c in cands:
            if os.path.isfile(c):
                try:
                    return read_rinex_nav(c)
                except UserError:
                    return None
        return None

    def decoded(self):
        """(ephemerides prn -> Ephemeris, IonoUtc or None) decoded again from the stored channel records."""
        if self._decoded is None:
            self._decoded = decode_channels(self.path, self.cfg("input.start_gps_week"))
        return self._decoded

    def leap_seconds(self) -> int:
        io = self.iono()
        if io is not None and io.dt_ls:
            return int(io.dt_ls)
        if len(self.fixes):
            return leap_seconds_at(gps_datetime(int(self.fixes["gps_week"][0]), float(self.fixes["gps_tow"][0])))
        return leap_seconds_at(_dt.datetime.utcnow())

    def utc(self, week: int, tow: float) -> _dt.datetime:
        return gps_datetime(week, tow) - _dt.timedelta(seconds=self.leap_seconds())

    # ----------------------------------------------------------------------------- derived
    def used_ephemerides(self) -> list:
        """The ephemerides the fixes used, one list without duplicates (same PRN, week, toe, IODE).

        Autonomous run: the decoded ephemerides stored in the run (or decoded again from the channel
        records).  Assisted run: for every observed satellite the assisting file's records with the toe
        nearest to the epochs' times (the engine's choice, which may change during the run), plus the
        decoded ones of satellites that file does not cover."""
        if self._used is not None:
            return self._used
        from ..gnss.ephemeris import select
        decoded = list(self.ephemerides) or list(self.decoded()[0].values())
        ephs = []
        if self.assisted and len(self.obs):
            rinex = self.assisting_rinex()
            if rinex is not None:
                # the engine picks the record with the nearest toe at every epoch: keep all it picked
                rx = self.rx_tow()
                for prn in sorted({int(p) for p in self.obs["prn"]}):
                    sel = self.obs["prn"] == prn
                    for tow in sorted(set(rx[sel].tolist())):
                        e = select(rinex[0].get(prn, []), tow)
                        if e is not None:
                            ephs.append(e)
        covered = {e.prn for e in ephs}
        ephs += [e for e in decoded if e.prn not in covered]
        seen, out = set(), []
        for e in ephs:
            key = (e.prn, e.week, round(e.toe), e.iode)
            if key not in seen:
                seen.add(key)
                out.append(e)
        self._used = out
        return out

    def rx_tow(self) -> np.ndarray:
        """Receiver clock reading (s of week) of every observable row: GPS time + clock bias / c."""
        obs, fx = self.obs, self.fixes
        if not len(obs):
            return np.zeros(0)
        if len(fx):
            order = np.argsort(fx["time_s"])
            bias = np.interp(obs["time_s"], fx["time_s"][order], fx["clock_bias_m"][order])
            bias = np.where(np.isfinite(bias), bias, 0.0)
        else:
            bias = np.zeros(len(obs))
        return obs["gps_tow"] + bias / C_LIGHT

    def fill_azel(self):
        """Compute azimuth/elevation of observable rows that have none (satellites not used in the fix)
        from the ephemerides and the nearest fix.  Modifies ``obs`` in place."""
        obs, fx = self.obs, self.fixes
        miss = ~np.isfinite(obs["elevation_deg"]) | ~np.isfinite(obs["azimuth_deg"])
        if not miss.any() or not len(fx):
            return
        from ..gnss.geodesy import azel
        from ..gnss.ephemeris import earth_rotation, sat_state
        order = np.argsort(fx["time_s"])
        ft = fx["time_s"][order]
        ephs = {e.prn: e for e in self.used_ephemerides()}
        for prn in np.unique(obs["prn"][miss]):
            if int(prn) not in ephs:
                continue
            rows = np.nonzero(miss & (obs["prn"] == prn))[0]
            k = np.clip(np.searchsorted(ft, obs["time_s"][rows]), 0, len(ft) - 1)
            rx = fx["ecef"][order][k]
            tau = obs["pseudorange_m"][rows] / C_LIGHT
            tau = np.where(np.isfinite(tau) & (np.abs(tau) < 0.2), tau, 0.075)
            pos, _, _, _ = sat_state(ephs[int(prn)], obs["gps_tow"][rows] - tau)
            pos = earth_rotation(pos, tau)
            for j, r in enumerate(rows):
                az, el = azel(rx[j], pos[j])
                obs["azimuth_deg"][r] = np.degrees(az)
                obs["elevation_deg"][r] = np.degrees(el)


def _opt_int(v):
    if v is None:
        return None
    try:
        return int(v)
    except (TypeError, ValueError):
        return None


def _table(group, dtype) -> np.ndarray:
    """A group of equally long datasets -> structured array of ``dtype`` (missing columns NaN/0)."""
    names = [n for n in dtype.names if n in group]
    n = group[names[0]].shape[0] if names else 0
    out = np.zeros(n, dtype)
    for name in dtype.names:
        if name in group:
            out[name] = group[name][:]
        elif out[name].dtype.kind == "f":
            out[name] = np.nan
    return out


def _ephemerides(group) -> list:
    from dataclasses import fields
    if "prn" not in group:
        return []
    n = group["prn"].shape[0]
    cols = {k: group[k][:] for k in group}
    out = []
    for i in range(n):
        kw = {}
        for f in fields(Ephemeris):
            if f.name not in cols:
                continue
            v = float(cols[f.name][i])
            kw[f.name] = int(round(v)) if f.type in ("int", int) else v
        try:
            out.append(Ephemeris(**kw))
        except TypeError:
            continue
    return out


def load_run(path) -> RunData:
    """Read a run file.  Raises UserError when it is missing or not a gnssrx run file."""
    path = os.fspath(path)
    f = open_h5(path, "run file")
    with f:
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
        if "config" not in attrs and "navigation" not in f and "channels" not in f:
            raise UserError(f"{path} is not a gnssrx run file (no config attribute, no /navigation, /channels)")
        try:
            config = yaml.safe_load(attrs.get("config", "")) or {}
        except yaml.YAMLError:
            config = {}
        fixes = _table(f["navigation"], FIX_DTYPE) if "navigation" in f else np.zeros(0, FIX_DTYPE)
        obs = _table(f["observables"], OBS_DTYPE) if "observables" in f else np.zeros(0, OBS_DTYPE)
        ephs = _ephemerides(f["ephemeris"]) if "ephemeris" in f else []
        groups = list(f.keys())
    return RunData(path=path, attrs=attrs, config=config if isinstance(config, dict) else {},
                   fixes=fixes, obs=obs, ephemerides=ephs, groups=groups)


# --------------------------------------------------------------------------------------------------
# LNAV decoding from stored channel records (for files that do not store the iono/UTC parameters)
# --------------------------------------------------------------------------------------------------
def _bit_sums(g):
    """Soft 20-ms bits of one channel group: (bit indices, sums), from the bit-synchronised epochs."""
    from ..runfile.record import STATE_BIT_SYNC
    state = g["state"][:]
    sync = state == STATE_BIT_SYNC
    if np.count_nonzero(sync) < 200:
        return None
    cp = g["code_period"][:][sync]
    pi = g["prompt_i"][:][sync].astype(float)
    ms = g["integration_ms"][:][sync].astype(float) if "integration_ms" in g else np.ones(len(cp))
    # the bit boundary: sign changes of the prompt happen only there
    s = np.sign(pi)
    change = np.nonzero(s[1:] * s[:-1] < 0)[0] + 1
    if len(change) < 5:
        return None
    offset = int(np.bincount(cp[change] % 20, minlength=20).argmax())
    bit = (cp - offset) // 20
    ub, inv = np.unique(bit, return_inverse=True)
    sums = np.bincount(inv, weights=pi)
    count = np.bincount(inv, weights=ms)
    full = count == 20
    return ub[full], sums[full]


def decode_channels(path, week_hint=None):
    """Decode the LNAV message of every stored channel again.  Returns (prn -> Ephemeris, IonoUtc or None)."""
    import h5py
    from ..gnss.lnav import LnavDecoder
    ephs, iono = {}, None
    with h5py.File(path, "r") as f:
        if "channels" not in f:
            return ephs, iono
        for name, g in f["channels"].items():
            if not all(k in g for k in ("state", "code_period", "prompt_i")):
                continue
            bits = _bit_sums(g)
            if bits is None:
                continue
            idx, sums = bits
            prn = int(g.attrs.get("prn", int(name[1:]) if name[1:].isdigit() else 0))
            dec = LnavDecoder(prn, week_hint=week_hint)
            runs = np.split(np.arange(len(idx)), np.nonzero(np.diff(idx) != 1)[0] + 1)
            for r in runs:
                if len(r):
                    dec.feed(sums[r], int(idx[r[0]]))
            if dec.ephemeris is not None:
                ephs[prn] = dec.ephemeris
            if iono is None and dec.iono_utc is not None:
                iono = dec.iono_utc
    return ephs, iono


# --------------------------------------------------------------------------------------------------
# truth (for the report)
# --------------------------------------------------------------------------------------------------
def load_truth(path):
    """Truth trajectory: a simulator truth HDF5 (/receiver/{gps_tow, ecef, velocity_ecef}, attr gps_week)
    or a YAML file with a static ``truth`` mapping (``ecef_m`` or ``lat_deg``/``lon_deg``/``height_m``).

    Returns dict(week, gps_tow (n,), ecef (n,3), velocity_ecef (n,3)) -- n = 1 for a static truth
    (velocity 0)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise UserError(f"truth file not found: {path}")
    if path.lower().endswith((".yaml", ".yml")):
        from ..config import read_yaml
        raw = read_yaml(path)
        t = raw.get("truth", raw)
        if not isinstance(t, dict):
            raise UserError(f"truth file {path}: no 'truth' mapping")
        if "ecef_m" in t:
            ecef = np.asarray(t["ecef_m"], float).reshape(1, 3)
        elif all(k in t for k in ("lat_deg", "lon_deg")):
            from ..gnss.geodesy import lla2ecef
            ecef = lla2ecef(float(t["lat_deg"]), float(t["lon_deg"]), float(t.get("height_m", 0.0))).reshape(1, 3)
        else:
            raise UserError(f"truth file {path}: 'truth' needs ecef_m or lat_deg/lon_deg/height_m")
        return {"week": None, "gps_tow": np.zeros(1), "ecef": ecef, "velocity_ecef": np.zeros((1, 3)),
                "static": True}
    import h5py
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise UserError(f"truth file {path} is neither YAML nor HDF5") from None
    with f:
        if "receiver" not in f:
            raise UserError(f"truth file {path} has no /receiver group (not a gnssrx simulator truth file)")
        g = f["receiver"]
        out = {"week": int(f.attrs.get("gps_week", 0)), "gps_tow": g["gps_tow"][:].astype(float),
               "ecef": g["ecef"][:].astype(float),
               "velocity_ecef": (g["velocity_ecef"][:].astype(float) if "velocity_ecef" in g
                                 else np.zeros((len(g["gps_tow"]), 3))),
               "static": False}
    return out


def truth_at(truth, week, tow):
    """Truth position and velocity at the given GPS times (arrays); NaN outside the truth's span."""
    tow = np.asarray(tow, float)
    if truth.get("static"):
        n = len(tow)
        return np.repeat(truth["ecef"], n, axis=0), np.zeros((n, 3))
    t = tow + (np.asarray(week, float) - truth["week"]) * WEEK_S if truth["week"] else tow
    tt = truth["gps_tow"]
    inside = (t >= tt[0]) & (t <= tt[-1])
    pos = np.stack([np.interp(t, tt, truth["ecef"][:, k]) for k in range(3)], axis=1)
    vel = np.stack([np.interp(t, tt, truth["velocity_ecef"][:, k]) for k in range(3)], axis=1)
    pos[~inside] = np.nan
    vel[~inside] = np.nan
    return pos, vel
