"""Click commands ``batch`` and ``compare`` (registered in the main ``gnssrx`` CLI).

    gnssrx batch BATCH.yaml [--jobs N] [--scheduler tcp://HOST:PORT | local] [--out DIR]
                            [--set key=value ...] [--force] [--retry-failed] [--dry-run] [--quiet]
    gnssrx compare SUMMARY.h5 [--by KEY ...] [--metric NAME ...] [--plot OUT.png | --no-plot]

UserError (bad batch keys, bad receiver keys in a variant, missing files) becomes one line on stderr and
exit code 2 through the main CLI.
"""
from __future__ import annotations

import os
import sys

import click

from ..errors import UserError


@click.command("batch")
@click.argument("batch_file", type=str)
@click.option("--jobs", "-j", type=int, default=None, help="parallel runs (default: batch key `jobs`, else cores)")
@click.option("--scheduler", type=str, default=None,
              help="Dask scheduler tcp://HOST:PORT, or 'local' for a LocalCluster (default: batch key)")
@click.option("--out", "out_dir", type=str, default=None, help="output directory (overrides output_dir)")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="override a batch key")
@click.option("--force", is_flag=True, help="run everything again (ignore the cache)")
@click.option("--retry-failed", is_flag=True, default=None, help="run failed runs again")
@click.option("--dry-run", is_flag=True, help="list the runs and whether they are cached; run nothing")
@click.option("--quiet", "-q", is_flag=True, help="no progress bar or summary")
def batch(batch_file, jobs, scheduler, out_dir, sets, force, retry_failed, dry_run, quiet):
    """Run a matrix of receiver configs x inputs x seeds from a BATCH_FILE (YAML: variants with config and
    set / sweep keys, inputs as scenarios or recordings, seeds, output_dir; README "Batch comparisons"); cached runs are
    reused."""
    from .config import load_batch
    from .cache import _cached_result
    from .plan import make_plan
    from .runner import run_batch
    if jobs is not None and jobs < 1:
        raise UserError("--jobs must be >= 1")
    overrides = list(sets)
    if out_dir:
        overrides.append(("output_dir", out_dir))
    b = load_batch(batch_file, overrides)
    if dry_run:
        plan = make_plan(b)
        retry = b.cfg.retry_failed if retry_failed is None else retry_failed
        n_cached = 0
        for r in plan.runs:
            res = None if force else _cached_result(r, retry)
            state = "run" if res is None else f"cached ({res.get('status')})"
            n_cached += res is not None
            seed = "" if r.seed is None else f" seed {r.seed}"
            click.echo(f"{r.key}  {r.variant:<30} {r.input}{seed}  {state}")
        need = {r.recording for r in plan.runs if r.recording}
        n_rec = sum(1 for k in need if not plan.recordings[k].available())
        click.echo(f"{len(plan.runs)} runs: {len(plan.runs) - n_cached} to run, {n_cached} cached; "
                   f"{len(need)} simulated recordings ({n_rec} not on disk); output {b.output_dir}")
        return
    try:
        res = run_batch(b, jobs=jobs, scheduler=scheduler, force=force, retry_failed=retry_failed,
                        quiet=quiet)
    except KeyboardInterrupt:
        click.echo(f"gnssrx: batch interrupted; finished runs are kept in {b.output_dir}/runs - run the same "
                   "command again to complete the missing ones", err=True)
        sys.exit(130)
    if not quiet:
        click.echo(res.text())
        failed = [r for r in res.rows if r["status"] != "ok"]
        for r in failed[:10]:
            click.echo(f"failed: {r['variant']} / {r['input']} seed {r['seed']}: {r['error']}", err=True)
        if len(failed) > 10:
            click.echo(f"... and {len(failed) - 10} more failed runs (see summary.csv)", err=True)


@click.command("compare")
@click.argument("summary", type=str)
@click.option("--by", "by", multiple=True,
              help="group by this summary column or receiver config key (repeatable; default: variant)")
@click.option("--metric", "metrics", multiple=True, help="metric to show (repeatable; default: all)")
@click.option("--plot", "plot", type=str, default=None,
              help="comparison plot PNG (default: compare_<by>.png beside the summary)")
@click.option("--no-plot", is_flag=True, help="print the table only")
def compare(summary, by, metrics, plot, no_plot):
    """Side-by-side table of a batch summary grouped by a key, and a comparison plot."""
    from .compare import compare as do_compare
    by = list(by) or ["variant"]
    if not no_plot and plot is None:
        safe = "_".join(by).replace("/", "_").replace(" ", "_")
        plot = os.path.join(os.path.dirname(os.path.abspath(summary)), f"compare_{safe}.png")
    table, _groups, path = do_compare(summary, by, metrics, None if no_plot else plot)
    click.echo(table)
    if path:
        click.echo(f"plot: {path}")
