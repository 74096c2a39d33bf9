"""Reading run files: the one place that opens a gnssrx run file (HDF5) for reading.

:class:`RunFile` gives typed access to one open run file -- attributes and configuration, the fix table
(``/navigation`` as a FIX_DTYPE array), the observables (OBS_DTYPE), per-channel epoch records (any subset of
the EPOCH_DTYPE columns, optionally decimated), the vector-loop log (``/vector``), the acquisition table, the
stored ephemerides and iono/UTC parameters -- reading only the columns asked for, so memory stays bounded by
one channel's columns however long the run.

:func:`load_run` returns a :class:`RunData` for the exporters, the report and ``gnssrx info``: the fix and
observable tables, the decoded ephemerides and the parsed configuration.  The Klobuchar/UTC parameters
(:meth:`RunData.iono`) are taken, in this order, from a ``/iono_utc`` group (its attributes named like the
:class:`IonoUtc` fields) when the file has one, from the RINEX navigation file of an assisted run
(``navigation.ephemeris``, when it can still be read), or by decoding the LNAV message again from the stored
prompt correlator outputs of ``/channels``.

GPS week/seconds become UTC with the leap seconds broadcast in the message (or the table in
:mod:`receiver.gnss.time` when they were not decoded).  The simulator's truth file has its own reader,
:mod:`receiver.runfile.truth`.

Why this module is long: it is the one place that opens run files for reading (every consumer goes through
:class:`RunFile`), so its size follows the file's layout.
"""
from __future__ import annotations

import datetime as _dt
import os
from dataclasses import dataclass, field

import h5py
import numpy as np
import yaml

from ..errors import UserError
from ..gnss.ephemeris import Ephemeris, IonoUtc
from ..gnss.signals import C_LIGHT
from ..gnss.time import gps_datetime, leap_seconds_at
from .check import check_run_file
from .record import FIX_DTYPE, IONO_UNKNOWN, OBS_DTYPE, STATE_BIT_SYNC


def open_h5(path, what: str = "file") -> h5py.File:
    """Open an HDF5 file for reading; a missing or non-HDF5 file is a one-line UserError naming `what`."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise UserError(f"{what} not found: {path}")
    try:
        return h5py.File(path, "r")
    except OSError:
        raise UserError(f"{path} is not an HDF5 file") from None


def _plain(v):
    return v.decode() if isinstance(v, bytes) else v


def _read(ds, step: int = 1):
    return ds[:] if step == 1 else ds[::step]


class H5Input:
    """An HDF5 input open for reading (a context manager), its layout checked on opening: a dataset of the
    wrong type or shape is one line naming it (``check``: a function of :mod:`receiver.runfile.check`).
    The base of :class:`RunFile` and :class:`receiver.runfile.truth.TruthFile`."""

    def __init__(self, path, what: str, check=None):
        self.path = os.fspath(path)
        self.f = open_h5(self.path, what)
        if check is not None:
            try:
                check(self.f, self.path)
            except BaseException:
                self.close()
                raise

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Close the HDF5 file; calling it again does nothing."""
        if self.f is not None:
            self.f.close()
            self.f = None

    @property
    def attrs(self) -> dict:
        """Root attributes of the file as a dict (bytes decoded to str)."""
        return {k: _plain(v) for k, v in self.f.attrs.items()}


