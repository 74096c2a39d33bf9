"""Output files that appear complete or not at all.

* :func:`check_output` checks an output path *before* any work is done: the directory exists (or is made),
  the path is not a directory, it is not one of the files the command reads (``os.path.samefile``), the
  name plus the temporary suffix fits the file system's name limit, and the directory is writable.
* :class:`OutputLock` is an ``O_EXCL`` lock file ``<output>.lock`` holding the writer's PID; a second run
  writing the same output stops with one line (a lock left by a dead process is taken over).
* :class:`AtomicH5` writes an HDF5 file under ``<output>.partial`` through :class:`GuardedFile` and
  renames it only after a successful close, flush and fsync; on failure the temporary file is removed.

Why :class:`GuardedFile`: when a write fails inside HDF5 (disk full, ``ulimit -f``), HDF5 prints one error
stack per cached object and then crashes on the next flush.  h5py's file-object driver sends every write
through Python instead; :class:`GuardedFile` records the first ``OSError`` and reports success to HDF5, so
HDF5's state stays consistent, and the writer raises a one-line :class:`UserError` at the next check.
"""
from __future__ import annotations

import errno
import io
import os
import re

from .errors import UserError

TMP_SUFFIX = ".partial"
LOCK_SUFFIX = ".lock"


def _samefile(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _name_max(d: str) -> int:
    try:
        return os.pathconf(d, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        return 255


def check_output(path, reads=(), what: str = "output", suffixes=(TMP_SUFFIX, LOCK_SUFFIX),
                 make_dirs: bool = True) -> str:
    """Validate an output path before the run; returns it as a str.  ``reads``: the files the command
    reads (an output equal to one of them is an error, as is a temporary/lock name equal to one)."""
    if path is None or not os.fspath(path):
        raise UserError(f"{what} path is empty")
    path = os.fspath(path)
    if path.endswith(os.sep) or os.path.isdir(path):
        raise UserError(f"{what} {path} is a directory")
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.exists(d):
        if not make_dirs:
            raise UserError(f"{what} directory does not exist: {d}")
        try:
            os.makedirs(d, exist_ok=True)
        except OSError as exc:
            raise UserError(f"cannot create the {what} directory {d}: {exc.strerror or exc}") from None
    if not os.path.isdir(d):
        raise UserError(f"{what} directory {d} is not a directory")
    name = os.path.basename(path)
    longest = max([len(os.fsencode(name + s)) for s in suffixes] + [len(os.fsencode(name))])
    limit = _name_max(d)
    if longest > limit:
        raise UserError(f"{what} file name {name[:40]}... is too long: {longest} bytes with the temporary "
                        f"suffix, the file system allows {limit}")
    for r in reads:
        if not r:
            continue
        r = os.fspath(r)
        for cand in [path] + [path + s for s in suffixes]:
            if os.path.exists(cand) and _samefile(cand, r):
                raise UserError(f"{what} {path} is the same file as the input {r}")
    if not os.access(d, os.W_OK | os.X_OK):
        raise UserError(f"{what} directory {d} is not writable")
    return path


class OutputLock:
    """``<path>.lock`` created with O_EXCL; holds the PID of the writer."""

    def __init__(self, path, what: str = "output"):
        self.path = os.fspath(path) + LOCK_SUFFIX
        self.what, self.target = what, os.fspath(path)
        self.held = False

    def acquire(self):
        """Create the lock file (a stale lock of a dead process is taken over); returns self.  Another live writer
        holding it, or a lock that cannot be created, is a one-line UserError."""
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                pid = self._owner()
                if pid is not None and pid != os.getpid() and _alive(pid):
                    raise UserError(f"{self.what} {self.target} is being written by another run "
                                    f"(pid {pid}; lock file {self.path})") from None
                try:                                      # stale lock: its writer is gone
                    os.remove(self.path)
                except FileNotFoundError:
                    pass
                except OSError as exc:
                    raise UserError(f"cannot remove the stale lock {self.path}: "
                                    f"{exc.strerror or exc}") from None
                continue
            except OSError as exc:
                raise UserError(f"cannot write the {self.what} {self.target}: {exc.strerror or exc}") from None
            try:
                os.write(fd, f"{os.getpid()}\n".encode())
            except OSError:
                pass
            finally:
                os.close(fd)
            self.held = True
            return self
        raise UserError(f"{self.what} {self.target} is locked ({self.path})")

    def _owner(self):
        try:
            with open(self.path, "rb") as fh:
                return int(fh.read(32).split()[0])
        except (OSError, ValueError, IndexError):
            return None

    def release(self):
        """Remove the lock file if this object holds it (idempotent)."""
        if self.held:
            self.held = False
            remove_quietly(self.path)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_quietly(path):
    """Remove a file, ignoring any OSError (missing file included)."""
    try:
        os.remove(path)
    except FileNotFoundError:
        pass
    except OSError:
        pass


def write_error_message(what: str, path: str, exc: BaseException) -> str:
    """The one-line message for a failed write of `what` to `path`; a full disk or file size limit is named as such."""
    reason = getattr(exc, "strerror", None) or str(exc)
    if getattr(exc, "errno", None) in (errno.ENOSPC, errno.EFBIG, errno.EDQUOT):
        reason += " (disk full or file size limit)"
    else:
        m = re.match(r"(\d+) requested and (\d+) written", reason)     # numpy's short write (no errno)
        if m:
            reason = (f"short write ({m.group(1)} bytes requested, {m.group(2)} written; disk full or file "
                      f"size limit)")
    return f"writing the {what} {path} failed: {reason}"


class GuardedFile(io.RawIOBase):
    """A binary file for h5py's file-object driver that never lets a write error reach HDF5: the first
    ``OSError`` is kept in ``error`` (later writes are skipped, positions still advance)."""

    def __init__(self, path):
        super().__init__()
        self._fh = open(path, "w+b", buffering=0)
        self.error: OSError | None = None
        self._pos = 0

    def readable(self):
        """Always True (h5py's file-object driver reads back what it wrote)."""
        return True

    def writable(self):
        """Always True."""
        return True

    def seekable(self):
        """Always True."""
        return True

    def seek(self, offset, whence=0):
        """Move the logical position (``whence`` 0 and 1 only set it; 2 seeks the real file); returns the position."""
        if whence == 0:
            self._pos = offset
        elif whence == 1:
            self._pos += offset
        else:
            self._pos = self._fh.seek(offset, whence)
        return self._pos

    def tell(self):
        """The logical position (bytes from the start of the file)."""
        return self._pos

    def readinto(self, b):
        """Read into `b` from the logical position; returns the number of bytes read."""
        self._fh.seek(self._pos)
        n = self._fh.readinto(b) or 0
        self._pos += n
        return n

    def write(self, b):
        """Write `b` at the logical position and report it all written; after a write error (kept in ``error``)
        nothing more reaches the disk but the position still advances."""
        mv = memoryview(b).cast("B")
        n = len(mv)
        if self.error is None:
            try:
                self._fh.seek(self._pos)
                done = 0
                while done < n:
                    k = self._fh.write(mv[done:])
                    if not k:
                        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                    done += k
            except OSError as exc:
                self.error = exc
        self._pos += n
        return n

    def truncate(self, size=None):
        """Truncate the file to `size` bytes (default: the logical position); an OSError is kept in ``error``."""
        size = self._pos if size is None else size
        if self.error is None:
            try:
                self._fh.truncate(size)
            except OSError as exc:
                self.error = exc
        return size

    def flush(self):
        """Nothing to do: the file is unbuffered (:meth:`sync` fsyncs it)."""
        pass

    def sync(self):
        """fsync; an error is recorded like a write error."""
        if self.error is None:
            try:
                os.fsync(self._fh.fileno())
            except OSError as exc:
                self.error = exc

    def close(self):
        """Close the real file; an OSError is kept in ``error`` unless an earlier one already is."""
        try:
            self._fh.close()
        except OSError as exc:
            if self.error is None:
                self.error = exc
        super().close()


class AtomicH5:
    """An HDF5 file written as ``<path>.partial`` and renamed to ``path`` by :meth:`commit`.

    ``f`` is the open h5py.File.  Call :meth:`check` at safe points (it raises a one-line UserError after
    a write error); :meth:`commit` on success, :meth:`abort` on any failure (idempotent)."""

    def __init__(self, path, what: str = "output", reads=(), lock: bool = True, make_dirs: bool = True):
        import h5py
        self.path = check_output(path, reads, what, make_dirs=make_dirs)
        self.tmp = self.path + TMP_SUFFIX
        self.what = what
        self.f = self._file = None
        self.lock = OutputLock(self.path, what) if lock else None
        if self.lock is not None:
            self.lock.acquire()
        try:
            self._file = GuardedFile(self.tmp)
            self.f = h5py.File(self._file, "w")
        except OSError as exc:
            self._cleanup()
            raise UserError(write_error_message(what, self.path, exc)) from None
        except BaseException:
            self._cleanup()
            raise

    def check(self):
        """Raise a one-line UserError if a write to the temporary file has failed."""
        if self._file is not None and self._file.error is not None:
            raise UserError(write_error_message(self.what, self.path, self._file.error))

    def commit(self, before_rename=None):
        """Close, flush and fsync the temporary file; if all went well (and ``before_rename()`` does not
        raise), rename it to the final name.  Any failure removes it."""
        try:
            self.f.close()
            self._file.sync()
            self._file.close()
            self.check()
            if before_rename is not None:
                before_rename()
            os.replace(self.tmp, self.path)
        except OSError as exc:
            self.abort()
            raise UserError(write_error_message(self.what, self.path, exc)) from None
        except BaseException:
            self.abort()
            raise
        self._file = None
        self._release()

    def abort(self):
        """Close and remove the temporary file and release the lock (errors on closing ignored; idempotent)."""
        try:
            if self.f is not None:
                self.f.close()
        except Exception:
            pass
        try:
            if self._file is not None:
                self._file.close()
        except Exception:
            pass
        self._cleanup()

    def _cleanup(self):
        self.f = self._file = None
        remove_quietly(self.tmp)
        self._release()

    def _release(self):
        if self.lock is not None:
            self.lock.release()
