"""The batch cache: result markers (JSON written last, atomically) and their reuse.

Layout of ``output_dir``
    ``runs/<run key>.h5`` (the run file), ``runs/<run key>.json`` (status, error, metrics; written last, so
    a run without its JSON is re-run), ``summary.csv``, ``summary.h5``, ``groups.csv``.  Simulated
    recordings live in ``recordings_dir`` as ``<recording key>.{bin,truth.h5,yaml,nav,json}`` (``.nav``:
    the broadcast ephemeris as RINEX 3.04, used by assisted inputs; ``.json`` written last).

A run whose JSON exists with the same key is not run again (failed runs neither, unless
``retry_failed``).  A run that raises is recorded as failed with its error; the others continue.  A killed
batch restarted with the same file runs only what is missing.
"""
from __future__ import annotations

import json
import math
import os

from .metrics import METRICS_VERSION, compute_metrics
from .plan import RunTask


def _write_json(path, obj):
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w") as fh:
        json.dump(obj, fh, indent=1, default=_json_default)
    os.replace(tmp, path)


def _json_default(o):
    try:
        import numpy as np
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
    except ImportError:  # pragma: no cover
        pass
    return repr(o)


def _read_json(path):
    try:
        with open(path) as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return None


def _cached_result(run: RunTask, retry_failed: bool):
    """The stored result of a run when it can be reused, else None."""
    res = _read_json(run.json)
    if not res or res.get("key") != run.key:
        return None
    if res.get("status") == "ok":
        if not os.path.isfile(run.h5):
            return None
        if res.get("metrics_version") != METRICS_VERSION:
            try:
                m = compute_metrics(run.h5, run.truth, run.reference_llh, run.carrier_settle_s)
            except Exception:
                return None
            old = res.get("metrics") or {}
            for k in ("job_wall_s", "job_cpu_s"):       # measured by the runner, not by compute_metrics
                m[k] = old.get(k, math.nan)
            res.update(metrics=m, metrics_version=METRICS_VERSION)
            _write_json(run.json, res)
        return res
    if res.get("status") == "failed" and not retry_failed:
        return res
    return None
