"""Vector-filter plugins for tests/unit/tracking/test_plugins.py: fixed_r with its R scaled by a parameter
of its own, and one missing its model."""
from receiver.config import P
from receiver.tracking.vector.base import VectorFilter
from receiver.tracking.vector.fixed_r import FixedR


class ScaledR(FixedR):
    name = "scaled_r"
    version = "2.0"
    PARAMS = {"r_scale": P(1.0, "float", "factor on both discriminator variances", lo=1e-3, hi=1e3)}

    def __init__(self, vcfg, T):
        super().__init__(vcfg, T)
        self.r_code *= self.params.r_scale
        self.r_carr *= self.params.r_scale


class NoModel(VectorFilter):
    name = "no_model"
