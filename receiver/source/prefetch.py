"""The pipeline's read-ahead view of the input stages (:class:`PrefetchingReader`): the next chunk is read
on a background thread from a copy of the input stage's state, and used only when it gives exactly the
samples of a plain read."""
from __future__ import annotations

import numpy as np

from .. import threads
from .decimate import DecimatingReader
from .io import SampleReader


#: chunks read ahead: the read-ahead thread starts the chunk after next as soon as the next one is done, so
#: it stays busy while the pool tracks and a chunk whose conditioning ran late does not hold the pool up
DEPTH = 2


class PrefetchingReader:
    """The pipeline's view of the input: every read goes through it (counted), and :meth:`chunk` reads the
    chunk at ``start`` while the next chunks (``DEPTH``) are read ahead on a background thread, each from
    a copy of the input stage's state after the one before it (the conditioning filter is causal and
    continues from the last read).  A read-ahead is used only if no other read happened in between (the
    channel manager's searches read elsewhere and move the filter stream), so the samples are exactly those
    of plain reads; otherwise the pending ones are discarded and the chunk read again.  The read-ahead runs
    the resampling / filtering kernels (which release the GIL) while the main thread does navigation and
    bookkeeping.  Only integer sample formats (a float input counts its non-finite samples as it reads)
    and the known input stages are read ahead."""

    def __init__(self, reader):
        object.__setattr__(self, "_r", reader)
        object.__setattr__(self, "reads", 0)
        object.__setattr__(self, "_pending", [])       # [(start, n, reads expected, future)] in stream order
        object.__setattr__(self, "_pool", None)
        object.__setattr__(self, "_ok", _can_read_ahead(reader))
        object.__setattr__(self, "ahead_used", 0)

    def __getattr__(self, name):
        return getattr(self._r, name)

    def __setattr__(self, name, value):
        setattr(self._r, name, value)

    def read(self, start: int, n: int) -> np.ndarray:
        """Plain read of samples [start, start+n) of the input stage, counted in ``reads`` (the pending
        read-ahead is then not used)."""
        object.__setattr__(self, "reads", self.reads + 1)
        return self._r.read(start, n)

    def chunk(self, start: int, n: int, next_start: int) -> np.ndarray:
        """read(start, n), then read ahead (next_start, n) and the chunks after it at the same stride."""
        pending, block = self._pending, None
        object.__setattr__(self, "_pending", [])
        if pending:
            s0, n0, reads0, fut = pending[0]
            try:
                got = fut.result()
            except Exception:                        # noqa: BLE001 - the plain read below reports it
                got = None
            if got is not None and (s0, n0, reads0) == (start, n, self.reads):
                block, fork, snap = got
                for k, v in fork.__dict__.items():   # the stage's state after that read
                    if snap.get(k, snap) is not v:
                        self._r.__dict__[k] = v
                object.__setattr__(self, "reads", self.reads + 1)
                object.__setattr__(self, "ahead_used", self.ahead_used + 1)
                pending = pending[1:]                # read on from that state: still valid
            else:
                _wait(pending)                       # (no two reads of the stage at once)
                pending = []
        if block is None:
            block = self.read(start, n)
        if self._ok:
            stride = next_start - start
            while len(pending) < DEPTH and stride > 0:
                s = pending[-1][0] + stride if pending else next_start
                if s >= self._r.end:
                    break
                pending.append((s, n, self.reads + len(pending), self._submit(pending, s, n)))
        object.__setattr__(self, "_pending", pending)
        return block

    def _submit(self, pending, s, n):
        """The read-ahead of (s, n) on the background thread, from the state after the last pending read
        (the stage's own state now when none is pending: copied here, before the caller changes it)."""
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor
            # the read-ahead's resampling runs on this thread beside the tracking pool (not queued
            # behind the chunk's tracking jobs, which the main thread submits right after this)
            object.__setattr__(self, "_pool", ThreadPoolExecutor(1, thread_name_prefix="gnssrx-read",
                                                                 initializer=threads.serial_here))
        if not pending:
            fork, snap = _fork_stage(self._r), dict(self._r.__dict__)
            return self._pool.submit(lambda: (fork.read(s, n), fork, snap))
        prev = pending[-1][3]

        def job():                                   # (one worker thread: prev is done when this starts)
            base = prev.result()[1]
            fork = _fork_stage(base)
            return fork.read(s, n), fork, dict(base.__dict__)
        return self._pool.submit(job)

    def close(self):
        """Wait for the pending read-ahead and stop the background thread (the input stage itself stays open)."""
        _wait(self._pending)
        object.__setattr__(self, "_pending", [])
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            object.__setattr__(self, "_pool", None)


def _wait(pending):
    """Wait for the pending read-aheads, whatever they return (they are not used)."""
    for *_, fut in pending:
        try:
            fut.result()
        except Exception:                            # noqa: BLE001 - an unused read-ahead
            pass


def _stages(reader):
    """The input stages from the outermost to the file reader."""
    out = [reader]
    while hasattr(out[-1], "__dict__") and "_reader" in out[-1].__dict__:
        out.append(out[-1].__dict__["_reader"])
    return out


def _can_read_ahead(reader) -> bool:
    from .conditioning import ConditionedReader
    st = _stages(reader)
    if not isinstance(st[-1], SampleReader) or getattr(st[-1], "_raw", None) is None or \
            st[-1]._raw.dtype.kind == "f":
        return False
    # stateless stages (file reader, resampler) and the conditioning stage (state copied: _fork_stage),
    # the latter only outermost (its state is what the read-ahead copies)
    return all(isinstance(s, (SampleReader, DecimatingReader)) for s in st[1:]) and \
        isinstance(st[0], (SampleReader, DecimatingReader, ConditionedReader))


def _fork_stage(reader):
    """A reader that reads like ``reader`` from its current state without changing it: the stateless
    stages are shared; the conditioning stage is copied with its filter state."""
    from .conditioning import ConditionedReader
    if isinstance(reader, ConditionedReader):
        fork = object.__new__(ConditionedReader)          # (its __getattr__ forwards: no copy.copy)
        fork.__dict__.update(reader.__dict__)
        c = reader.canceller
        cc = object.__new__(type(c))
        cc.__dict__.update({k: v.copy() if isinstance(v, np.ndarray) else v for k, v in c.__dict__.items()})
        fork.__dict__["canceller"] = cc
        return fork
    return reader

