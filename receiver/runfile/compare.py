"""Exact comparison of two run files (or two output trees): every group, dataset (dtype, shape, values,
NaNs in the same places) and attribute, bit for bit -- how a refactoring shows that outputs are unchanged
(``scripts/tools/compare_runs.py`` is its command line).

Ignored: attributes that depend on the wall clock or on the invocation (``command``, ``created_utc``,
``wall_time_s``, ``realtime_factor``).  In string attributes and text files the directory of each side is
replaced by a placeholder first, so ``-o /tmp/a/run.h5`` and ``-o /tmp/b/run.h5`` compare equal, and a
string attribute naming an existing file is compared as its real path (the same input reached through a
symlink).  Each function appends one line per difference to ``out``.
"""
from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

IGNORED_ATTRS = {"command", "created_utc", "wall_time_s", "realtime_factor"}
TEXT_SUFFIXES = {".yaml", ".yml", ".csv", ".txt", ".json", ".nmea", ".kml", ".gpx", ".html", ".md", ".obs",
                 ".nav", ".rnx"}


def _norm(value, root: str):
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if isinstance(value, str):
        if "\n" not in value and len(value) < 4096 and os.path.isabs(value) and os.path.exists(value):
            value = os.path.realpath(value)      # the same input reached through a symlinked directory
        return value.replace(root, "<DIR>")
    return value


def _same_array(a: np.ndarray, b: np.ndarray) -> bool:
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.dtype.names:                                   # compound: field by field
        return all(_same_array(a[n], b[n]) for n in a.dtype.names)
    if a.dtype.kind in "fc":
        # bit-identical including NaN payload positions; -0.0 vs 0.0 counts as a difference
        return a.tobytes() == b.tobytes()
    if a.dtype.kind == "O":
        return all(_norm(x, "") == _norm(y, "") for x, y in zip(a.ravel(), b.ravel()))
    return np.array_equal(a, b)


def _attrs(obj, root: str) -> dict:
    return {k: _norm(v, root) for k, v in obj.attrs.items() if k not in IGNORED_ATTRS}


def _same_attr(x, y) -> bool:
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        x, y = np.asarray(x), np.asarray(y)
        return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()
    if type(x) is not type(y):
        return False
    if isinstance(x, float) and np.isnan(x):
        return np.isnan(y)
    return x == y


def compare_h5(a: Path, b: Path, out: list[str], label: str = "") -> None:
    """Compare two HDF5 files group by group, dataset by dataset (bit for bit) and attribute by attribute;
    appends one line per difference to `out`, prefixed with `label`."""
    ra, rb = str(a.parent.resolve()), str(b.parent.resolve())
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        def walk(ga, gb, path):
            aa, ab = _attrs(ga, ra), _attrs(gb, rb)
            for k in sorted(set(aa) | set(ab)):
                if k not in aa or k not in ab:
                    out.append(f"{label}{path}@{k}: only in {'A' if k in aa else 'B'}")
                elif not _same_attr(aa[k], ab[k]):
                    out.append(f"{label}{path}@{k}: {str(aa[k])[:60]!r} != {str(ab[k])[:60]!r}")
            if isinstance(ga, h5py.Dataset) or isinstance(gb, h5py.Dataset):
                if not (isinstance(ga, h5py.Dataset) and isinstance(gb, h5py.Dataset)):
                    out.append(f"{label}{path}: dataset on one side only")
                    return
                x, y = ga[()], gb[()]
                x, y = np.asarray(x), np.asarray(y)
                if not _same_array(x, y):
                    detail = f"{x.dtype}{x.shape} vs {y.dtype}{y.shape}"
                    if x.shape == y.shape and x.dtype == y.dtype and x.dtype.kind in "fiu" and x.size:
                        d = np.abs(x.astype(float) - y.astype(float))
                        detail += f", max |diff| {np.nanmax(d) if np.isfinite(d).any() else 'nan'}"
                    out.append(f"{label}{path}: values differ ({detail})")
                return
            ka, kb = set(ga.keys()), set(gb.keys())
            for k in sorted(ka ^ kb):
                out.append(f"{label}{path.rstrip('/')}/{k}: only in {'A' if k in ka else 'B'}")
            for k in sorted(ka & kb):
                walk(ga[k], gb[k], f"{path.rstrip('/')}/{k}")
        walk(fa, fb, "/")


def compare_files(a: Path, b: Path, out: list[str], label: str = "") -> None:
    """Compare two output files by type: HDF5 as :func:`compare_h5`, text with each side's directory replaced,
    anything else byte for byte; appends one line per difference to `out`."""
    if a.suffix == ".h5":
        compare_h5(a, b, out, label)
    elif a.suffix in TEXT_SUFFIXES:
        ta = a.read_text(errors="replace").replace(str(a.parent.resolve()), "<DIR>")
        tb = b.read_text(errors="replace").replace(str(b.parent.resolve()), "<DIR>")
        if ta != tb:
            out.append(f"{label}: text differs")
    elif a.read_bytes() != b.read_bytes():
        out.append(f"{label}: bytes differ")
