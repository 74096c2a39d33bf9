"""Executors of a batch: inline, a local process pool (forkserver) or a Dask cluster.

Execution
    ``jobs == 1``: in this process; ``jobs > 1``: a process pool (forkserver); a Dask ``scheduler``
    (``tcp://host:port`` or ``local``): the distributed cluster, through its concurrent.futures executor
    (``output_dir`` and ``recordings_dir`` must then be on a file system shared with the workers, and the workers
    need gnssrx installed). Workers are warm (receiver/batch/warm.py): the imports and compiled kernels of a run are
    loaded once per worker process, before its first task. At most ``capacity`` tasks are in flight; ready runs go
    first, then new simulations. With ``keep_recordings: false`` at most capacity + 1 simulated IF files exist at a
    time and each is deleted as soon as its last run is done. Pool workers exit within 0.5 s when the batch process
    dies (even by SIGKILL), so a restarted batch never races an orphan; stale ``*.partial`` run files are removed at
    start. Ctrl-C stops the workers and keeps every finished run.
"""
from __future__ import annotations

import concurrent.futures as cf
import os
import threading
import time

from ..errors import UserError


class _InlineExecutor:
    """jobs == 1: run every task in this process (the serial reference)."""

    def submit(self, fn, *args):
        fut = cf.Future()
        try:
            fut.set_result(fn(*args))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller through the future
            if isinstance(exc, KeyboardInterrupt):
                raise
            fut.set_exception(exc)
        return fut

    def shutdown(self, **_):
        pass


#: imported by the forkserver before it forks the pool's workers: the run's modules and compiled kernels
#: (receiver/batch/warm.py), so every worker starts warm
_PRELOAD = ["receiver.batch._preload"]


def _process_pool(jobs: int):
    import multiprocessing as mp
    for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ.setdefault(v, "1")
    methods = mp.get_all_start_methods()
    if "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD)
    else:  # pragma: no cover - Windows / macOS without forkserver
        ctx = mp.get_context("spawn")
    return cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_worker_init,
                                  initargs=(os.getpid(),))


def _worker_init(batch_pid: int):
    """Pool workers exit as soon as the batch process is gone: a batch killed hard (SIGKILL) leaves no
    orphan still running (forkserver workers hold both ends of their task queue and never see EOF).
    The worker is warm (receiver/batch/warm.py): forked from the warmed forkserver, or warmed here (spawn)."""
    def watch():
        while True:
            time.sleep(0.5)
            try:
                os.kill(batch_pid, 0)
            except ProcessLookupError:
                os._exit(1)
            except OSError:      # pragma: no cover - exists, other owner
                pass

    threading.Thread(target=watch, name="gnssrx-batch-watchdog", daemon=True).start()
    from .warm import warm
    warm()


def _warm_dask(client) -> None:
    """Every worker of the cluster warm before its first task (receiver/batch/dask_warm.py); a cluster that
    refuses the plugin still runs the batch (each worker then pays its imports at its first task)."""
    try:
        from .dask_warm import register
        register(client)
    except Exception as exc:  # noqa: BLE001 - an optimisation only
        import logging
        logging.getLogger("receiver.batch").info("batch           Dask workers not pre-warmed (%s)", exc)


class _Exec:
    """The executor of one batch: inline, process pool or Dask (owns what it creates)."""

    def __init__(self, jobs: int, scheduler: str | None, client=None):
        self.kind, self.client, self.cluster, self._own_client = "local", client, None, False
        self.jobs = jobs
        if client is not None or scheduler:
            try:
                from distributed import Client, LocalCluster
            except ImportError:
                raise UserError("a Dask scheduler needs dask.distributed: pip install 'gnssrx[dask]'") from None
            if client is None:
                if scheduler == "local":
                    self.cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                                dashboard_address=None)
                    client = Client(self.cluster)
                else:
                    try:
                        client = Client(scheduler, timeout="10s")
                    except (OSError, TimeoutError, ValueError) as exc:
                        raise UserError(f"cannot connect to the Dask scheduler {scheduler}: {exc}") from None
                self._own_client = True
            self.client, self.kind = client, "dask"
            _warm_dask(client)
            self.capacity = max(1, sum(client.nthreads().values()))
            self.pool = client.get_executor(pure=False)
        elif jobs <= 1:
            self.kind, self.capacity, self.pool = "inline", 1, _InlineExecutor()
        else:
            self.capacity, self.pool = jobs, _process_pool(jobs)

    def submit(self, fn, arg):
        return self.pool.submit(fn, arg)

    def renew(self):
        """After a crashed worker broke the process pool: a fresh pool."""
        if self.kind == "local":
            self.pool.shutdown(wait=False, cancel_futures=True)
            self.pool = _process_pool(self.jobs)

    def close(self, abort=False):
        if self.kind == "local":
            if abort:
                for p in list(getattr(self.pool, "_processes", {}).values()):
                    try:
                        p.terminate()
                    except Exception:  # pragma: no cover
                        pass
            self.pool.shutdown(wait=not abort, cancel_futures=True)
        elif self.kind == "dask":
            if self._own_client:
                self.client.close()
                if self.cluster is not None:
                    self.cluster.close()
