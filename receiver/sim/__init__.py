"""Truth-tagged IF simulator of GPS L1 C/A, QZSS, BeiDou B1I and Galileo E1 signals (``gnssrx simulate
scenario.yaml``).

Entry point: :func:`receiver.sim.simulate.simulate`.  Modules: scenario (schema, loading),
constellation / bds_constellation / gal_constellation (RINEX or the embedded nominal constellations ->
Ephemeris), sources (the scenario's signals and satellites, navigation data, C/N0, scintillation streams),
geometry (orbits, light time, atmosphere, elevation), trajectory, clock (bias, drift, Allan-variance noise),
scintillation (Cornell model), blockage, impairments (front-end), kernel (numba IF generation), simulate
(time base and streaming block synthesis), outputs (output names, truth writer, receiver-input fragment,
SigMF, tag), corrsim (correlator-level simulation), cli (click commands ``simulate`` and ``eval``).
"""
