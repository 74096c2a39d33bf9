"""Navigation stage: LNAV bits and frame sync, observables, PVT (WLS, EKF/CKF) and the engine that runs them
per navigation epoch (``engine.py``).  The GNSS knowledge it uses (ephemeris, LNAV, atmosphere, RINEX,
geodesy) lives in :mod:`receiver.gnss`."""
