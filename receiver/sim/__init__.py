"""Truth-tagged IF simulator of GPS L1 C/A, QZSS and BeiDou B1I signals (``gnssrx simulate scenario.yaml``).

Entry point: :func:`receiver.sim.simulate.simulate`.  Modules: scenario (schema, loading),
constellation (RINEX or the embedded nominal constellation -> Ephemeris), trajectory, clock (bias, drift,
Allan-variance noise), scintillation (Cornell model), kernel (numba IF generation), simulate (streaming
generator and truth writer), cli (click commands ``simulate`` and ``eval``).
"""
