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

from ...gnss.clock import OSCILLATORS, h0_h2
from ...gnss.geodesy import ecef2lla, enu_matrix
from ...gnss.signals import C_LIGHT
from .kalman import FORM_NONE

#: oscillator classes, (h0, h_-2) of the fractional-frequency PSD (receiver.gnss.clock)
CLOCK_CLASSES = {k: h0_h2(k) for k in OSCILLATORS}


def clock_psd(clock_class: str):
    """(S_b m^2/s, S_d m^2/s^3): white bias and drift noise PSDs of a two-state clock model."""
    h0, h2 = CLOCK_CLASSES[clock_class]
    return 0.5 * h0 * C_LIGHT ** 2, 2.0 * np.pi ** 2 * h2 * C_LIGHT ** 2


class VectorFilter:
    """Base class of the vector-loop filters (see the module docstring)."""
    name = "base"
    version: str | None = None      # a plugin's (None: its distribution's version)
    selectable_motion = False       # True: vector.motion_model chooses the kinematic model
    #: a plugin's own config keys (receiver.config.P), mounted at vector.<name> and given as self.params
    PARAMS: dict = {}

    def __init__(self, vcfg, T: float):
        self.vcfg = vcfg
        self.params = vcfg[self.name] if self.PARAMS else None
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
        self._r0 = None                     # set by initial(): position at handover

    # --------------------------------------------------------------------- to implement
    @property
    def n(self) -> int:
        """Number of states (a variant implements it)."""
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
        """The filter as text for the vector handover log message (base: its name)."""
        return self.name


class KinematicFilter(VectorFilter):
    """[r, v, (a,) b, d (, delta)] error-state EKF with a kinematic transition (fixed_r, adaptive_r, cv).

    Error-state / total-state: the loop feeds the NCOs from the prediction, so the innovations are the
    papers' E_code = t_b + (X - X_hat)^T a_j and E_carr = dt_d + (V - V_hat)^T a_j; the filter keeps the
    total state (the error state is reset into it after every update), which is the same filter.

    ``vector.motion_model``: ``cv`` is the papers' constant-velocity model (8 states; white acceleration
    of PSD ``vector.q_accel``); ``ca`` adds an acceleration state per axis (11 states; white jerk of PSD
    ``vector.q_jerk``), which carries a turning vehicle through periods where fewer satellites than
    velocity unknowns carry a signal.  ``vector.q_vertical_scale`` scales the PSD on the local vertical
    (1 = isotropic; a land vehicle's vertical dynamics are far smaller than its horizontal ones).
    """
    motion = None           # class override (cv: always constant velocity)

    @property
    def selectable_motion(self) -> bool:
        """True when ``vector.motion_model`` chooses the model (the class fixes none)."""
        return self.motion is None

    @property
    def model(self) -> str:
        """The kinematic model: ``cv`` or ``ca``."""
        return self.motion or str(self.vcfg.motion_model)

    @property
    def nk(self) -> int:
        """number of kinematic states (6 or 9)."""
        return 9 if self.model == "ca" else 6

    @property
    def n(self) -> int:
        """Number of states: the kinematic ones, b, d and (with code_carrier_drift) delta."""
        return self.nk + (3 if self.has_delta else 2)

    def layout(self):
        """int64 [ip, iv, ib, id, idel] (idel -1 without the code-minus-carrier drift state)."""
        k = self.nk
        return np.array([0, 3, k, k + 1, k + 2 if self.has_delta else -1], np.int64)

    def transition(self):
        """State transition F over one epoch of T seconds (kinematic model and two-state clock)."""
        T, n, k = self.T, self.n, self.nk
        F = np.eye(n)
        F[0:3, 3:6] = T * np.eye(3)
        if self.model == "ca":
            F[0:3, 6:9] = 0.5 * T * T * np.eye(3)
            F[3:6, 6:9] = T * np.eye(3)
        F[k, k + 1] = T
        if self.has_delta:
            F[k, k + 2] = T
        return F

    def kinematic_psd_ecef(self):
        """3x3 PSD of the white acceleration (cv, m^2/s^3) or jerk (ca, m^2/s^5) in ECEF.

        Isotropic, except that ``vector.q_vertical_scale`` multiplies it on the local vertical at the
        handover position.
        """
        q = float(self.vcfg.q_jerk if self.model == "ca" else self.vcfg.q_accel)
        scale = float(self.vcfg.q_vertical_scale)
        if scale == 1.0 or self._r0 is None:
            return q * np.eye(3)
        lat, lon, _ = ecef2lla(np.asarray(self._r0, float))
        E = enu_matrix(float(lat), float(lon))          # rows: E, N, U in ECEF
        return E.T @ np.diag([q, q, q * scale]) @ E

    def q_text(self) -> str:
        """The process-noise settings as text (PSD in m^2/s^3 or m^2/s^5, vertical scale)."""
        if self.model == "ca":
            txt = f"constant acceleration, q_jerk {self.vcfg.q_jerk:g} m^2/s^5"
        else:
            txt = f"q_accel {self.vcfg.q_accel:g} m^2/s^3"
        sc = float(self.vcfg.q_vertical_scale)
        return txt + ("" if sc == 1.0 else f" (x{sc:g} vertical)")

    def process_noise(self):
        """Q of the kinematic model (kinematic_psd_ecef) and of the oscillator class (two-state clock)."""
        T, n, k = self.T, self.n, self.nk
        S = self.kinematic_psd_ecef()
        sb, sd = clock_psd(self.vcfg.clock_class)
        Q = np.zeros((n, n))
        if self.model == "ca":          # white jerk: integrated three times
            c = np.array([[T ** 5 / 20.0, T ** 4 / 8.0, T ** 3 / 6.0],
                          [T ** 4 / 8.0, T ** 3 / 3.0, T ** 2 / 2.0],
                          [T ** 3 / 6.0, T ** 2 / 2.0, T]])
        else:                           # white acceleration: integrated twice
            c = np.array([[T ** 3 / 3.0, T ** 2 / 2.0], [T ** 2 / 2.0, T]])
        for i in range(c.shape[0]):
            for j in range(c.shape[0]):
                Q[3 * i:3 * i + 3, 3 * j:3 * j + 3] = c[i, j] * S
        Q[k, k] = sb * T + sd * T ** 3 / 3.0
        Q[k, k + 1] = Q[k + 1, k] = sd * T ** 2 / 2.0
        Q[k + 1, k + 1] = sd * T
        if self.has_delta:
            Q[k + 2, k + 2] = float(self.vcfg.q_code_carrier_drift) * T
        return Q

    def matrices(self):
        """(F, Q, QB) for one epoch of T seconds; no manoeuvre noise (QB zero)."""
        return self.transition(), self.process_noise(), np.zeros((self.n, self.n))

    def initial(self, r, v, b, d, delta, sig):
        """(x0, P0) from the navigation solution at the handover (r m ECEF, v m/s, b m, d m/s, delta m/s);
        sig: dict of standard deviations pos, vel, b, d, delta.  Sets the position of the local vertical."""
        self._r0 = np.array(r, float)       # the local level of the process noise (handover position)
        n, k = self.n, self.nk
        x = np.zeros(n)
        x[0:3], x[3:6], x[k], x[k + 1] = r, v, b, d
        sd = [sig["pos"]] * 3 + [sig["vel"]] * 3
        if self.model == "ca":
            sd += [float(self.vcfg.init_sigma_acc_mps2)] * 3      # acceleration starts at zero
        sd += [sig["b"], sig["d"]]
        if self.has_delta:
            x[k + 2] = delta
            sd.append(sig["delta"])
        return x, np.diag(np.square(sd))
