"""SIGINT / SIGTERM handling: stop at the next safe point instead of inside compiled code.

The CLI installs :func:`install` once.  Inside a :func:`deferred` region (the receiver's chunk loop, the
simulator's block loop) a signal only sets a flag; the loop calls :func:`check` between compiled calls
(once per chunk or block), which raises :class:`Interrupted`.  Outside such a region the handler raises
:class:`Interrupted` at once, like Ctrl-C normally does.  ``Interrupted`` derives from BaseException so
that ``except Exception`` blocks do not swallow it; the writers' ``finally`` blocks remove their
temporary files on the way out, and the CLI prints one line and exits with 128 + the signal number
(130 for SIGINT, 143 for SIGTERM).
"""
from __future__ import annotations

import contextlib
import signal

_SIGNALS = tuple(s for s in (getattr(signal, "SIGINT", None), getattr(signal, "SIGTERM", None))
                 if s is not None)
_state = {"signum": None, "depth": 0, "installed": False}


class Interrupted(BaseException):
    """The process received SIGINT or SIGTERM; ``signum`` says which."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(signum)

    @property
    def name(self) -> str:
        """Name of the signal (``SIGINT``, ``SIGTERM``), or ``signal <n>`` for an unknown number."""
        try:
            return signal.Signals(self.signum).name
        except ValueError:
            return f"signal {self.signum}"

    @property
    def exit_code(self) -> int:
        """Process exit code for the signal: 128 + its number (130 for SIGINT, 143 for SIGTERM)."""
        return 128 + self.signum


def _handler(signum, frame):
    if _state["signum"] is None:
        _state["signum"] = signum
    if _state["depth"] == 0:
        raise Interrupted(signum)


def install():
    """Install the SIGINT/SIGTERM handlers (main thread only; a no-op elsewhere).  Also ignore SIGXFSZ,
    so that exceeding the file-size limit makes the write fail with EFBIG (a clean error) instead of
    killing the process with a core dump."""
    try:
        for s in _SIGNALS:
            signal.signal(s, _handler)
        if hasattr(signal, "SIGXFSZ"):
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        _state["installed"] = True
    except ValueError:           # not the main thread
        pass


def pending() -> int | None:
    """The number of the signal received, or None."""
    return _state["signum"]


def check():
    """Raise :class:`Interrupted` if a signal arrived (call between compiled calls)."""
    if _state["signum"] is not None:
        raise Interrupted(_state["signum"])


def reset():
    """Forget a received signal (tests)."""
    _state["signum"] = None


@contextlib.contextmanager
def deferred():
    """Within this block a signal only sets the flag; :func:`check` raises it at a safe point."""
    _state["depth"] += 1
    try:
        yield
    finally:
        _state["depth"] -= 1
    check()
