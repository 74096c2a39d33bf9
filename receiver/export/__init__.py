"""Standard outputs written from a finished run file: RINEX, NMEA, KML, GPX and a PNG report.

``export_all(run_h5, cfg_output)`` writes the outputs switched on in the ``output`` config section
(``rinex``, ``nmea``, ``kml``, ``gpx``, ``report``) beside the HDF5 file, with names derived from it::

    out/run.h5 -> out/run.obs, out/run.nav (RINEX 3.04), out/run.nmea, out/run.kml, out/run.gpx,
                  out/run_report.png

The same files can be written later with ``gnssrx export RUN.h5 --rinex --nmea --kml --gpx`` and
``gnssrx report RUN.h5``.  Everything is read from the HDF5 file (see :mod:`receiver.runfile.reader`).
"""
from __future__ import annotations

from ..errors import UserError
from ..runfile.outputs import KINDS, _enabled, output_paths  # noqa: F401  (names beside the run file)


def export_all(run_h5, cfg_output, log=None, truth=None) -> dict:
    """Write the outputs enabled in ``cfg_output`` for the run file ``run_h5``.

    cfg_output: the ``output`` config section (or a dict / a collection of kind names).
    log: callable for one line per written file (None: silent).  truth: optional truth file for the report.
    Returns {kind: path} of the files written.  An output that the run cannot provide (no fixes, no
    observables or no ephemerides) is skipped with a log line; a bad run file raises UserError.
    """
    wanted = [k for k in KINDS if _enabled(cfg_output, k)]
    if not wanted:
        return {}
    from ..runfile.reader import load_run
    run = load_run(run_h5)
    paths = output_paths(run_h5)
    written: dict = {}
    say = log or (lambda *_: None)

    def attempt(kind, path, fn, what):
        try:
            info = fn(path, run)
        except ValueError as exc:          # nothing to write (no fixes / observables / ephemerides)
            say(f"export: no {what} written: {exc}")
            return
        except OSError as exc:
            raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
        written[kind] = path
        detail = ", ".join(f"{k} {v}" for k, v in (info or {}).items()
                           if isinstance(v, (int, float, bool)) and not isinstance(v, bool))
        say(f"wrote {path}" + (f" ({detail})" if detail else ""))

    if "rinex" in wanted:
        from .rinex_obs import write_nav, write_rinex_obs
        attempt("obs", paths["obs"], write_rinex_obs, "RINEX observation file")
        attempt("nav", paths["nav"], write_nav, "RINEX navigation file")
    if "nmea" in wanted:
        from .nmea import write_nmea
        attempt("nmea", paths["nmea"], _needs_fixes(write_nmea), "NMEA file")
    if "kml" in wanted:
        from .tracks import write_kml
        attempt("kml", paths["kml"], _needs_fixes(write_kml), "KML track")
    if "gpx" in wanted:
        from .tracks import write_gpx
        attempt("gpx", paths["gpx"], _needs_fixes(write_gpx), "GPX track")
    if "report" in wanted:
        from .report import write_report
        attempt("report", paths["report"], lambda p, r: write_report(r, p, truth=truth), "report")
    return written


def _needs_fixes(fn):
    def wrapped(path, run):
        if not len(run.fixes):
            raise ValueError("the run has no fixes")
        return fn(path, run)
    return wrapped


__all__ = ["export_all", "output_paths", "KINDS"]
