"""fll_pll: a 3rd-order PLL assisted by a 2nd-order FLL, as a gnssrx carrier-loop plugin.

Discriminators (per epoch of T seconds, prompt P_k = I_k + j Q_k):
    PLL  e_p = atan(Q_k / I_k) / 2 pi                                   cycles (Costas: data-bit proof)
    FLL  e_f = atan(cross / dot) / (2 pi T),  cross = I_k-1 Q_k - Q_k-1 I_k,  dot = I_k-1 I_k + Q_k-1 Q_k
                                                                         Hz (atan, not atan2: bit-flip proof)
Loop filter (Kaplan & Hegarty, Understanding GPS, 3rd-order PLL with 2nd-order FLL assist; rectangular
integrators, the discriminators of epoch k set the NCO frequency of epoch k+1):
    w_p = pll_bw_hz / 0.7845,  w_f = fll_bw_hz / 0.53
    rate += T (w_p^3 e_p + w_f^2 e_f)
    freq += T (rate + 1.1 w_p^2 e_p + 1.414 w_f e_f)
    f_nco = freq + 2.4 w_p e_p
The FLL term widens the pull-in range of the PLL and keeps it through dynamics a PLL alone would lose; with
fll_bw_hz: 0 it is the plain 3rd-order Costas PLL.

Config (``tracking.carrier.variant: fll_pll``):
    tracking.carrier.fll_pll.pll_bw_hz   PLL noise bandwidth (Hz, default 15)
    tracking.carrier.fll_pll.fll_bw_hz   FLL noise bandwidth (Hz, default 2)
"""
from __future__ import annotations

import math

import numpy as np

from receiver.tracking.loops.plugin import START_SIG, UPDATE_SIG, P, PythonLoop, nco_command, njit

__version__ = "0.1.0"

# state slots of the compiled path: NCO phase / frequency (nco_command), loop integrators, previous prompt
NCO, FREQ, RATE, PREV_I, PREV_Q, HAVE_PREV, N_STATE = 0, 2, 3, 4, 5, 6, 7


@njit(cache=True, nogil=True)
def _fll_error(pi, pq, ip, qp, T):
    dot = pi * ip + pq * qp
    cross = pi * qp - pq * ip
    return math.atan(cross / dot) / (2.0 * math.pi * T) if dot != 0.0 else 0.0


@njit(START_SIG, cache=True, nogil=True)
def start(lp, ls, doppler_hz, T, rate_hz_s, carrier_hz):
    ls[:] = 0.0
    ls[NCO + 1] = doppler_hz
    ls[FREQ] = doppler_hz
    ls[RATE] = rate_hz_s


@njit(UPDATE_SIG, cache=True, nogil=True)
def update(lp, ls, ip, qp, T, p1i, p1q, p2i, p2q):
    ep = math.atan(qp / ip) / (2.0 * math.pi) if ip != 0.0 else 0.0
    ef = _fll_error(ls[PREV_I], ls[PREV_Q], ip, qp, T) if ls[HAVE_PREV] != 0.0 else 0.0
    ls[PREV_I], ls[PREV_Q], ls[HAVE_PREV] = ip, qp, 1.0
    wp = lp[0] / 0.7845
    wf = lp[1] / 0.53
    ls[RATE] += T * (wp * wp * wp * ep + wf * wf * ef)
    ls[FREQ] += T * (ls[RATE] + 1.1 * wp * wp * ep + 1.414 * wf * ef)
    f = ls[FREQ] + 2.4 * wp * ep
    return nco_command(ls, NCO, T, ls[NCO] + ls[NCO + 1] * T, f)


class FllPll(PythonLoop):
    """3rd-order PLL with 2nd-order FLL assist (module docstring)."""
    name = "fll_pll"
    PARAMS = {
        "pll_bw_hz": P(15.0, "float", "PLL noise bandwidth (Hz)", lo=0.1, hi=100.0),
        "fll_bw_hz": P(2.0, "float", "FLL noise bandwidth (Hz; 0: PLL only)", lo=0.0, hi=50.0),
    }

    def __init__(self, cfg):
        super().__init__(cfg)
        self.pll_bw = float(self.params.pll_bw_hz)
        self.fll_bw = float(self.params.fll_bw_hz)

    # reference path (Python, one call per epoch)
    def init(self, doppler_hz, rate_hz_s):
        self.freq, self.rate, self.prev = doppler_hz, rate_hz_s, None

    def step(self, ip, qp, T, p1=None, p2=None):
        ep = math.atan(qp / ip) / (2.0 * math.pi) if ip != 0.0 else 0.0
        ef = 0.0
        if self.prev is not None:
            dot = self.prev[0] * ip + self.prev[1] * qp
            cross = self.prev[0] * qp - self.prev[1] * ip
            ef = math.atan(cross / dot) / (2.0 * math.pi * T) if dot != 0.0 else 0.0
        self.prev = (ip, qp)
        wp, wf = self.pll_bw / 0.7845, self.fll_bw / 0.53
        self.rate += T * (wp * wp * wp * ep + wf * wf * ef)
        self.freq += T * (self.rate + 1.1 * wp * wp * ep + 1.414 * wf * ef)
        return self._command(T, self.nco_phase + self.nco_freq * T, self.freq + 2.4 * wp * ep)

    # compiled path (runs inside the channel's compiled epoch loop)
    def compiled(self):
        return start, update, np.array([self.pll_bw, self.fll_bw]), np.zeros(N_STATE)
