"""The built-in cpll_atan loop written again as a plugin, through the public interface only
(receiver.tracking.loops.plugin): a reference path and a compiled path (tests/unit/tracking/test_plugins.py
checks that a run with it is bit for bit the run with the built-in)."""
import math

import numpy as np

from receiver.tracking.loops.plugin import START_SIG, UPDATE_SIG, P, PythonLoop, nco_command, njit

# ls slots: NCO phase / frequency (nco_command), loop frequency and rate integrators
NCO, FREQ, RATE = 0, 2, 3


@njit(START_SIG, cache=True, nogil=True)
def start(lp, ls, doppler_hz, T, rate_hz_s, carrier_hz):
    ls[:] = 0.0
    ls[NCO + 1] = doppler_hz
    ls[FREQ] = doppler_hz
    ls[RATE] = rate_hz_s if int(lp[1]) == 3 else 0.0


@njit(UPDATE_SIG, cache=True, nogil=True)
def update(lp, ls, ip, qp, T, p1i, p1q, p2i, p2q):
    e = math.atan(qp / ip) / (2.0 * math.pi) if ip != 0.0 else 0.0
    bn = lp[0]
    if int(lp[1]) == 3:
        w0 = bn / 0.7845
        ls[RATE] += T * w0 ** 3 * e
        ls[FREQ] += T * (ls[RATE] + 1.1 * w0 * w0 * e)
        f = ls[FREQ] + 2.4 * w0 * e
    else:
        w0 = bn / 0.53
        ls[FREQ] += T * w0 * w0 * e
        f = ls[FREQ] + 1.414 * w0 * e
    return nco_command(ls, NCO, T, ls[NCO] + ls[NCO + 1] * T, f)


class CpllAgain(PythonLoop):
    """ATAN Costas PLL, 2nd/3rd order (receiver/tracking/loops/cpll.py), as a plugin."""
    name = "cpll_again"
    version = "1.0"
    PARAMS = {
        "bn_hz": P(15.0, "float", "loop noise bandwidth", lo=0.1),
        "order": P(3, "int", "loop order", choices=(2, 3)),
    }

    def __init__(self, cfg):
        super().__init__(cfg)
        self.bn, self.order = float(self.params.bn_hz), int(self.params.order)

    def init(self, doppler_hz, rate_hz_s):
        self.freq = doppler_hz
        self.rate = rate_hz_s if self.order == 3 else 0.0

    def step(self, ip, qp, T, p1=None, p2=None):
        e = math.atan(qp / ip) / (2.0 * math.pi) if ip != 0.0 else 0.0
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

    def compiled(self):
        return start, update, np.array([self.bn, self.order], float), np.zeros(4)


class NoUpdate(PythonLoop):
    """Broken on purpose: no step."""
    name = "no_update"

    def init(self, doppler_hz, rate_hz_s):
        pass


class BadParam(CpllAgain):
    """Broken on purpose: a parameter whose default is out of its own range."""
    name = "bad_param"
    PARAMS = {"bn_hz": P(-1.0, "float", "loop noise bandwidth", lo=0.1)}
