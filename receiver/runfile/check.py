"""Dataset checks for the HDF5 files gnssrx reads back: run files and simulator truth files.

A file with a dataset of the wrong type (text where numbers belong, a group where a dataset belongs, a
(N,) array where (N, 3) belongs) or tables whose columns differ in length is a one-line UserError that
names the file and the offending dataset or attribute -- before any reader indexes into it.

:func:`check_run_file` and :func:`check_truth_file` take an open h5py.File; the one run-file reader
(:class:`receiver.runfile.reader.RunFile`) and the one truth reader (:class:`receiver.runfile.truth.TruthFile`)
call them on opening, so every command that reads these files (info, export, report, eval, batch) is covered.
"""
from __future__ import annotations

import numpy as np

from ..errors import UserError

_NUMERIC = "biuf"


def _fields(dtype: np.dtype) -> dict:
    return {name: dtype[name].shape for name in dtype.names}


def _run_tables():
    from .record import EPOCH_DTYPE, FIX_DTYPE, OBS_DTYPE, VECTOR_LOG_DTYPE
    acq = {"prn": (), "doppler_hz": (), "code_phase_chips": (), "metric": (), "detected": (),
           "cn0_dbhz_est": (), "time_s": ()}
    return {"navigation": _fields(FIX_DTYPE), "observables": _fields(OBS_DTYPE),
            "vector": _fields(VECTOR_LOG_DTYPE), "acquisition": acq}, _fields(EPOCH_DTYPE)


_TRUTH_RECEIVER = {"time_s": (), "gps_tow": (), "ecef": (3,), "velocity_ecef": (3,), "clock_bias_m": (),
                   "clock_drift_mps": ()}


def _where(path, obj) -> str:
    return f"{path}: {obj.name}"


def _check_table(g, path: str, fields: dict | None, what: str):
    """Every dataset of group g: numeric; the known ones (fields: name -> trailing shape) with that shape;
    all with the same number of rows.  fields None: every dataset 1-D (or N x k) numeric."""
    import h5py
    if not isinstance(g, h5py.Group):
        raise UserError(f"{_where(path, g)} is a dataset, expected a group ({what})")
    rows, first = None, None
    for name, ds in g.items():
        known = fields is None or name in fields
        if isinstance(ds, h5py.Group):
            if known and fields is not None:
                raise UserError(f"{_where(path, ds)} is a group, expected a dataset ({what})")
            continue
        if not known:
            continue
        if ds.dtype.kind not in _NUMERIC or ds.dtype.names is not None:
            raise UserError(f"{_where(path, ds)} has type {ds.dtype}, expected numbers ({what})")
        if ds.ndim == 0:
            raise UserError(f"{_where(path, ds)} is a scalar, expected one value per row ({what})")
        if fields is not None and ds.shape[1:] != tuple(fields[name]):
            want = "(N" + "".join(f", {k}" for k in fields[name]) + ")"
            raise UserError(f"{_where(path, ds)} has shape {ds.shape}, expected {want} ({what})")
        if rows is None:
            rows, first = ds.shape[0], ds.name
        elif ds.shape[0] != rows:
            raise UserError(f"{_where(path, ds)} has {ds.shape[0]} rows, {first} has {rows} ({what})")


def _check_attrs(obj, path: str, names, what: str):
    for name in names:
        if name not in obj.attrs:
            continue
        v = obj.attrs[name]
        arr = np.asarray(v)
        if arr.dtype.kind not in _NUMERIC:
            raise UserError(f"{path}: attribute {obj.name.rstrip('/')}/{name} is {v!r}, expected a number "
                            f"({what})")


def check_run_file(f, path: str):
    """Validate the dataset types and shapes of an open gnssrx run file (see docs/reference/runfile-format.md)."""
    import h5py
    tables, epoch = _run_tables()
    what = "not a valid gnssrx run file"
    _check_attrs(f, path, ("sample_rate_hz", "if_hz", "first_sample", "n_samples", "n_fixes",
                           "wall_time_s", "nonfinite_samples"), what)
    for group, fields in tables.items():
        if group in f:
            _check_table(f[group], path, fields, what)
    if "channels" in f:
        ch = f["channels"]
        if not isinstance(ch, h5py.Group):
            raise UserError(f"{path}: /channels is a dataset, expected a group ({what})")
        for g in ch.values():
            _check_table(g, path, epoch, what)
            _check_attrs(g, path, ("prn",), what)
    if "ephemeris" in f:
        _check_table(f["ephemeris"], path, None, what)
    if "iono_utc" in f:
        g = f["iono_utc"]
        _check_attrs(g, path, [k for k in g.attrs if k != "source"], what)


def check_truth_file(f, path: str):
    """Validate the dataset types and shapes of an open simulator truth file."""
    import h5py
    what = "not a valid gnssrx truth file"
    _check_attrs(f, path, ("gps_week", "sample_rate_hz", "if_hz", "n_samples", "start_gps_tow_s"), what)
    if "receiver" in f:
        _check_table(f["receiver"], path, _TRUTH_RECEIVER, what)
        _check_table(f["receiver"], path, None, what)
    if "satellites" in f:
        sats = f["satellites"]
        if not isinstance(sats, h5py.Group):
            raise UserError(f"{path}: /satellites is a dataset, expected a group ({what})")
        for g in sats.values():
            _check_table(g, path, None, what)
