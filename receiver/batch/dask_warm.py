"""The Dask worker plugin that warms batch workers (:func:`receiver.batch.warm.warm`); imported only on
the Dask path (it needs dask.distributed)."""
from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin

from .warm import warm


class WarmWorker(WorkerPlugin):
    """Dask worker plugin: :func:`receiver.batch.warm.warm` on every worker, present and future (its record
    is kept as the worker's ``gnssrx_warm`` attribute)."""

    name = "gnssrx-warm"

    def setup(self, worker):
        """Called by dask.distributed on every worker."""
        worker.gnssrx_warm = warm()


def register(client) -> None:
    """Register :class:`WarmWorker` on ``client``'s cluster (waits until the present workers ran it)."""
    if hasattr(client, "register_plugin"):
        client.register_plugin(WarmWorker())
    else:                                    # pragma: no cover - dask.distributed before 2023.9
        client.register_worker_plugin(WarmWorker())
