"""fixed_r: vector lock loop (VLL) as an error-state EKF with a fixed measurement noise R.

State [x, y, z, vx, vy, vz, t_b, dt_d] (+ the optional code-minus-carrier drift), constant-velocity
transition, Q from the white-acceleration PSD ``vector.q_accel`` and the oscillator class
``vector.clock_class``; R fixed: ``vector.r_code_m2`` (paper default 1500 m^2) on every code
discriminator and ``vector.r_carrier_m2s2`` (900 (m/s)^2) on every frequency discriminator, whatever the
channel's signal strength.
"""
from __future__ import annotations

from .base import KinematicFilter


class FixedR(KinematicFilter):
    """Error-state EKF VLL (``fixed_r``) with a fixed R, or R from each channel's C/N0 with ``vector.r_model: cn0``
    (see the module docstring)."""
    name = "fixed_r"

    def describe(self):
        """One line for the log: the R model, Q and the oscillator class."""
        r = ("R from each channel's C/N0" if self.vcfg.r_model == "cn0" else
             f"R code {self.r_code:g} m^2, carrier {self.r_carr:g} (m/s)^2")
        return (f"fixed_r VLL: {r}, "
                f"{self.q_text()}, clock {self.vcfg.clock_class}")
