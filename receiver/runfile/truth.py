"""The truth of a run: the one reader of the simulator's truth file (``OUT.truth.h5``, written by
:mod:`receiver.sim.simulate`) and of static truth YAML, the interpolation of truth to fix times, and the one
carrier-phase-error computation of a tracked channel against the truth.

Truth file layout (docs/reference/runfile-format.md): attributes (``gps_week``, ``start_gps_tow_s``, ...);
``/receiver`` (``time_s`` since the first sample, ``gps_tow``, ``ecef``, ``velocity_ecef``, ``clock_bias_m``,
``clock_drift_mps``); ``/satellites/Gnn`` per PRN (``time_s``, ``carrier_phase_cycles``, ``doppler_hz``,
``pseudorange_m``, ``visible``, ...); optional ``/blockage``.
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import UserError
from ..estimation.interpolation import hermite, interp_columns
from ..gnss.time import week_seconds_since
from .check import check_truth_file
from .reader import H5Input, _plain


class TruthFile(H5Input):
    """A simulator truth file open for reading (a context manager)."""

    def __init__(self, path):
        super().__init__(path, "truth file", check_truth_file)

    @property
    def week(self) -> int:
        """GPS week of the truth's ``gps_tow`` (0 when the file does not say)."""
        return int(self.f.attrs.get("gps_week", 0))

    def has(self, path: str) -> bool:
        """True when the file holds the group or dataset ``path`` (e.g. ``receiver``, ``satellites``)."""
        return path in self.f

    def receiver(self, names=("gps_tow", "ecef", "velocity_ecef")) -> dict:
        """``/receiver`` columns (those present of ``names``; None: all) plus ``week``."""
        if "receiver" not in self.f:
            raise UserError(f"truth file {self.path} has no /receiver group (not a gnssrx simulator truth file)")
        g = self.f["receiver"]
        names = list(g.keys()) if names is None else [k for k in names if k in g]
        out = {k: g[k][:] for k in names}
        out["week"] = self.week
        return out

    def satellite_names(self) -> list[str]:
        """Names (``Gnn``) of the satellite groups under ``/satellites`` ([] when the file has none)."""
        return list(self.f["satellites"].keys()) if "satellites" in self.f else []

    def satellite(self, name: str, names=None) -> dict:
        """Columns of satellite ``name`` (``Gnn``): those present of ``names`` (None: all), as arrays."""
        g = self.f["satellites"][name]
        names = list(g.keys()) if names is None else [k for k in names if k in g]
        return {k: g[k][:] for k in names}

    def satellites(self, names=None) -> dict:
        """name (``Gnn``) -> columns of every satellite."""
        return {s: self.satellite(s, names) for s in self.satellite_names()}

    def group_attrs(self, path: str) -> dict | None:
        """Attributes of a group, or None when the file has no such group."""
        return {k: _plain(v) for k, v in self.f[path].attrs.items()} if path in self.f else None

    def table(self, path: str) -> dict:
        """Any other table group (e.g. ``/blockage``) as a dict of its datasets; {} when absent."""
        if path not in self.f:
            return {}
        g = self.f[path]
        return {k: g[k][:] for k in g}


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
    try:
        tf = TruthFile(path)
    except UserError as exc:
        if "is not an HDF5 file" not in str(exc):
            raise                                   # an HDF5 file with a bad dataset: named as such
        raise UserError(f"truth file {path} is neither YAML nor HDF5") from None
    with tf:
        r = tf.receiver(("gps_tow", "ecef", "velocity_ecef"))
    n = len(r["gps_tow"])
    return {"week": r["week"], "gps_tow": r["gps_tow"].astype(float), "ecef": r["ecef"].astype(float),
            "velocity_ecef": (r["velocity_ecef"].astype(float) if "velocity_ecef" in r else np.zeros((n, 3))),
            "static": False}


def truth_at(truth, week, tow):
    """Truth position and velocity at the given GPS times (arrays); NaN outside the truth's span."""
    tow = np.asarray(tow, float)
    if truth.get("static"):
        n = len(tow)
        return np.repeat(truth["ecef"], n, axis=0), np.zeros((n, 3))
    t = week_seconds_since(np.asarray(week, float), tow, truth["week"]) if truth["week"] else tow
    tt = truth["gps_tow"]
    inside = (t >= tt[0]) & (t <= tt[-1])
    pos = interp_columns(tt, truth["ecef"], t)
    vel = interp_columns(tt, truth["velocity_ecef"], t)
    pos[~inside] = np.nan
    vel[~inside] = np.nan
    return pos, vel


def carrier_phase_error(ch: dict, sat: dict, if_hz: float = 0.0, at: str = "start"):
    """Truth carrier phase minus the channel's carrier NCO phase (cycles), per epoch record.

    ch: epoch-record columns of one channel (``time_s``, ``carrier_phase_cycles``; with ``at="mid"`` also
    ``doppler_hz`` and ``integration_ms``); sat: that satellite's truth columns (``time_s``,
    ``carrier_phase_cycles``, ``doppler_hz``).  The NCO phase is taken without its IF ramp (``if_hz * t``; the
    truth phase is the Doppler part only) at the epoch start (``at="start"``) or mid-epoch (``at="mid"``:
    start phase + NCO Doppler * T/2); the truth is interpolated there by cubic Hermite interpolation of
    (phase, Doppler).  Returns (t, error): unwrapped, including any half-cycle (data-bit) ambiguity and
    constant offset -- callers decide what to remove.
    """
    t0 = np.asarray(ch["time_s"], dtype=float)
    nco = np.asarray(ch["carrier_phase_cycles"], dtype=float) - if_hz * t0
    if at == "mid":
        half = np.asarray(ch["integration_ms"], dtype=float) * 0.5e-3
        t = t0 + half
        nco = nco + np.asarray(ch["doppler_hz"], dtype=float) * half
    elif at == "start":
        t = t0
    else:
        raise ValueError(f"at must be 'start' or 'mid', not {at!r}")
    true = hermite(sat["time_s"], sat["carrier_phase_cycles"], sat["doppler_hz"], t)
    return t, true - nco
