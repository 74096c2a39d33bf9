"""Python carrier loops (see receiver.tracking.carrier): CPLL, KF-PLL, adaptive KF-PLL, EKF, PLI-EKF."""
from .. import carrier as _carrier  # noqa: F401  (defines CarrierLoop before the loop modules load)
