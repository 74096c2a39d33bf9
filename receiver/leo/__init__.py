"""LEO (Iridium-like) Doppler positioning: constellation, measurement model, filters and solvers.

Modules: ``constellation`` (TLE, SGP4, TEME -> Earth-fixed), ``doppler`` (model, simulator, HDF5),
``filters`` (generic KF / EKF / CKF / square-root CKF), ``geosot`` (GeoSOT grid codes and the
grid-search initial value), ``solvers`` (LSM / EKF / CKF / SR-CKF drivers), ``config`` (schemas) and
``cli`` (the ``gnssrx leo`` command group).
"""
