"""numba's first use without its BLAS probe importing scipy.linalg.

The first compiled function a process loads from numba's cache makes numba initialise its target context,
which imports ``numba.np.arraymath``; that module's import-time check for a BLAS (``_check_blas``) imports
``scipy.linalg`` (~0.25 s CPU at start-up; the receiver needs it only for larger triangular solves in the
navigation filters, imported there when used).  The check only decides how numba *compiles* ``np.dot``
and friends, and scipy (a dependency of gnssrx) provides the BLAS, so :func:`prepare` imports
``numba.np.arraymath`` once with the probe answering "available" without the import.  numba's own BLAS
paths (compiling a ``np.dot``, calling it) keep their checks and import scipy.linalg when they run.
Nothing happens when arraymath is already imported or numba's layout differs.

:func:`tolerate_cache_write_errors`: numba writes a function's compiled code to its cache after compiling
it, and an ``OSError`` there (a full disk, a file-size limit, a read-only install) would end the run with a
traceback although the compiled function is ready to use; the run goes on uncached instead.
"""
from __future__ import annotations

import sys


def prepare() -> bool:
    """Import numba.np.arraymath with the BLAS probe skipped; True when it was done."""
    if "numba.np.arraymath" in sys.modules:
        return False
    try:
        import numba.np.linalg as nl
    except ImportError:                          # pragma: no cover - numba's layout changed
        return False
    probe = getattr(nl, "ensure_blas", None)
    if probe is None:                            # pragma: no cover
        return False
    nl.ensure_blas = lambda: None
    try:
        import numba.np.arraymath as am
        if getattr(am, "ensure_blas", None) is not probe:
            am.ensure_blas = probe               # (bound by name at its import)
    finally:
        nl.ensure_blas = probe
    return True


def tolerate_cache_write_errors() -> bool:
    """Make numba's cache writes ignore OSError (the function then runs uncached); True when installed."""
    try:
        from numba.core import caching
    except ImportError:                          # pragma: no cover - numba's layout changed
        return False
    orig = getattr(caching.Cache, "save_overload", None)
    if orig is None or getattr(orig, "_gnssrx_tolerant", False):
        return False

    def save_overload(self, sig, data):
        try:
            orig(self, sig, data)
        except OSError:
            pass
    save_overload._gnssrx_tolerant = True
    caching.Cache.save_overload = save_overload
    return True
