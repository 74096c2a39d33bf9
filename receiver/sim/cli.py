"""Click commands ``simulate`` and ``eval`` (registered in the main ``gnssrx`` CLI).

UserError raised here is turned into a one-line message (exit code 2) by the main CLI; ``simulate``
removes its partial output files on any error.
"""
from __future__ import annotations

import json
import os
import sys

import click


@click.command("simulate")
@click.argument("scenario", type=str)
@click.option("--output", "-o", "out", type=str, default=None,
              help="IF output file (default: <scenario name>.bin in the current directory); the truth "
                   "goes to <stem>.truth.h5 and a receiver input section to <stem>.yaml")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="override a scenario key")
@click.option("--quiet", "-q", is_flag=True, help="no progress bar or summary")
def simulate(scenario, out, sets, quiet):
    """Simulate an IF recording (GPS L1 C/A, QZSS, BeiDou B1I) with truth from a SCENARIO YAML file."""
    from .simulate import simulate as run_sim
    if out is None:
        out = os.path.splitext(os.path.basename(scenario))[0] + ".bin"
    # (no progress bar off a terminal)
    paths = run_sim(scenario, out, overrides=list(sets), progress=not quiet and sys.stderr.isatty())
    if not quiet:
        from ..runfile.truth import TruthFile
        with TruthFile(paths["truth"]) as tf:
            a = tf.attrs
            sats = tf.satellites(("visible",))
            vis = [k for k, s in sats.items() if s["visible"].size and bool(s["visible"].any())]
            click.echo(f"wrote {paths['if']} ({a['n_samples'] / a['sample_rate_hz']:.1f} s, {a['format']}, "
                       f"{a['sample_rate_hz'] / 1e6:g} MS/s, IF {a['if_hz']:g} Hz)")
            click.echo(f"truth {paths['truth']}: {len(vis)} satellites with signal: {' '.join(vis)}")
            b = tf.table("blockage")
            if b and b["kind"].size:
                from .blockage import KIND_OUTAGE, KIND_RANDOM, KIND_TOTAL
                kind, start, end = b["kind"], b["start_s"], b["end_s"]
                parts = []
                tot = kind == KIND_TOTAL
                if tot.any():
                    parts.append(f"{int(tot.sum())} total outages (" + ", ".join(
                        f"{x:g}-{y:g} s" for x, y in zip(start[tot], end[tot])) + ")")
                if (kind == KIND_OUTAGE).any():
                    parts.append(f"{int((kind == KIND_OUTAGE).sum())} satellite outages")
                if (kind == KIND_RANDOM).any():
                    ra = tf.group_attrs("blockage")
                    parts.append(f"{int((kind == KIND_RANDOM).sum())} random blockages in "
                                 f"{ra['random_start_s']:g}-{ra['random_end_s']:g} s, >= "
                                 f"{int(ra['random_min_visible'])} satellites visible "
                                 f"{100 * ra['random_fraction']:.1f} % of that time")
                click.echo("blockage: " + "; ".join(parts))
            if "l5_if" in paths:
                click.echo(f"wrote {paths['l5_if']} (GPS L5, truth {paths['l5_truth']}; same clock, "
                           f"named in input.signal_files)")
            if "e5a_if" in paths:
                click.echo(f"wrote {paths['e5a_if']} (Galileo E5a, truth {paths['e5a_truth']}; same clock, "
                           f"named in input.signal_files)")
            click.echo(f"receiver input section: {paths['yaml']}")


@click.command("eval")
@click.argument("run_h5", type=str)
@click.argument("truth_h5", type=str)
@click.option("--json", "as_json", is_flag=True, help="print the statistics as JSON")
@click.option("--outages", is_flag=True,
              help="score continuity through the truth's outages (total outages: time to the first good fix "
                   "after each, max errors, fixes to the end; random blockage: availability, 3D RMS); "
                   "automatic when the truth has outages, an error when it has none")
def evaluate_cmd(run_h5, truth_h5, as_json, outages):
    """Compare a receiver run file with a simulator truth file (position, velocity, clock, TTFF)."""
    from ..errors import UserError
    from ..evaluate import evaluate, format_table
    from ..evaluate.outages import format_report, has_outages, report
    stats = evaluate(run_h5, truth_h5)
    rep = report(run_h5, truth_h5)
    if outages and not has_outages(rep):
        raise UserError(f"--outages: the truth file {truth_h5} shows no total outage and no random blockage")
    if as_json:
        if has_outages(rep):
            stats = {**stats, "outages": rep}
        click.echo(json.dumps(stats, indent=2, default=float))
    else:
        click.echo(format_table(stats))
        if has_outages(rep):
            click.echo(format_report(rep))