class RunFile(H5Input):
    """One run file open for reading (a context manager; :meth:`close` releases the file).

    Column access returns plain numpy arrays; a column the file does not have is left out of the returned
    dict (older files, hand-made files); the typed tables (:meth:`fixes`, :meth:`observables`) fill it with
    NaN / 0 instead."""

    def __init__(self, path, what: str = "run file"):
        super().__init__(path, what, check_run_file if what == "run file" else None)

    def config(self) -> dict:
        """The run's configuration (the ``config`` attribute, parsed); {} when absent or unreadable."""
        try:
            cfg = yaml.safe_load(_plain(self.f.attrs.get("config", ""))) or {}
        except yaml.YAMLError:
            cfg = {}
        return cfg if isinstance(cfg, dict) else {}

    @property
    def system(self) -> str:
        """RINEX letter of the run's signal (G for gps_l1ca, whose PRNs 193..202 are QZSS J01..J10)."""
        return str(_plain(self.f.attrs.get("system", "G")))

    def has(self, path: str) -> bool:
        """True when the file has a group or dataset at `path`."""
        return path in self.f

    def groups(self) -> list[str]:
        """Names of the file's top-level groups and datasets."""
        return list(self.f.keys())

    def is_run_file(self) -> bool:
        """True when the file looks like a run file (a ``config`` attribute, ``/navigation`` or ``/channels``)."""
        return "config" in self.f.attrs or "navigation" in self.f or "channels" in self.f

    def datasets(self) -> list[tuple[str, tuple, np.dtype]]:
        """(path, shape, dtype) of every dataset in the file."""
        rows = []

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                rows.append((name, obj.shape, obj.dtype))
        self.f.visititems(visit)
        return rows

    def group_attrs(self, path: str) -> dict | None:
        """Attributes of a group, or None when the file has no such group."""
        return {k: _plain(v) for k, v in self.f[path].attrs.items()} if path in self.f else None

    def length(self, path: str) -> int:
        """Rows of a table group (the length of its ``time_s``, else of its first dataset); 0 when absent."""
        if path not in self.f:
            return 0
        g = self.f[path]
        names = ["time_s"] if "time_s" in g else [k for k in g if isinstance(g[k], h5py.Dataset)]
        return int(g[names[0]].shape[0]) if names else 0

    def columns(self, path: str, names=None, step: int = 1) -> dict:
        """Datasets of a table group as a dict (``names``: the subset wanted; ``step``: every step-th row)."""
        if path not in self.f:
            return {}
        g = self.f[path]
        names = list(g.keys()) if names is None else [k for k in names if k in g]
        return {k: _read(g[k], step) for k in names if isinstance(g[k], h5py.Dataset)}

    # ---------------------------------------------------------------------------------- tables
    def fixes(self) -> np.ndarray:
        """``/navigation`` as a FIX_DTYPE array."""
        return _table(self.f["navigation"], FIX_DTYPE) if "navigation" in self.f else np.zeros(0, FIX_DTYPE)

    def fix_columns(self, names=None) -> dict | None:
        """``/navigation`` columns as a dict, or None when the run has no fixes table."""
        if "navigation" not in self.f or "gps_tow" not in self.f["navigation"]:
            return None
        return self.columns("navigation", names)

    def observables(self) -> np.ndarray:
        """``/observables`` as an OBS_DTYPE array."""
        return _table(self.f["observables"], OBS_DTYPE) if "observables" in self.f else np.zeros(0, OBS_DTYPE)

    def observable_columns(self, names=None) -> dict:
        """``/observables`` columns as a dict (only the ones present; {} when the run has none)."""
        return self.columns("observables", names)

    def vector_log(self, names=None, step: int = 1) -> dict | None:
        """``/vector`` columns (VECTOR_LOG_DTYPE names), or None when the run has no vector log."""
        if not self.length("vector"):
            return None
        return self.columns("vector", names, step)

    def acquisition(self, names=None) -> dict:
        """``/acquisition`` columns as a dict (only the ones present; {} when the run has none)."""
        return self.columns("acquisition", names)

    def ephemerides(self) -> list:
        """The decoded ephemerides stored in ``/ephemeris`` (and ``/ephemeris_bds`` / ``/ephemeris_gal``: the
        BeiDou / Galileo ones of a run over several signals)."""
        return [e for g in ("ephemeris", "ephemeris_bds", "ephemeris_gal") if g in self.f
                for e in _ephemerides(self.f[g])]

    def iono_utc_attrs(self) -> dict | None:
        """Attributes of the ``/iono_utc`` group (named like the IonoUtc fields), or None when the file has none."""
        return self.group_attrs("iono_utc")

    # ---------------------------------------------------------------------------------- channels
    def channel_names(self) -> list[str]:
        """Names of the ``/channels`` groups (satellite labels such as ``G05``); [] when the run has none."""
        return list(self.f["channels"].keys()) if "channels" in self.f else []

    def channel_prn(self, name: str) -> int:
        """PRN of one channel group: its ``prn`` attribute, else the digits of its name (0 when there are none)."""
        g = self.f["channels"][name]
        return int(g.attrs.get("prn", int(name[1:]) if name[1:].isdigit() else 0))

    def channel_length(self, name: str) -> int:
        """Number of epoch records stored for one channel."""
        return self.length(f"channels/{name}")

    def channel(self, name: str, names=None, step: int = 1) -> dict:
        """Epoch-record columns (EPOCH_DTYPE names) of one channel; ``step``: every step-th record."""
        return self.columns(f"channels/{name}", names, step)


