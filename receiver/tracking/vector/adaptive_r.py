"""adaptive_r: the VLL of fixed_r with each diagonal element of R re-estimated every epoch.

Per channel and measurement type, over the last N = ``vector.adaptive_r.window`` epochs
(``vector.adaptive_r.form``):
  paper       R_k = (1/N) sum v_j^2 + h P(k|k) h^T     (innovations v; the adaptive-VLL paper's printed form)
  innovation  R_k = (1/N) sum v_j^2 - h P(k|k-1) h^T   (textbook innovation-based estimate)
  residual    R_k = (1/N) sum r_j^2 + h P(k|k) h^T     (post-fit residuals r; textbook residual-based)
floored at ``floor_code_m2`` / ``floor_carrier_m2s2``.  The estimate made after epoch k is used at epoch
k+1; a new channel starts from the fixed R until its window holds min(N, 100) samples.  A blocked or weak
channel's discriminators are noise, its R grows and its weight in the navigation filter falls.
"""
from __future__ import annotations

from .fixed_r import FixedR
from .kalman import FORMS


class AdaptiveR(FixedR):
    """The fixed_r VLL (``adaptive_r``) with each diagonal element of R re-estimated every epoch from the last
    ``vector.adaptive_r.window`` innovations or residuals (see the module docstring)."""
    name = "adaptive_r"

    def __init__(self, vcfg, T):
        super().__init__(vcfg, T)
        self.adaptive_form = FORMS[vcfg.adaptive_r.form]

    def describe(self):
        """One line for the log: the adaptive-R form and window, Q and the oscillator class."""
        return (f"adaptive_r VLL: {self.vcfg.adaptive_r.form} form, window {self.window}, "
                f"{self.q_text()}, clock {self.vcfg.clock_class}")
