"""Shared GNSS knowledge, independent of the receiver stages: signals and codes (``signals``, ``signals_bds``,
``registry``), geodesy, broadcast ephemeris and satellite state, atmosphere models, LNAV encode/decode and
RINEX navigation files.  Imports nothing above :mod:`receiver.errors` / :mod:`receiver.config`."""
