"""The run writer behind a background thread (:class:`BackgroundWriter`): the HDF5 appends of a run
overlap the tracking of the next chunk, in the same order and with the same bytes as direct writes."""
from __future__ import annotations

import queue
import threading

import numpy as np


class BackgroundWriter:
    """A :class:`RunWriter` whose appends (channel records, fixes, observables, vector log) run in order on
    one background thread, so that the HDF5 writing and compression overlap the tracking of the next chunk
    (the tracking kernels release the GIL; h5py holds it).  Fixes, observables and vector-log rows are
    gathered into blocks of at least ``TABLE_ROWS`` rows before they are appended (fewer, larger HDF5
    writes; the datasets hold the same rows).  Every other attribute or method first waits for the pending
    appends, then is the wrapped writer's, so reads of the file and one-off writes keep their order.  A
    write error on the thread (disk full: a UserError) is raised in the caller at the next call.  The
    queue is bounded: memory does not grow when the writing lags."""

    TABLE_ROWS = 2000
    _ASYNC = ("append_channel", "append_fixes", "append_observables", "append_vector_log")
    _TABLES = ("append_fixes", "append_observables", "append_vector_log")

    def __init__(self, writer, max_pending: int = 64):
        self._w = writer
        self._q: queue.Queue = queue.Queue(maxsize=max_pending)
        self._err: BaseException | None = None
        self._tables: dict[str, list] = {}
        self._thread = threading.Thread(target=self._work, name="gnssrx-write", daemon=True)
        self._thread.start()

    def _work(self):
        while True:
            item = self._q.get()
            try:
                if item is None:
                    return
                if self._err is None:
                    name, args = item
                    getattr(self._w, name)(*args)
            except BaseException as exc:     # noqa: BLE001 - handed to the caller
                self._err = exc
            finally:
                self._q.task_done()

    def _raise(self):
        if self._err is not None:
            err, self._err = self._err, None
            raise err

    def _put(self, name, args):
        self._raise()
        if name in self._TABLES:
            rows = args[0]
            if rows is None or len(rows) == 0:
                return
            buf = self._tables.setdefault(name, [])
            buf.append(rows)
            if sum(len(r) for r in buf) < self.TABLE_ROWS:
                return
            args = (np.concatenate(self._tables.pop(name)),)
        self._q.put((name, args))

    def write_acquisition(self, results, attrs=None):
        """Queued like the appends (a search no longer waits for the pending writes), from copies of the
        results taken now."""
        import copy
        self._put("write_acquisition", ([copy.copy(r) for r in results], dict(attrs or {})))

    def flush(self):
        """Wait until every append has been written (raises a write error)."""
        for name in list(self._tables):
            self._q.put((name, (np.concatenate(self._tables.pop(name)),)))
        self._q.join()
        self._raise()

    def __getattr__(self, name):
        if name in self._ASYNC:
            return lambda *args: self._put(name, args)
        self.flush()
        return getattr(self._w, name)

    def close(self, ok: bool = True):
        """Finish the run file (ok: write what is pending, then the writer's close renames it to the final name;
        not ok or a failure: drop the pending appends and remove the temporary file); stops the thread."""
        try:
            if ok:
                self.flush()
        except BaseException:
            ok = False
            raise
        finally:
            if not ok:
                self._tables.clear()
                self._err = None
                while True:                          # drop what is pending: the file is discarded
                    try:
                        self._q.get_nowait()
                        self._q.task_done()
                    except queue.Empty:
                        break
            self._q.put(None)
            self._thread.join()
            self._w.close(ok)

