"""Batch comparisons: a matrix of receiver configs x inputs x seeds, run in parallel, scored, summarised.

* :mod:`.config`  - the batch YAML schema and the expansion into runs (``plan``)
* :mod:`.runner`  - content-hashed caching, simulated-recording cache, local pool / Dask execution
* :mod:`.metrics` - per-run metrics from the run HDF5 and the truth
* :mod:`.compare` - summary table (CSV + HDF5), grouped statistics, side-by-side comparison and plot
* :mod:`.cli`     - the ``gnssrx batch`` and ``gnssrx compare`` commands
"""
from .config import BATCH_SCHEMA, load_batch  # noqa: F401


def run_batch(*args, **kwargs):
    """See :func:`receiver.batch.runner.run_batch`."""
    from .runner import run_batch as _run_batch
    return _run_batch(*args, **kwargs)
