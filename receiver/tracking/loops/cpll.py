"""cpll_atan: conventional Costas PLL with the ATAN discriminator and a 2nd/3rd-order loop filter.

Discriminator e = atan(Q/I) / (2 pi) (cycles, insensitive to data bits).  Loop filter (rectangular
integrators, the discriminator of epoch k sets the NCO frequency of epoch k+1), omega0 = Bn / 0.7845
(3rd order) or Bn / 0.53 (2nd order), with the usual coefficients (a3 = 1.1, b3 = 2.4; a2 = 1.414):

    3rd: rate += T w0^3 e;  freq += T (rate + 1.1 w0^2 e);  f_nco = freq + 2.4 w0 e
    2nd: freq += T w0^2 e;  f_nco = freq + 1.414 w0 e

Defaults (tracking.carrier.bn_hz, order): 15 Hz, 3rd order.  The NCO takes the frequency only.
"""
from __future__ import annotations

import math

from .common import PythonLoop


class CPLL(PythonLoop):
    """Costas PLL (``cpll_atan``) with the ATAN discriminator and a 2nd- or 3rd-order loop filter of noise
    bandwidth ``bn_hz`` (Hz); the arguments override ``tracking.carrier``."""
    name = "cpll_atan"

    def __init__(self, cfg, bn_hz=None, order=None):
        super().__init__(cfg)
        self.bn = float(bn_hz if bn_hz is not None else self.car.bn_hz)
        self.order = int(order if order is not None else self.car.order)

    def init(self, doppler_hz, rate_hz_s):
        """Set the loop filter's frequency (Hz) and, for the 3rd order, its rate (Hz/s) at handover."""
        self.freq = doppler_hz
        self.rate = rate_hz_s if self.order == 3 else 0.0
        self.last_err = 0.0

    def step(self, ip, qp, T, p1=None, p2=None):
        """One epoch: ATAN phase error (cycles) through the loop filter; returns (frequency for the next epoch Hz,
        phase step cycles), the phase continuing the NCO (no phase step)."""
        e = math.atan(qp / ip) / (2.0 * math.pi) if ip != 0.0 else 0.0
        self.last_err = e
        if self.order == 3:
            w0 = self.bn / 0.7845
            self.rate += T * w0 ** 3 * e
            self.freq += T * (self.rate + 1.1 * w0 * w0 * e)
            f = self.freq + 2.4 * w0 * e
        else:
            w0 = self.bn / 0.53
            self.freq += T * w0 * w0 * e
            f = self.freq + 1.414 * w0 * e
        return self._command(T, self.nco_phase + self.nco_freq * T, f)
