"""Stale numba caches of compiled functions that call compiled functions of other modules.

numba's on-disk cache (``cache=True``) is keyed on the source file of the cached function only: when a
function it calls lives in another module and that module changes, the cached machine code (with the old
callee compiled in) is still loaded.  :func:`refresh` drops the in-tree cache files (``__pycache__/
<module>.*.nbi`` / ``.nbc``) of each module listed in :data:`DEPENDS` that are older than one of the
module's compiled dependencies, so numba compiles it again.  It runs when receiver.tracking is imported,
before any compiled function is loaded.  (Caches outside the source tree, NUMBA_CACHE_DIR or the user-wide
fallback for a read-only install, are not checked: an install does not change its sources.)
"""
from __future__ import annotations

import glob
import os

_HERE = os.path.dirname(os.path.abspath(__file__))

#: module (path relative to receiver/tracking) -> the modules whose compiled functions it calls (directly or
#: through another listed module: the cached machine code holds every callee)
DEPENDS = {
    "kernel.py": ["correlator.py"],
    "loops/compiled.py": ["kernel.py", "correlator.py", "loops/ekf.py", "loops/kfpll.py"],
    "loops/runner.py": ["kernel.py", "correlator.py"],     # the loops' own functions: called by address
    "vector/loop.py": ["kernel.py", "correlator.py", "vector/discriminators.py", "vector/kalman.py"],
    # outside the package: the correlator-level simulator's compiled driver calls the loops' compiled twins
    "../evaluate/corrloop.py": ["loops/compiled.py", "loops/ekf.py", "loops/kfpll.py", "kernel.py",
                                "correlator.py"],
}


def refresh() -> list[str]:
    """Remove stale cache files; returns the removed paths."""
    removed = []
    for mod, deps in DEPENDS.items():
        try:
            newest = max(os.stat(os.path.join(_HERE, d)).st_mtime_ns for d in deps)
        except OSError:
            continue
        path = os.path.join(_HERE, mod)
        stem = os.path.splitext(os.path.basename(path))[0]
        cache = os.path.join(os.path.dirname(path), "__pycache__")
        stale = [f for f in glob.glob(os.path.join(cache, f"{stem}.*.nbi")) if os.stat(f).st_mtime_ns < newest]
        for idx in stale:
            for f in [idx] + glob.glob(idx[:-len(".nbi")].rsplit(".", 1)[0] + ".*.nbc"):
                try:
                    os.remove(f)
                    removed.append(f)
                except OSError:          # another process removed it, or a read-only tree
                    pass
    return removed
