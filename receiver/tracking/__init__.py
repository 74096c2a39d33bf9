"""Tracking: scalar channels (numba kernel), pluggable carrier loops, vector loops."""