@dataclass
class RunData:
    """One run file loaded by :func:`load_run`: root attributes, parsed configuration, the fix table (FIX_DTYPE),
    the observables (OBS_DTYPE), the stored ephemerides and the top-level group names; the iono/UTC parameters
    and the ephemerides decoded from the channel records are derived on first use (and cached)."""
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
        """The run file's path without its extension."""
        return os.path.splitext(self.path)[0]

    @property
    def name(self) -> str:
        """The run file's name without directory and extension."""
        return os.path.splitext(os.path.basename(self.path))[0]

    def cfg(self, dotted: str, default=None):
        """Configuration value at a dotted key (e.g. ``"navigation.ephemeris"``), or `default` when absent."""
        from ..config import dotted_get
        return dotted_get(self.config, dotted, default)

    @property
    def assisted(self) -> bool:
        """True for a run assisted by a RINEX navigation file (``navigation.ephemeris`` set)."""
        return bool(self.cfg("navigation.ephemeris"))

    @property
    def system(self) -> str:
        """RINEX letter of the run's signal (G for gps_l1ca, whose PRNs 193..202 are QZSS J01..J10)."""
        return str(self.attrs.get("system", "G"))

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
        with RunFile(self.path) as rf:
            a = rf.iono_utc_attrs()
        if a is None:
            return None
        try:
            return IonoUtc(alpha=tuple(float(v) for v in a["alpha"]), beta=tuple(float(v) for v in a["beta"]),
                           a0=float(a.get("a0", 0.0)), a1=float(a.get("a1", 0.0)),
                           tot=float(a.get("tot", 0.0)), wnt=int(a.get("wnt", 0)),
                           dt_ls=int(a.get("dt_ls", 0)),
                           wn_lsf=_opt_int(a.get("wn_lsf")), dn=_opt_int(a.get("dn")),
                           dt_lsf=_opt_int(a.get("dt_lsf")), ref_hz=float(a.get("ref_hz", 1575.42e6)))
        except (KeyError, TypeError, ValueError):
            return None

    def assisting_rinex(self):
        """(ephemerides dict, iono) of the assisted run's RINEX navigation file, or None when unreadable: the
        records of the run's systems, keyed like its observables (:func:`receiver.gnss.rinex.read_rinex_nav_for`)."""
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
        from ..gnss.rinex import read_rinex_nav_for
        for c in cands:
            if os.path.isfile(c):
                try:
                    return read_rinex_nav_for(c, self.signal_letters())
                except UserError:
                    return None
        return None

    def signal_letters(self) -> list:
        """The RINEX letters of the run's systems, once each in the order of ``signals`` (else ``signal``; G when
        the config has neither): a second band (gal_e5a beside gal_e1) adds no system."""
        from ..gnss.registry import get_signal
        names = self.cfg("signals") or [self.cfg("signal") or "gps_l1ca"]
        try:
            return list(dict.fromkeys(get_signal(n).system for n in names))
        except (ValueError, TypeError):
            return [self.system if self.system != "M" else "G"]

    def decoded(self):
        """(ephemerides prn -> Ephemeris, IonoUtc or None) decoded again from the stored channel records."""
        if self._decoded is None:
            self._decoded = decode_channels(self.path, self.cfg("input.start_gps_week"))
        return self._decoded

    def leap_seconds(self) -> int:
        """GPS-UTC leap seconds (s): the broadcast value when decoded, else the table's at the first fix (or now)."""
        io = self.iono()
        if io is not None and io.dt_ls:
            return int(io.dt_ls)
        if len(self.fixes):
            return leap_seconds_at(gps_datetime(int(self.fixes["gps_week"][0]), float(self.fixes["gps_tow"][0])))
        return leap_seconds_at(_dt.datetime.utcnow())

    def utc(self, week: int, tow: float) -> _dt.datetime:
        """UTC time of a GPS week and time of week (s), with :meth:`leap_seconds`."""
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
        covered = {self.eph_key(e) for e in ephs}
        ephs += [e for e in decoded if self.eph_key(e) not in covered]
        seen, out = set(), []
        for e in ephs:
            key = (self.eph_key(e), e.week, round(e.toe), e.iode)
            if key not in seen:
                seen.add(key)
                out.append(e)
        self._used = out
        return out

    def eph_key(self, e) -> int:
        """The observables' ``prn`` of an ephemeris' satellite: its PRN, or in a run over several signals
        (system M) its satellite key (receiver.gnss.satid.sat_key: BeiDou PRN p -> 400 + p)."""
        from ..gnss.satid import MIXED, sat_key
        return sat_key(getattr(e, "system", "G"), e.prn) if self.system == MIXED else e.prn

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
        ephs = {self.eph_key(e): e for e in self.used_ephemerides()}
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


