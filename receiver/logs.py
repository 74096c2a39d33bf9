"""Logging: library code reports through ``logging.getLogger(__name__)`` (every logger is under
``receiver``) and never prints or redirects the process's streams.

The CLI installs :func:`setup_cli` once: plain message lines (no level, no time stamp) on the standard output
of the moment (so click's test runner and redirections see them).  The batch runner collects the records of
one task with :func:`capture` (only the records of the calling thread, so tasks on the threads of a Dask
worker do not mix).
"""
from __future__ import annotations

import contextlib
import logging
import sys
import threading

ROOT = "receiver"


class _PlainLines(logging.Handler):
    """One line per record, the message only, written to ``stream`` or to the current ``sys.stdout``."""

    def __init__(self, stream=None, thread: int | None = None):
        super().__init__()
        self.stream = stream
        self.thread = thread
        self.setFormatter(logging.Formatter("%(message)s"))

    def emit(self, record):
        if self.thread is not None and record.thread != self.thread:
            return
        try:
            out = self.stream if self.stream is not None else sys.stdout
            out.write(self.format(record) + "\n")
            out.flush() if hasattr(out, "flush") else None
        except Exception:  # noqa: BLE001 - logging must not break the run
            self.handleError(record)


def setup_cli(level: int = logging.INFO) -> None:
    """Route the library's log records to plain lines on stdout (idempotent)."""
    root = logging.getLogger(ROOT)
    root.setLevel(level)
    if not any(isinstance(h, _PlainLines) and h.thread is None for h in root.handlers):
        root.addHandler(_PlainLines())
    root.propagate = False


@contextlib.contextmanager
def capture(buf, level: int = logging.INFO):
    """Collect the library's log lines emitted by this thread into ``buf`` (a text stream) while active."""
    root = logging.getLogger(ROOT)
    handler = _PlainLines(buf, thread=threading.get_ident())
    old = root.level
    if root.level == logging.NOTSET or root.level > level:
        root.setLevel(level)
    root.addHandler(handler)
    try:
        yield buf
    finally:
        root.removeHandler(handler)
        root.setLevel(old)
