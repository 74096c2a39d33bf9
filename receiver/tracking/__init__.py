"""Tracking: scalar channels (numba kernel), pluggable carrier loops, vector loops."""


def refresh_compiled_caches() -> list:
    """Drop stale numba cache files of compiled functions whose compiled callees changed in a source tree
    (see receiver/tracking/_jitcache.py); the command line and the test suite call it before any compiled
    function loads.  Returns the removed paths."""
    from ._jitcache import refresh
    return refresh()
