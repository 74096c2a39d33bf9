"""Tracking: scalar channels (numba kernel), pluggable carrier loops, vector loops."""
from ._jitcache import refresh as _refresh_jit_cache

_refresh_jit_cache()        # numba caches of functions whose compiled callees changed (see _jitcache.py)
