"""How many threads the receiver's parallel stages use (``gnssrx run --threads N``; default: all cores).

Tracking runs the channels of a chunk on a thread pool: the compiled epoch loop releases the GIL
(``nogil``), and every channel owns its state, so the records are the same whatever the thread count
(each channel's arithmetic is the same sequence of operations on its own arrays; tests compare run files
bit for bit).  The acquisition's FFTs use the same count.  Batch workers run with 1 thread each (the batch
parallelises over runs).
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

_threads: int | None = None
_pool: ThreadPoolExecutor | None = None
_pool_n = 0
_local = threading.local()


def cores() -> int:
    """CPU cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:       # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def set_threads(n: int | None) -> None:
    """Use n threads (None or 0: all cores)."""
    global _threads
    if n is not None and n < 0:
        raise ValueError("the thread count must be >= 0")
    _threads = int(n) if n else None


def threads() -> int:
    """The thread count in force (GNSSRX_THREADS in the environment when set_threads was not called)."""
    if _threads is not None:
        return _threads
    env = os.environ.get("GNSSRX_THREADS", "")
    if env.strip().isdigit() and int(env) > 0:
        return int(env)
    return cores()


def _get_pool() -> ThreadPoolExecutor:
    global _pool, _pool_n
    if _pool is None or _pool_n != threads():
        if _pool is not None:
            _pool.shutdown(wait=True)
        _pool_n = threads()
        _pool = ThreadPoolExecutor(max_workers=_pool_n, thread_name_prefix="gnssrx-track")
    return _pool


def shutdown() -> None:
    """Stop the pool's worker threads (a new pool starts on the next use)."""
    global _pool, _pool_n
    if _pool is not None:
        _pool.shutdown(wait=True)
        _pool, _pool_n = None, 0


def serial_here() -> None:
    """On the calling thread, map_ordered runs its items itself instead of on the pool: for a helper
    thread (the pipeline's read-ahead) whose work should run beside the pool's, not queue behind the
    tracking jobs (the same items in the same order: the same results)."""
    _local.serial = True


def map_ordered(fn, items: list) -> list:
    """[fn(x) for x in items], on the thread pool when more than one thread is allowed (results in the
    order of ``items``); in line on a thread marked by :func:`serial_here`."""
    n = min(threads(), len(items))
    if n <= 1 or getattr(_local, "serial", False):
        return [fn(x) for x in items]
    return list(_get_pool().map(fn, items))


def submit_ordered(fn, items: list):
    """Start [fn(x) for x in items] on the thread pool and return a callable that waits for the list
    (in the order of ``items``), so that the caller can work meanwhile.  With one thread (or one item)
    the list is computed here, before returning."""
    n = min(threads(), len(items))
    if n <= 1:
        res = [fn(x) for x in items]
        return lambda: res
    futs = [_get_pool().submit(fn, x) for x in items]
    return lambda: [f.result() for f in futs]


def submit_each(fn, items: list) -> list:
    """Start fn(x) for every x of ``items`` on the thread pool; a list of callables, one per item, each
    waiting for (and returning) its item's result, so that the caller can use the first results while the
    pool computes the others.  With one thread fn(x) runs in line when its callable is first called."""
    if threads() <= 1 or getattr(_local, "serial", False):
        def later(x):
            box = []
            return lambda: box[0] if box else (box.append(fn(x)) or box[0])
        return [later(x) for x in items]
    futs = [_get_pool().submit(fn, x) for x in items]
    return [f.result for f in futs]