#: the value of a column an older run file does not have, where neither NaN nor 0 would be honest
_MISSING = {"iono_params": IONO_UNKNOWN}


def _table(group, dtype) -> np.ndarray:
    """A group of equally long datasets -> structured array of ``dtype`` (missing columns NaN/0, or
    their _MISSING value)."""
    names = [n for n in dtype.names if n in group]
    n = group[names[0]].shape[0] if names else 0
    out = np.zeros(n, dtype)
    for name in dtype.names:
        if name in group:
            out[name] = group[name][:]
        elif name in _MISSING:
            out[name] = _MISSING[name]
        elif out[name].dtype.kind == "f":
            out[name] = np.nan
    return out


def _ephemerides(group) -> list:
    from dataclasses import fields
    if "prn" not in group:
        return []
    n = group["prn"].shape[0]
    cols = {k: group[k][:] for k in group}
    cls = Ephemeris
    if "tgd2" in cols:                       # BeiDou ephemerides (BDT toe/toc/week)
        from ..gnss.bds_ephemeris import BdsEphemeris as cls
    elif "bgd_e1e5a" in cols:                # Galileo I/NAV ephemerides (GST toe/toc, week = GPS week)
        from ..gnss.gal_inav import GalEphemeris as cls
    out = []
    for i in range(n):
        kw = {}
        for f in fields(cls):
            if f.name not in cols:
                continue
            v = float(cols[f.name][i])
            kw[f.name] = int(round(v)) if f.type in ("int", int) else v
        try:
            out.append(cls(**kw))
        except TypeError:
            continue
    return out


def load_run(path) -> RunData:
    """Read a run file.  Raises UserError when it is missing or not a gnssrx run file."""
    path = os.fspath(path)
    with RunFile(path) as rf:
        if not rf.is_run_file():
            raise UserError(f"{path} is not a gnssrx run file (no config attribute, no /navigation, /channels)")
        return RunData(path=path, attrs=rf.attrs, config=rf.config(), fixes=rf.fixes(), obs=rf.observables(),
                       ephemerides=rf.ephemerides(), groups=rf.groups())


# --------------------------------------------------------------------------------------------------
# LNAV decoding from stored channel records (for files that do not store the iono/UTC parameters)
# --------------------------------------------------------------------------------------------------
def _bit_sums(ch: dict):
    """Soft 20-ms bits of one channel (columns state, code_period, prompt_i[, integration_ms]):
    (bit indices, sums), from the bit-synchronised epochs."""
    sync = ch["state"] == STATE_BIT_SYNC
    if np.count_nonzero(sync) < 200:
        return None
    cp = ch["code_period"][sync]
    pi = ch["prompt_i"][sync].astype(float)
    ms = ch["integration_ms"][sync].astype(float) if "integration_ms" in ch else np.ones(len(cp))
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
    from ..gnss.lnav import LnavDecoder
    ephs, iono = {}, None
    with RunFile(path) as rf:
        for name in rf.channel_names():
            ch = rf.channel(name, ("state", "code_period", "prompt_i", "integration_ms"))
            if not all(k in ch for k in ("state", "code_period", "prompt_i")):
                continue
            bits = _bit_sums(ch)
            if bits is None:
                continue
            idx, sums = bits
            prn = rf.channel_prn(name)
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
