"""numba's first use without its BLAS probe importing scipy.linalg.

The first compiled function a process loads from numba's cache makes numba initialise its target context,
which imports ``numba.np.arraymath``; that module's import-time check for a BLAS (``_check_blas``) imports
``scipy.linalg`` (~0.25 s CPU at start-up; the receiver needs it only for larger triangular solves in the
navigation filters, imported there when used).  The check only decides how numba *compiles* ``np.dot``
and friends, and scipy (a dependency of gnssrx) provides the BLAS, so :func:`prepare` imports
``numba.np.arraymath`` once with the probe answering "available" without the import.  numba's own BLAS
paths (compiling a ``np.dot``, calling it) keep their checks and import scipy.linalg when they run.
Nothing happens when arraymath is already imported or numba's layout differs.
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
