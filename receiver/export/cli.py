"""Click commands ``export``, ``report`` and ``info`` (registered in the main ``gnssrx`` CLI).

UserError raised here (missing or foreign run file, unwritable output) is turned into a one-line message
with exit code 2 by the main CLI.
"""
from __future__ import annotations

import json

import click

from ..errors import UserError


@click.command("export")
@click.argument("run_h5", type=str)
@click.option("--rinex", is_flag=True, help="RINEX 3.04 observation (.obs) and navigation (.nav) files")
@click.option("--nmea", is_flag=True, help="NMEA 0183 GGA/RMC/GSA/GSV sentences (.nmea)")
@click.option("--kml", is_flag=True, help="KML track (.kml)")
@click.option("--gpx", is_flag=True, help="GPX track (.gpx)")
@click.option("--all", "everything", is_flag=True, help="all of the above")
@click.option("--quiet", "-q", is_flag=True, help="print nothing")
def export(run_h5, rinex, nmea, kml, gpx, everything, quiet):
    """Write standard files beside RUN_H5 (RUN.obs, RUN.nav, RUN.nmea, RUN.kml, RUN.gpx)."""
    from . import export_all
    kinds = {"rinex": rinex or everything, "nmea": nmea or everything, "kml": kml or everything,
             "gpx": gpx or everything}
    if not any(kinds.values()):
        raise UserError("nothing to export: give one or more of --rinex --nmea --kml --gpx (or --all)")
    written = export_all(run_h5, kinds, log=None if quiet else click.echo)
    if not written:
        raise UserError(f"{run_h5}: nothing could be exported (no fixes or observables in the run)")


@click.command("report")
@click.argument("run_h5", type=str)
@click.option("--truth", type=str, default=None,
              help="truth: a simulator truth HDF5 file, or a YAML file with a static 'truth' position")
@click.option("--output", "-o", type=str, default=None, help="PNG file (default: RUN_report.png beside RUN_H5)")
def report(run_h5, truth, output):
    """Plot a one-page PNG report of a run (C/N0, sky plot, Doppler, lock, position/velocity)."""
    from . import output_paths
    from .report import write_report
    from ..runfile.reader import load_run
    from ..runfile.truth import load_truth
    run = load_run(run_h5)
    tr = load_truth(truth) if truth else None
    out = output or output_paths(run_h5)["report"]
    from ..safeio import check_output
    check_output(out, reads=[run_h5, truth], what="report", suffixes=())   # makes missing directories
    try:
        write_report(run, out, truth=tr)
    except OSError as exc:
        raise UserError(f"cannot write {out}: {exc.strerror or exc}") from None
    click.echo(f"wrote {out}")


@click.command("info")
@click.argument("run_h5", type=str)
@click.option("--json", "as_json", is_flag=True, help="print as JSON")
@click.option("--no-config", is_flag=True, help="leave out the run's configuration")
def info(run_h5, as_json, no_config):
    """Describe a run file: schema, version, channels, fixes, time span, configuration."""
    from .info import format_info, run_info
    d = run_info(run_h5)
    if no_config:
        d.pop("config", None)
    if as_json:
        click.echo(json.dumps(d, indent=2, default=str))
    else:
        click.echo(format_info(d, show_config=not no_config))
