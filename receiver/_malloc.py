"""The C allocator's side of a flat resident memory on long runs (glibc only).

With its defaults glibc's malloc keeps memory a long run no longer uses:

- the size above which an allocation is a memory mapping of its own (handed back to the kernel when
  freed) rises after each large free, up to 32 MB; the chunk-sized numpy arrays of the chunk loop
  (8-16 MB) then come from the heap, and freed heap memory below a live block stays resident;
- every thread that contends for the heap may get an arena of its own (up to 8 per core), each keeping
  its own free memory; the tracking pool, the read-ahead thread and the writer's compression all
  allocate and free such arrays.

:func:`configure` limits the arenas to :data:`ARENA_MAX`; :func:`trim` (``malloc_trim``) hands the free pages
of every arena back to the kernel, and the pipeline calls it every :data:`TRIM_EVERY_S` seconds of signal.
A fixed mapping threshold instead (every large array mapped afresh) holds less memory but costs ~20 % more
CPU in page faults (measured side by side, docs/benchmarks.md#memory); trimming every 2 s costs no
measurable CPU.  Where the allocator puts an array does not change any number the receiver computes.
Nothing happens on another C library, with ``GNSSRX_MALLOC=default``, or when ``MALLOC_ARENA_MAX`` is set
in the environment (glibc then follows it).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from functools import lru_cache

#: mallopt parameter (glibc's malloc.h)
_M_ARENA_MAX = -8

ARENA_MAX = 2
#: seconds of signal between two :func:`trim` calls of the chunk loop
TRIM_EVERY_S = 2.0


@lru_cache(maxsize=1)
def _libc():
    """glibc (with mallopt and malloc_trim), or None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        lib = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return None
    if not all(hasattr(lib, f) for f in ("mallopt", "malloc_trim", "gnu_get_libc_version")):
        return None                          # not glibc (musl has no such knobs)
    return lib


def enabled() -> bool:
    """False with ``GNSSRX_MALLOC=default`` or without glibc."""
    return os.environ.get("GNSSRX_MALLOC", "").strip().lower() != "default" and _libc() is not None


@lru_cache(maxsize=1)
def configure() -> bool:
    """Limit the arenas, once per process (before the thread pool starts); True when it was done."""
    if not enabled() or "MALLOC_ARENA_MAX" in os.environ:
        return False
    return bool(_libc().mallopt(_M_ARENA_MAX, ARENA_MAX))


def trim() -> bool:
    """Hand the free memory of every arena back to the kernel; True when it was done."""
    if not enabled():
        return False
    _libc().malloc_trim(0)
    return True
