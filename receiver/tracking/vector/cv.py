"""cv: the constant-velocity VDFLL baseline of the polynomial-VDFLL paper.

Same state and transition as fixed_r, but Q is the paper's per-epoch diagonal: sigma_p^2 on each position
axis (``vector.cv.q_position``, 0.1 m^2), sigma_v^2 on each velocity axis (``vector.cv.q_velocity``; the
paper sweeps 10, 0.1, 1e-3, 1e-5 (m/s)^2), sigma_b^2 on the clock bias (1e-7 m^2) and sigma_d^2 on the
drift (0.1 (m/s)^2); R fixed (``vector.r_code_m2``, ``vector.r_carrier_m2s2``).  The values are read as
per-epoch variances (Q = diag(q), as listed in the paper); ``vector.cv.psd: true`` reads them as continuous
PSDs instead (Q = q T), the other possible reading of the paper - with T = 1 ms the two differ by 1000.
"""
from __future__ import annotations

import numpy as np

from .base import KinematicFilter


class CV(KinematicFilter):
    """Constant-velocity VDFLL baseline (``cv``): the fixed_r state and transition with the paper's diagonal Q
    (see the module docstring)."""
    name = "cv"
    motion = "cv"

    def process_noise(self):
        """Diagonal Q of position (m^2), velocity ((m/s)^2), clock bias and drift (+ delta), per epoch (times T when
        ``vector.cv.psd``)."""
        c = self.vcfg.cv
        q = [c.q_position] * 3 + [c.q_velocity] * 3 + [c.q_bias, c.q_drift]
        if c.psd:
            q = [v * self.T for v in q]
        if self.has_delta:
            q.append(float(self.vcfg.q_code_carrier_drift) * self.T)
        return np.diag(np.asarray(q, dtype=float))

    def describe(self):
        """One line for the log: the velocity variance and the R model."""
        r = ", R from each channel's C/N0" if self.vcfg.r_model == "cn0" else ""
        return f"cv VDFLL: sigma_v^2 {self.vcfg.cv.q_velocity:g} (m/s)^2 per epoch{r}"
