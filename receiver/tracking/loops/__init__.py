"""Python carrier loops (registered in receiver.tracking.carrier): CPLL, KF-PLL, adaptive KF-PLL, EKF, PLI-EKF.

Each loop module imports only ``base`` and ``common`` from here; the registry imports the loop modules.
"""
