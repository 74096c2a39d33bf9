"""Vector-loop filter interface: what a variant must provide to the common tracker.

A variant is a small class that defines the navigation filter of the loop - state layout, transition F,
process noise Q, manoeuvre noise QB, initial state/covariance and the options of the shared compiled
update (adaptive-R form and window, chi-square manoeuvre threshold).  The measurement model, the
discriminators, the NCO feedback and the channel handling are common (tracker.py, loop.py, kalman.py).

State conventions (metres and seconds): r receiver position (ECEF), v velocity, b receiver clock bias
as seen by the code (c times the clock error), d carrier clock drift (m/s), delta = code drift - carrier
drift (m/s; optional state, see ``vector.code_carrier_drift``): db/dt = d + delta.  For a front end whose
oscillator drives both the sample clock and the local oscillator delta is zero; a recording whose
oscillator error was applied to the carrier only (the third-party test file) has delta = -d.
"""
from __future__ import annotations

import numpy as np

from ...signals import C_LIGHT
from .kalman import FORM_NONE

#: oscillator classes, (h0, h_-2) of the fractional-frequency PSD (textbook values)
CLOCK_CLASSES = {
    "tcxo": (2e-19, 2e-20),
    "ocxo": (8e-20, 4e-23),
    "rubidium": (2e-20, 4e-29),
}


def clock_psd(clock_class: str):
    """(S_b m^2/s, S_d m^2/s^3): white bias and drift noise PSDs of a two-state clock model."""
    h0, h2 = CLOCK_CLASSES[clock_class]
    return 0.5 * h0 * C_LIGHT ** 2, 2.0 * np.pi ** 2 * h2 * C_LIGHT ** 2


class VectorFilter:
    """Base class of the vector-loop filters (see the module docstring)."""
    name = "base"

    def __init__(self, vcfg, T: float):
        self.vcfg = vcfg
        self.T = float(T)
        self.has_delta = bool(vcfg.code_carrier_drift)
        self.r_code = float(vcfg.r_code_m2)
        self.r_carr = float(vcfg.r_carrier_m2s2)
        # options of the shared update (variants override)
        self.adaptive_form = FORM_NONE
        self.window = int(vcfg.adaptive_r.window)
        self.floor_code = float(vcfg.adaptive_r.floor_code_m2)
        self.floor_carr = float(vcfg.adaptive_r.floor_carrier_m2s2)
        self.chi2_threshold = 0.0

    # --------------------------------------------------------------------- to implement
    @property
    def n(self) -> int:
        raise NotImplementedError

    def layout(self) -> np.ndarray:
        """int64 [ip, iv, ib, id, idel] (idel -1 without the code-minus-carrier drift state)."""
        raise NotImplementedError

    def matrices(self):
        """(F, Q, QB) for one epoch of T seconds."""
        raise NotImplementedError

    def initial(self, r, v, b, d, delta, sig):
        """(x0, P0) from the navigation solution; sig: dict of standard deviations pos, vel, b, d, delta."""
        raise NotImplementedError

    # --------------------------------------------------------------------- common
    def nav_state(self, x):
        """(r, v, b, d, delta) of a state vector."""
        ip, iv, ib, idd, idl = self.layout()
        return (np.array(x[ip:ip + 3]), np.array(x[iv:iv + 3]), float(x[ib]), float(x[idd]),
                float(x[idl]) if idl >= 0 else 0.0)

    def describe(self) -> str:
        return self.name


class KinematicFilter(VectorFilter):
    """[r, v, b, d (, delta)] error-state EKF with a constant-velocity transition (fixed_r, adaptive_r, cv).

    Error-state / total-state: the loop feeds the NCOs from the prediction, so the innovations are the
    papers' E_code = t_b + (X - X_hat)^T a_j and E_carr = dt_d + (V - V_hat)^T a_j; the filter keeps the
    total state (the error state is reset into it after every update), which is the same filter.
    """

    @property
    def n(self) -> int:
        return 9 if self.has_delta else 8

    def layout(self):
        return np.array([0, 3, 6, 7, 8 if self.has_delta else -1], np.int64)

    def transition(self):
        T, n = self.T, self.n
        F = np.eye(n)
        F[0:3, 3:6] = T * np.eye(3)
        F[6, 7] = T
        if self.has_delta:
            F[6, 8] = T
        return F

    def process_noise(self):
        """Q from a white-acceleration model (q_accel) and the oscillator class (two-state clock)."""
        T, n = self.T, self.n
        qa = float(self.vcfg.q_accel)
        sb, sd = clock_psd(self.vcfg.clock_class)
        Q = np.zeros((n, n))
        for a in range(3):
            Q[a, a] = qa * T ** 3 / 3.0
            Q[a, 3 + a] = Q[3 + a, a] = qa * T ** 2 / 2.0
            Q[3 + a, 3 + a] = qa * T
        Q[6, 6] = sb * T + sd * T ** 3 / 3.0
        Q[6, 7] = Q[7, 6] = sd * T ** 2 / 2.0
        Q[7, 7] = sd * T
        if self.has_delta:
            Q[8, 8] = float(self.vcfg.q_code_carrier_drift) * T
        return Q

    def matrices(self):
        return self.transition(), self.process_noise(), np.zeros((self.n, self.n))

    def initial(self, r, v, b, d, delta, sig):
        n = self.n
        x = np.zeros(n)
        x[0:3], x[3:6], x[6], x[7] = r, v, b, d
        sd = [sig["pos"]] * 3 + [sig["vel"]] * 3 + [sig["b"], sig["d"]]
        if self.has_delta:
            x[8] = delta
            sd.append(sig["delta"])
        return x, np.diag(np.square(sd))
