"""Names of the standard outputs written beside a run file (RINEX, NMEA, KML, GPX, PNG report).

The exporters (:mod:`receiver.export`) write them; the pipeline checks before a run that none of them would
overwrite a file the run reads.  ``out/run.h5 -> out/run.obs, out/run.nav, out/run.nmea, out/run.kml,
out/run.gpx, out/run_report.png``.
"""
from __future__ import annotations

import os

KINDS = ("rinex", "nmea", "kml", "gpx", "report")


def output_paths(run_h5) -> dict:
    """File names of every output kind for a run file (``rinex`` maps to the obs file, ``nav`` too)."""
    stem = os.path.splitext(os.fspath(run_h5))[0]
    return {"obs": stem + ".obs", "nav": stem + ".nav", "nmea": stem + ".nmea", "kml": stem + ".kml",
            "gpx": stem + ".gpx", "report": stem + "_report.png"}


def _enabled(cfg_output, kind: str) -> bool:
    if cfg_output is None:
        return False
    if isinstance(cfg_output, dict):
        return bool(cfg_output.get(kind, False))
    if isinstance(cfg_output, (set, list, tuple, frozenset)):
        return kind in cfg_output
    try:
        return bool(cfg_output[kind]) if kind in cfg_output else bool(getattr(cfg_output, kind, False))
    except TypeError:
        return bool(getattr(cfg_output, kind, False))
