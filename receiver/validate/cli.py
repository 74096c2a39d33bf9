"""``gnssrx validate``: run the outside-simulator matrix (``make validate``; from a checkout
``python -m receiver.cli validate``).

    gnssrx validate [MATRIX.yaml] [-j N] [--cache DIR] [--only SUBSTR,...] [--set KEY=VALUE ...] [--no-doc]
                    [--rescore] [--dry-run]

Prints the table and, for a full run of the default matrix with the default receiver (no ``--set``),
writes it into docs/validation.md's generated section.  ``--set`` adds receiver config overrides to every
row (cached apart from the default receiver's rows: the overrides are part of the cache key).
No GPS-SDR-SIM / C compiler / ../shared: one line on stderr, exit 2.
"""
from __future__ import annotations

import click

from ..errors import UserError


@click.command("validate")
@click.argument("matrix", required=False, default=None)
@click.option("--jobs", "-j", type=click.IntRange(1), default=2, help="recordings in parallel (1 receiver thread each)")
@click.option("--cache", default=None, help="cache / work directory (default out/validate)")
@click.option("--only", default="", help="comma-separated substrings of the row names to run")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE",
              help="a receiver config override for every row (repeatable; the page is then not written)")
@click.option("--no-doc", is_flag=True, help="print the table only")
@click.option("--rescore", is_flag=True, help="recompute the cached rows' metrics from their kept run files")
@click.option("--dry-run", is_flag=True, help="run nothing: the table of what is cached")
def validate(matrix, jobs, cache, only, sets, no_doc, rescore, dry_run):
    """Run the GPS-SDR-SIM validation matrix (configs/validate/matrix.yaml; docs/validation.md)."""
    import yaml

    from .gpssdrsim import DEFAULT_CACHE, NAV_FILE, SimulatorUnavailable
    from .matrix import DOC, MATRIX, doc_header, load_matrix, run_matrix, table, write_doc
    from ..logs import setup_cli
    setup_cli()
    if not NAV_FILE.is_file():
        raise UserError(f"validate: {NAV_FILE} not found (../shared or $GNSSRX_SHARED needed)")
    path = matrix or str(MATRIX)
    try:
        rows = load_matrix(path)
    except (OSError, ValueError, KeyError, TypeError, yaml.YAMLError) as e:
        raise UserError(f"validate: bad matrix {path}: {e}") from None
    if sets:                        # a wrong key or value: one line now, not an error in every row
        from ..schema import load_receiver_config
        from . import RECEIVER_CONFIG
        try:
            load_receiver_config(str(RECEIVER_CONFIG), list(sets))
        except UserError as e:
            raise UserError(f"validate: --set: {e}") from None
    for row in rows:                # (a row's own sets first: the command line's win)
        row["sets"] = list(row.get("sets") or []) + list(sets)
    cache = cache or str(DEFAULT_CACHE)
    sel = [s for s in only.split(",") if s]
    try:
        res = run_matrix(rows, jobs, cache, sel, rescore=rescore, dry_run=dry_run)
    except SimulatorUnavailable as e:
        raise UserError(f"validate: {e}") from None
    tab = table(rows, res)
    click.echo(tab)
    if not no_doc and not sel and not sets and matrix is None:
        write_doc(tab, header=doc_header(cache))
        click.echo(f"validate: table written to {DOC}")
