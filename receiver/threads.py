"""How many threads the receiver's parallel stages use (``gnssrx run --threads N``; default: all cores).

Tracking runs the channels of a chunk on a thread pool: the compiled epoch loop releases the GIL
(``nogil``), and every channel owns its state, so the records are the same whatever the thread count
(each channel's arithmetic is the same sequence of operations on its own arrays; tests compare run files
bit for bit).  The acquisition's FFTs use the same count.  Batch workers run with 1 thread each (the batch
parallelises over runs).

Why one pool per process (the module-level :data:`POOL`, not an object of each run): the thread count is a
property of the process -- its cores, ``--threads`` / :func:`set_threads`, ``GNSSRX_THREADS`` -- and every
parallel stage of every run in the process (acquisition FFTs, tracking) shares the same workers, so that
two stages or two API runs never oversubscribe the cores with pools of their own; the workers start on
first use and :func:`shutdown` (the CLI's exit) stops them.  The state is the :class:`ThreadPool` object;
the functions below are its methods on :data:`POOL`.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

class ThreadPool:
    """The thread count in force and the executor that runs the parallel stages (see the module docstring)."""

    def __init__(self):
        self._threads: int | None = None      # set_threads; None: GNSSRX_THREADS or all cores
        self._pool: ThreadPoolExecutor | None = None
        self._pool_n = 0
        self._local = threading.local()       # serial_here marks

    def set_threads(self, n: int | None) -> None:
        """Use n threads (None or 0: all cores)."""
        if n is not None and n < 0:
            raise ValueError("the thread count must be >= 0")
        self._threads = int(n) if n else None

    def threads(self) -> int:
        """The thread count in force (GNSSRX_THREADS in the environment when set_threads was not called)."""
        if self._threads is not None:
            return self._threads
        env = os.environ.get("GNSSRX_THREADS", "")
        if env.strip().isdigit() and int(env) > 0:
            return int(env)
        return cores()

    def _executor(self) -> ThreadPoolExecutor:
        if self._pool is None or self._pool_n != self.threads():
            if self._pool is not None:
                self._pool.shutdown(wait=True)
            self._pool_n = self.threads()
            self._pool = ThreadPoolExecutor(max_workers=self._pool_n, thread_name_prefix="gnssrx-track")
        return self._pool

    def shutdown(self) -> None:
        """Stop the pool's worker threads (a new pool starts on the next use)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool, self._pool_n = None, 0

    def serial_here(self) -> None:
        """On the calling thread, map_ordered runs its items itself instead of on the pool: for a helper
        thread (the pipeline's read-ahead) whose work should run beside the pool's, not queue behind the
        tracking jobs (the same items in the same order: the same results)."""
        self._local.serial = True

    def _serial(self) -> bool:
        return getattr(self._local, "serial", False)

    def map_ordered(self, fn, items: list) -> list:
        """[fn(x) for x in items], on the thread pool when more than one thread is allowed (results in the
        order of ``items``); in line on a thread marked by :meth:`serial_here`."""
        n = min(self.threads(), len(items))
        if n <= 1 or self._serial():
            return [fn(x) for x in items]
        return list(self._executor().map(fn, items))

    def submit_ordered(self, fn, items: list):
        """Start [fn(x) for x in items] on the thread pool and return a callable that waits for the list
        (in the order of ``items``), so that the caller can work meanwhile.  With one thread (or one item)
        the list is computed here, before returning."""
        n = min(self.threads(), len(items))
        if n <= 1:
            res = [fn(x) for x in items]
            return lambda: res
        futs = [self._executor().submit(fn, x) for x in items]
        return lambda: [f.result() for f in futs]

    def submit_each(self, fn, items: list) -> list:
        """Start fn(x) for every x of ``items`` on the thread pool; a list of callables, one per item, each
        waiting for (and returning) its item's result, so that the caller can use the first results while
        the pool computes the others.  With one thread fn(x) runs in line when its callable is first
        called."""
        if self.threads() <= 1 or self._serial():
            def later(x):
                box = []
                return lambda: box[0] if box else (box.append(fn(x)) or box[0])
            return [later(x) for x in items]
        futs = [self._executor().submit(fn, x) for x in items]
        return [f.result for f in futs]


def cores() -> int:
    """CPU cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:       # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


#: the process's pool (see the module docstring for why there is one)
POOL = ThreadPool()
set_threads = POOL.set_threads
threads = POOL.threads
shutdown = POOL.shutdown
serial_here = POOL.serial_here
map_ordered = POOL.map_ordered
submit_ordered = POOL.submit_ordered
submit_each = POOL.submit_each
