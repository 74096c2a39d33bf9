"""Warm batch workers: the imports and the compiled kernels of a run paid once per worker process, not per run.

A fresh ``gnssrx run`` process spends ~0.5 s of CPU before its first sample: the interpreter, numpy, numba and
the receiver's modules, numba's one-time set-up and the loading of every compiled function it calls from
numba's on-disk cache.  A batch worker runs many tasks, so :func:`warm` does all of that once, before the
first task:

- the local pool (``jobs > 1``, receiver/batch/executors.py): the forkserver imports
  :mod:`receiver.batch._preload`, which calls :func:`warm`; every pool worker is forked from that warm
  process (and its initializer calls :func:`warm` again, which returns at once);
- Dask: the batch registers :class:`receiver.batch.dask_warm.WarmWorker` (a worker plugin) on the cluster
  it uses, so every worker,
  including one that joins or restarts later, warms itself once; a cluster started by hand can do the
  same with ``dask worker --preload receiver.batch.warm SCHEDULER`` (:func:`dask_setup`).

The results do not change: a kernel loaded early is the same machine code the run would load itself
(tests/unit/batch/test_batch_warm.py compares a warm pool's run files with separate ``gnssrx run`` ones).
Every step is best effort: a kernel that cannot be loaded is left to load (or compile) at its first call.
"""
from __future__ import annotations

import importlib
import os
import sys
import time

#: the modules a batch task imports (receiver/batch/tasks.py): the receiver, the simulator, the scoring
RUN_MODULES = ("receiver.batch.tasks", "receiver.pipeline", "receiver.sim.simulate", "receiver.evaluate",
               "receiver.export")

_DONE: dict | None = None


def load_cached_kernels(prefix: str = "receiver.") -> int:
    """Load, from numba's on-disk cache, every compiled version of every cached compiled function in the
    imported modules named ``prefix*`` that the cache holds for this machine and this source (those a run
    would otherwise load at their first call).  Nothing is compiled: entries whose data file is missing
    are skipped.  Returns the number of versions loaded."""
    try:
        from numba.core.dispatcher import Dispatcher
        from numba.core.registry import cpu_target
    except ImportError:                                   # pragma: no cover - numba is a dependency
        return 0
    magic = cpu_target.target_context.codegen().magic_tuple()
    seen, n = set(), 0
    for name, mod in list(sys.modules.items()):
        if not name.startswith(prefix) or mod is None:
            continue
        for obj in list(vars(mod).values()):
            if not isinstance(obj, Dispatcher) or id(obj) in seen:
                continue
            seen.add(id(obj))
            n += _load_dispatcher(obj, magic)
    return n


def _load_dispatcher(disp, magic) -> int:
    """The cached versions of one compiled function (see :func:`load_cached_kernels`)."""
    cache = getattr(disp, "_cache", None)
    index_file = getattr(cache, "_cache_file", None)
    if index_file is None or not hasattr(index_file, "_load_index"):
        return 0                                          # not cache=True
    try:
        index = index_file._load_index()
        n = 0
        for key, data_name in index.items():
            sig, key_magic = key[0], key[1]
            if key_magic != magic or sig in disp.overloads:
                continue
            if not os.path.exists(os.path.join(index_file._cache_path, data_name)):
                continue
            before = sum(disp.stats.cache_misses.values())
            disp.compile(sig)
            n += sum(disp.stats.cache_misses.values()) == before      # loaded, not compiled
        return n
    except Exception:  # noqa: BLE001 - warming is an optimisation: the run loads what it needs itself
        return 0


def warm(modules=RUN_MODULES) -> dict:
    """Prepare this process for batch tasks once (later calls return the first call's record): one BLAS
    thread, numba's set-up (receiver/_numba_start.py, stale caches dropped), the run's ``modules`` imported
    and their compiled functions loaded (:func:`load_cached_kernels`).  Returns {"kernels": versions
    loaded, "cpu_s": CPU seconds spent, "wall_s": wall seconds}."""
    global _DONE
    if _DONE is not None:
        return _DONE
    t0, c0 = time.perf_counter(), time.process_time()
    from .. import _malloc, _numba_start, limit_blas_threads
    limit_blas_threads()
    _malloc.configure()
    try:
        from ..tracking import refresh_compiled_caches
        refresh_compiled_caches()
        _numba_start.prepare()
        _numba_start.tolerate_cache_write_errors()      # as the CLI's set-up: a full disk is not a crash
        for m in modules:
            importlib.import_module(m)
        n = load_cached_kernels()
    except Exception:  # noqa: BLE001 - a worker that cannot warm up still runs its tasks
        n = 0
    _DONE = {"kernels": n, "cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - t0,
             "pid": os.getpid()}
    return _DONE


def dask_setup(worker):
    """``dask worker --preload receiver.batch.warm``: warm the worker as it starts."""
    worker.gnssrx_warm = warm()
