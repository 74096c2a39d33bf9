"""Single-point positioning: iterative weighted least squares on code pseudoranges (GPS, QZSS, BeiDou, Galileo),
velocity and clock drift from Doppler.

Measurement model (all in metres):
    rho_raw = c (rx_tow - tx_tow)                       raw pseudorange
    rho_raw + c dt_sv - I - T = |R(tau) r_sv - x| + b   (dt_sv includes relativity and -TGD)
where r_sv is the satellite position at the true transmit time tx_tow - dt_sv, R(tau) the
Earth-rotation (Sagnac) correction over the travel time tau, I and T the ionospheric and
tropospheric delays and b the receiver clock bias (c times the receiver clock error).

Why this module is long: the solver, its weighting models (per system and signal) and its aiding constraints
are one measurement model and one least-squares iteration; split, each part would reach into the others' state.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ..gnss.geodesy import azel, ecef2lla, enu_matrix
from ..gnss.signals import C_LIGHT, CA_CHIP_RATE, L1_HZ, LAMBDA_L1
from ..gnss.signals_bds import B1I_CHIP_RATE, B1I_HZ
from ..gnss.atmosphere import klobuchar_delay_s, saastamoinen_m
from ..gnss.ephemeris import earth_rotation, sat_state, select
from ..gnss.ephemeris_jit import sat_states
from .config import default
from .wls_jit import WEIGHTING, linearise
from ..gnss.time import normalize_week_tow, wrap_week_seconds


def vnorm(v) -> float:
    """np.linalg.norm of a 1-D vector, the same value (the square root of the same BLAS dot product:
    ``v @ v``), but without releasing the GIL: ndarray.dot releases it around the BLAS call, and on the
    main thread, with the writer / read-ahead / tracking threads running, taking it back waited out the
    interpreter's 5-ms switch interval (~1 ms per call on average, ~1000 calls in a 20-s run)."""
    v = np.asarray(v, dtype=float)
    if v.ndim != 1:
        return float(np.linalg.norm(v))
    return math.sqrt(v @ v)


def _median_small(a) -> float:
    """np.median of a short 1-D array, the same value (the middle element, or the mean (x + y) / 2 of the
    two middle ones), computed on a Python list: np.median's partition releases the GIL (see vnorm)."""
    v = np.asarray(a, dtype=float).ravel().tolist()
    if not v or any(x != x for x in v):           # empty or NaN: numpy's own answer
        return float(np.median(a))
    v.sort()
    m = len(v) // 2
    return v[m] if len(v) % 2 else (v[m - 1] + v[m]) / 2


def _argmax_abs(a) -> int:
    """np.argmax(np.abs(a)) of a short 1-D array (the first largest), without releasing the GIL."""
    v = np.abs(np.asarray(a, dtype=float)).tolist()
    if any(x != x for x in v):
        return int(np.argmax(np.abs(a)))
    return v.index(max(v))


@dataclass
class Observation:
    """One satellite's measurements at a receiver epoch.

    tx_tow: transmit GPS time of week read from the satellite's signal (s), so that the raw
    pseudorange is c (rx_tow - tx_tow).  doppler_hz: measured carrier frequency minus nominal
    (positive when the satellite approaches); NaN when unknown.
    """
    prn: int
    tx_tow: float
    doppler_hz: float = float("nan")
    cn0_dbhz: float = float("nan")
    carrier_phase_cycles: float = float("nan")
    wavelength_m: float = LAMBDA_L1     # carrier wavelength of the signal (Doppler -> range rate)
    system: str = "G"                   # clock group: every system but the first gets an inter-system bias


@dataclass
class Fix:
    """A navigation solution.  Per-satellite arrays follow ``prns`` (satellites used)."""
    gps_week: int
    gps_tow: float                      # true GPS time of the fix: rx_tow - clock_bias_m / c
    ecef: np.ndarray
    velocity_ecef: np.ndarray           # NaN when fewer than 4 Doppler measurements
    clock_bias_m: float
    clock_drift_mps: float
    n_sats: int
    prns: list
    pdop: float
    hdop: float
    vdop: float
    gdop: float
    residuals_m: np.ndarray
    elevations_deg: np.ndarray
    azimuths_deg: np.ndarray
    pseudoranges_m: np.ndarray          # corrected: raw + c dt_sv - iono - tropo
    pseudorange_rates_mps: np.ndarray   # corrected: -doppler * lambda + c ddt_sv
    raw_pseudoranges_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    iono_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tropo_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    velocity_residuals_mps: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rejected_prns: list = field(default_factory=list)   # dropped by the residual check
    # satellite states at transmit time, rotated into the ECEF frame at reception (the geometry of the
    # fix: pseudoranges_m ~ |sat_pos_ecef - ecef| + clock_bias_m, pseudorange_rates_mps ~
    # los . (sat_vel_ecef - velocity_ecef) + clock_drift_mps); used by the navigation filters
    sat_pos_ecef: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    sat_vel_ecef: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    rx_tow: float = float("nan")
    iterations: int = 0
    isb_m: dict = field(default_factory=dict)   # system letter -> inter-system clock bias (m) vs clock_bias_m
    aiding: tuple = ()                  # constraints used ("clock", "height"); () for an unaided fix
    var_factors: dict = field(default_factory=dict)   # weighting_per_system vce: system letter -> variance
    #                                   factor used (the first system's 1); {} when the fixed weights were used

    @property
    def lla(self):
        """(lat_deg, lon_deg, h_m)."""
        lat, lon, h = ecef2lla(self.ecef)
        return float(lat), float(lon), float(h)


@dataclass
class Aiding:
    """Constraints for a fix from few satellites or a weak geometry (receiver.navigation.engine builds them from
    the recent unaided fixes): the receiver clock bias (m) and/or the ellipsoidal height (m) predicted at the
    fix's epoch, each with its standard deviation.  They enter the least squares as pseudo-measurement rows
    (clock: b = clock_m; height: up . x = height_m, linearised at each iteration) weighted
    (code_sigma_m / sigma)^2 against a weight-1 satellite, whose pseudorange standard deviation is
    code_sigma_m.  residual_threshold_m: an aided fix whose largest normalised residual (satellites and
    constraints, metres referred to a weight-1 satellite) exceeds this drops that satellite while the fix stays
    over-determined after the drop, and is refused otherwise (a bad range or a wrong constraint)."""
    clock_m: float | None = None
    clock_sigma_m: float = float("inf")
    height_m: float | None = None
    height_sigma_m: float = float("inf")
    code_sigma_m: float = 3.0
    residual_threshold_m: float = 15.0
    drift_mps: float | None = None      # predicted clock drift (velocity of a 3-satellite fix) ...
    drift_sigma_mps: float = 1.0
    rate_sigma_mps: float = 0.1         # ... against a weight-1 pseudorange rate of this standard deviation
    max_pdop: float = float("inf")      # an aided fix whose PDOP (constraints included) exceeds this is refused

    def count(self) -> int:
        """Number of constraints given (clock and/or height): 0, 1 or 2."""
        return int(self.clock_m is not None) + int(self.height_m is not None)

    def kinds(self) -> tuple:
        """Names of the constraints given, from ("clock", "height")."""
        return tuple(k for k, v in (("clock", self.clock_m), ("height", self.height_m)) if v is not None)

    def rows(self, x, b, ncols):
        """(rows of the design matrix, residuals, weights) of the constraints at position x, clock b."""
        hs, rs, ws = [], [], []
        if self.clock_m is not None:
            row = np.zeros(ncols)
            row[3] = 1.0
            hs.append(row)
            rs.append(self.clock_m - b)
            ws.append((self.code_sigma_m / self.clock_sigma_m) ** 2)
        if self.height_m is not None:
            lat, lon, h = ecef2lla(x)
            row = np.zeros(ncols)
            row[:3] = enu_matrix(lat, lon)[2]
            hs.append(row)
            rs.append(self.height_m - float(h))
            ws.append((self.code_sigma_m / self.height_sigma_m) ** 2)
        return np.array(hs), np.array(rs), np.array(ws)


_ZERO4 = np.zeros(4)

# URA index -> nominal URA (m), IS-GPS-200 20.3.3.3.1.3 (upper bounds; 15: no accuracy prediction)
URA_M = (2.40, 3.40, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0, 96.0, 192.0, 384.0, 768.0, 1536.0, 3072.0,
         6144.0, 6144.0)
#: the accuracy (m) RTKLIB's error model gives a Galileo satellite without an accuracy prediction (NAPA)
SISA_NAPA_M = 500.0


def broadcast_accuracy_m(eph) -> float:
    """The broadcast range accuracy (m) of an ephemeris, the URA term of RTKLIB's error model (weighting
    rtklib): a Galileo SISA index through the ICD's SISA table (NAPA and spare indices: SISA_NAPA_M), a GPS /
    QZSS / BeiDou URA index through the URA table."""
    if getattr(eph, "system", "G") == "E":
        from ..gnss.rinex_gal import sisa_m_from_index
        m = sisa_m_from_index(eph.ura_index)
        return m if m >= 0.0 else SISA_NAPA_M
    return URA_M[min(max(int(eph.ura_index), 0), 15)]


#: variance of a system's L1-band pseudorange relative to a GPS L1 C/A one at the same C/N0 (the signal's total)
#: and elevation, for the SIGNAL_WEIGHTINGS of a fix mixing systems (docs/multi-gnss.md).  B1I
#: (2.046 Mcps): the code tracking error in metres scales with the chip length (same DLL bandwidth and spacing
#: in chips), (1.023 / 2.046)^2 = 1/4.  Galileo E1 (E1-C pilot, BOC(1,1), 8-Hz DLL, carrier smoothed): 2, a
#: measured value -- over 7 GPS + Galileo recordings of our simulator and both weightings, 2 gave the fewest
#: combined fixes worse than the better system alone (2 of 14; 1: 3, 0.5 and 4: 4) at the same mean error as 1.
#: Other systems (GPS, QZSS): 1.  With navigation.weighting_per_system vce (default) each system's variance is
#: this times the factor estimated from the residuals (NavSolver.vce_factors), once there is enough redundancy.
CODE_VAR_REL_CA = {"C": (CA_CHIP_RATE / B1I_CHIP_RATE) ** 2, "E": 2.0}

#: the weightings that model a range's variance from its signal, elevation and C/N0: a fix mixing signals
#: scales them by CODE_VAR_REL_CA, and weighting_per_system vce applies to them (not to none and rtklib)
SIGNAL_WEIGHTINGS = ("elevation", "cn0", "cn0_elevation")

#: weighting_per_system vce: a system's factor is estimated once its satellites' redundancy numbers summed over
#: the window reach VCE_MIN_REDUNDANCY and average VCE_MIN_MEAN_REDUNDANCY per fix (a system of 1-3 satellites,
#: e.g. QZSS, has almost none left after its own inter-system bias: its residuals say little about its
#: variance, so such fixes keep the fixed weights), and the factors are kept within [1/VCE_MAX_RATIO,
#: VCE_MAX_RATIO] of the first system's
VCE_MIN_REDUNDANCY = 5.0
VCE_MIN_MEAN_REDUNDANCY = 2.0
VCE_MAX_RATIO = 100.0


class _Sats:
    """Arrays of the satellites of one epoch (positions in the transmit-time ECEF frame)."""

    def __init__(self, prn, rho, pos, vel, clk, drift, cn0, doppler, ura_m=None, systems=None):
        sy = list(systems) if systems is not None else ["G"] * len(prn)
        order = sorted(set(sy), key=lambda c: ("GJCE".index(c) if c in "GJCE" else 9, c))
        self.systems = order                                  # order[0]: the reference clock
        self.group = np.array([order.index(c) for c in sy], dtype=int)
        self.ura_m = np.asarray(ura_m if ura_m is not None else np.zeros(len(prn)), float)
        self.prn = np.asarray(prn, dtype=int)
        self.rho = np.asarray(rho, float)
        self.pos = np.asarray(pos, float).reshape(-1, 3)
        self.vel = np.asarray(vel, float).reshape(-1, 3)
        self.clk = np.asarray(clk, float)
        self.drift = np.asarray(drift, float)
        self.cn0 = np.asarray(cn0, float)
        self.doppler = np.asarray(doppler, float)
        # carrier of each satellite's signal (the Klobuchar delay is scaled from the model's reference carrier)
        self.carrier_hz = np.array([B1I_HZ if c == "C" else L1_HZ for c in sy], float)
        # code-noise variance of each satellite's signal relative to L1 C/A at the same C/N0 and elevation
        # (CODE_VAR_REL_CA)
        self.code_var = np.array([CODE_VAR_REL_CA.get(c, 1.0) for c in sy], float)

    def __len__(self):
        return len(self.prn)


class NavSolver:
    """Iterative WLS position/clock and Doppler velocity/drift.

    nav_cfg: the receiver config ``navigation`` section (or any object with the attributes
    elevation_mask_deg, weighting ('elevation'|'cn0'|'none'), troposphere ('saastamoinen'|
    'none'), ionosphere ('klobuchar'|'none'), residual_threshold_m, max_pdop); missing ones default.

    Weights: elevation -> sin^2(el); cn0 -> 10^(cn0/10); none -> 1; all scaled so the largest
    weight is 1.  A fix mixing systems (elevation, cn0) divides them by each signal's code variance
    (CODE_VAR_REL_CA) and, with weighting_per_system 'vce', by its system's variance factor estimated over the
    previous fixes (:meth:`vce_factors`): the solver then keeps state from one fix to the next.
    Residual check: the normalised residual of satellite i is
    sqrt(w_i) r_i / sqrt(1 - h_ii) (h_ii: diagonal of the weighted hat matrix), i.e. a metre
    value referred to a weight-1 satellite; while more than 5 satellites are used and the
    largest exceeds residual_threshold_m, that satellite is dropped and the fix recomputed.
    Iono (Klobuchar, needs ``iono_utc``) and tropo corrections and the elevation mask are
    applied once a position is known (after a first uncorrected solution from the Earth's
    centre, or from ``x0``).
    """

    MAX_ITER = 20
    CONVERGED_M = 1e-4

    def __init__(self, nav_cfg=None):
        g = lambda name: getattr(nav_cfg, name, default(name)) if nav_cfg is not None else default(name)  # noqa: E731
        self.elevation_mask_deg = float(g("elevation_mask_deg"))
        self.weighting = str(g("weighting"))
        self.cn0_ref_dbhz = float(g("cn0_ref_dbhz"))
        self.troposphere = str(g("troposphere"))
        self.ionosphere = str(g("ionosphere"))
        self.residual_threshold_m = float(g("residual_threshold_m"))
        self.max_pdop = float(g("max_pdop"))
        if self.weighting not in WEIGHTING:
            raise ValueError(f"unknown weighting {self.weighting!r}")
        self.per_system = str(g("weighting_per_system"))
        if self.per_system not in ("fixed", "vce"):
            raise ValueError(f"unknown weighting_per_system {self.per_system!r}")
        self.vce_window_s = float(g("vce_window_s"))
        # weighting_per_system vce: (time s, {system: (sum of w r^2 over the fix's variance of unit weight, sum of
        # redundancy numbers)}) of the recent unaided fixes mixing systems (w: the satellite's weight without the
        # factor, not normalised to a largest 1)
        self._vce_hist = deque()

    # -------------------------------------------------------------------------------------
    # variance component estimation (weighting_per_system vce)
    def _vce_on(self, systems) -> bool:
        return self.per_system == "vce" and self.weighting in SIGNAL_WEIGHTINGS and len(systems) > 1

    def vce_factors(self, systems) -> dict:
        """{system: variance factor} for a fix of ``systems`` (the first one the reference, 1), estimated over
        the window: sum of w r^2 over sum of redundancy numbers per system (the simplified Helmert estimator
        of a variance component, w the satellite's weight without the factor), each fix's w r^2 divided by
        that fix's variance of unit weight (a common scale that may change from fix to fix, e.g. as the
        smoothing of every channel converges; only the ratios are estimated); {} while a system has too
        little redundancy in the window (VCE_MIN_REDUNDANCY, VCE_MIN_MEAN_REDUNDANCY) or VCE is off."""
        if not self._vce_on(systems):
            return {}
        num, den, cnt = {}, {}, {}
        for _, st in self._vce_hist:
            for c, (n, d) in st.items():
                num[c] = num.get(c, 0.0) + n
                den[c] = den.get(c, 0.0) + d
                cnt[c] = cnt.get(c, 0) + 1
        if any(den.get(c, 0.0) < max(VCE_MIN_REDUNDANCY, VCE_MIN_MEAN_REDUNDANCY * cnt.get(c, 0))
               for c in systems):
            return {}
        var = {c: num[c] / den[c] for c in systems}
        ref = var[systems[0]]
        if not (ref > 0.0 and all(np.isfinite(v) and v > 0.0 for v in var.values())):
            return {}
        return {c: min(max(v / ref, 1.0 / VCE_MAX_RATIO), VCE_MAX_RATIO) for c, v in var.items()}

    def _vce_learn(self, t_s: float, s, sol, base_var):
        """Add an unaided fix's per-system sums (w r^2 over the fix's variance of unit weight, redundancy numbers)
        to the window ending at t_s."""
        idx = sol["idx"]
        el = sol["el"]
        w = self._base_weights(el, s.cn0[idx], sol["iono"], s.ura_m[idx]) / base_var[idx]
        r2 = w * np.square(sol["resid"])
        red = sol["red"]
        # each fix's sums in units of its own variance of unit weight (all systems): the variances of smoothed
        # ranges fall by an order of magnitude over the first seconds of a channel, alike for every system, and
        # unnormalised sums would be the first fixes' alone; the ratios between the systems are what is kept
        total = float(np.sum(r2)) / max(float(np.sum(red)), 1e-9)
        if not total > 0.0 or not np.isfinite(total):
            return
        st = {}
        for g in sorted(set(s.group[idx].tolist())):
            m = s.group[idx] == g
            st[s.systems[g]] = (float(np.sum(r2[m])) / total, float(np.sum(red[m])))
        hist = self._vce_hist
        if hist and t_s < hist[-1][0]:          # time went back (a new run through the same solver): restart
            hist.clear()
        hist.append((t_s, st))
        while hist and hist[0][0] < t_s - self.vce_window_s:
            hist.popleft()

    # -------------------------------------------------------------------------------------
    def _prepare(self, rx_tow, observations, ephemerides, week):
        rows = []
        for ob in observations:
            eph = ephemerides.get(ob.prn) if ephemerides else None
            if isinstance(eph, (list, tuple)):
                eph = select(eph, rx_tow, week)
            if eph is None or eph.health != 0 or not np.isfinite(ob.tx_tow):
                continue
            rows.append((ob, eph))
        if not rows:
            return None
        obs = [r[0] for r in rows]
        ephs = [r[1] for r in rows]
        tx = np.array([o.tx_tow for o in obs], float)
        if any(hasattr(type(e), "state") for e in ephs):      # BeiDou ephemerides among them
            pos, vel, clk, drift = sat_state(ephs, tx)
        else:                                                   # GPS/QZSS LNAV: the compiled path
            pos, vel, clk, drift = sat_states(ephs, tx)
        rho = C_LIGHT * wrap_week_seconds(rx_tow - tx)
        return _Sats([o.prn for o in obs], rho, pos, vel, clk, drift,
                     [o.cn0_dbhz for o in obs], [o.doppler_hz * o.wavelength_m / LAMBDA_L1 for o in obs],
                     ura_m=[broadcast_accuracy_m(e) for e in ephs],
                     systems=[o.system for o in obs])

    def _weights(self, el, cn0, iono=None, ura_m=None, code_var=None):
        """Relative weights of the satellites (largest 1).  code_var (elevation and cn0 weightings): the code
        variance of each satellite's signal relative to L1 C/A (_Sats.code_var); a fix mixing signals of
        different chip rates weights each by its inverse (None or all equal: no change)."""
        w = self._base_weights(el, cn0, iono, ura_m)
        if code_var is not None and self.weighting in SIGNAL_WEIGHTINGS and np.ptp(code_var) > 0.0:
            w = w / code_var
        return w / np.max(w)

    def _base_weights(self, el, cn0, iono=None, ura_m=None):
        if self.weighting == "rtklib" and el is not None:
            # RTKLIB's single-point error model with its default settings (code/phase error ratio 100,
            # a = b = 3 mm, code bias 0.3 m, URA, half the Klobuchar delay, 3 m unmodelled troposphere when
            # the troposphere is off): the weighting to compare fixes with rnx2rtkp on equal terms
            var = 100.0 ** 2 * (0.003 ** 2 + 0.003 ** 2 / np.sin(np.maximum(el, np.radians(1.0)))) \
                + 0.3 ** 2 + (0.5 * (iono if iono is not None else 0.0)) ** 2 \
                + (ura_m if ura_m is not None else 0.0) ** 2 \
                + (9.0 if self.troposphere == "none" else (0.3 / np.sin(np.maximum(el, np.radians(1.0)))) ** 2)
            w = 1.0 / var
        elif self.weighting == "elevation" and el is not None:
            w = np.sin(np.maximum(el, np.radians(1.0))) ** 2
        elif self.weighting == "cn0" and np.all(np.isfinite(cn0)):
            w = 10.0 ** (cn0 / 10.0)
        elif self.weighting == "cn0_elevation" and el is not None:
            se2 = np.sin(np.maximum(el, np.radians(1.0))) ** 2
            w = 1.0 / (10.0 ** ((self.cn0_ref_dbhz - np.asarray(cn0, float)) / 10.0) + 1.0 / se2) \
                if np.all(np.isfinite(cn0)) else se2
        else:
            w = np.ones(len(cn0))
        return w

    def _atmosphere(self, x, az, el, iono_utc, tow):
        lat, lon, h = ecef2lla(x)
        lat, lon = np.radians(lat), np.radians(lon)
        iono = np.zeros(len(el))
        tropo = np.zeros(len(el))
        if self.ionosphere == "klobuchar" and iono_utc is not None:
            iono = C_LIGHT * klobuchar_delay_s(iono_utc, lat, lon, az, el, tow)
        if self.troposphere == "saastamoinen" and -1000.0 < h < 50e3:
            tropo = saastamoinen_m(lat, h, el)
        return iono, tropo

    def _compiled_ok(self, extra, iono_utc) -> bool:
        """The compiled linearisation covers this solve: one clock (no inter-system bias columns), the
        built-in weightings and models, a 4+4-coefficient Klobuchar model."""
        if extra or self.weighting not in WEIGHTING or self.troposphere not in ("saastamoinen", "none") or \
                self.ionosphere not in ("klobuchar", "none"):
            return False
        if self.ionosphere == "klobuchar" and iono_utc is not None:
            return len(iono_utc.alpha) == 4 and len(iono_utc.beta) == 4
        return True

    def _linearise(self, pos_tx, x, b, rho_c, cn0, ura, corrections, iono_utc, tow):
        """One Gauss-Newton step's geometry, corrections, weights and residuals (receiver.navigation.wls_jit;
        the same as :meth:`_linearise_numpy` without inter-system biases)."""
        known = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) > 5.0e6
        lat = lon = h = 0.0
        if known:
            lat, lon, h = (float(v) for v in ecef2lla(x))
        corr = bool(corrections and known)
        iono_on = corr and self.ionosphere == "klobuchar" and iono_utc is not None
        alpha = np.asarray(iono_utc.alpha, float) if iono_on else _ZERO4
        beta = np.asarray(iono_utc.beta, float) if iono_on else _ZERO4
        tropo_on = corr and self.troposphere == "saastamoinen" and -1000.0 < h < 50e3
        tau, los, az, el, iono, tropo, w, resid, hm = linearise(
            pos_tx, np.asarray(x, float), float(b), rho_c, cn0, ura, known, corr, lat, lon, h, iono_on, alpha,
            beta, float(tow), tropo_on, WEIGHTING[self.weighting], self.troposphere == "none", self.cn0_ref_dbhz)
        if not known:
            az = el = None
        return known, tau, los, az, el, iono, tropo, w, resid, hm

    def _linearise_numpy(self, pos_tx, x, b, rho_c, cn0, ura, e_cols, isb, corrections, iono_utc, tow,
                         iono_scale=None, code_var=None):
        """(known, tau, los, az, el, iono, tropo, w, resid, h) at position x, clock b (numpy; any number
        of clock groups: e_cols / isb)."""
        n = len(pos_tx)
        tau = np.linalg.norm(pos_tx - x, axis=1) / C_LIGHT
        pos = earth_rotation(pos_tx, tau)
        diff = pos - x
        rng = np.linalg.norm(diff, axis=1)
        los = diff / rng[:, None]
        known = vnorm(x) > 5.0e6
        if known:
            az, el = azel(x, pos)
        else:
            az = el = None
        if corrections and known:
            iono, tropo = self._atmosphere(x, az, el, iono_utc, tow)
            if iono_scale is not None:
                iono = iono * iono_scale
        else:
            iono = tropo = np.zeros(n)
        w = self._weights(el if (corrections and known) else None, cn0, iono, ura, code_var)
        resid = rho_c - iono - tropo - (rng + b + e_cols @ isb)
        h = np.hstack([-los, np.ones((n, 1)), e_cols])
        return known, tau, los, az, el, iono, tropo, w, resid, h

    def _wls(self, s: _Sats, active, x, b, corrections, iono_utc, tow, aid=None):
        """Gauss-Newton WLS on the active satellites. Returns dict or None.

        Several systems: one clock bias b (the first system's) plus one inter-system bias column per other
        system with active satellites (unknowns 4 + extra systems).  aid (:class:`Aiding`): clock-bias and/or
        height constraints, added as pseudo-measurement rows (weights relative to a weight-1 satellite) once
        the position is known."""
        idx = np.nonzero(active)[0]
        extra = sorted(set(s.group[idx].tolist()) - {0})
        n_aid = aid.count() if aid is not None else 0
        if len(idx) + n_aid < 4 + len(extra) or len(idx) < 3 or (extra and 0 not in s.group[idx]):
            return None
        e_cols = (s.group[idx][:, None] == np.array(extra, int)[None, :]).astype(float)
        isb = np.zeros(len(extra))
        rho_c = s.rho[idx] + C_LIGHT * s.clk[idx]
        pos_tx = s.pos[idx]
        cn0, ura = s.cn0[idx], s.ura_m[idx]
        # the Klobuchar model gives the delay on its reference carrier (GPS set: L1; BeiDou set: B1I); a signal
        # on another carrier sees (f_ref / f)^2 of it -- 1 exactly for every satellite of one-system fixes
        iono_scale = None
        if iono_utc is not None:
            ratio = (float(getattr(iono_utc, "ref_hz", L1_HZ)) / s.carrier_hz[idx]) ** 2
            if np.any(ratio != 1.0):
                iono_scale = ratio
        compiled = self._compiled_ok(extra, iono_utc) and iono_scale is None
        for it in range(1, self.MAX_ITER + 1):
            if compiled:
                known, tau, los, az, el, iono, tropo, w, resid, h = self._linearise(
                    pos_tx, x, b, rho_c, cn0, ura, corrections, iono_utc, tow)
            else:
                known, tau, los, az, el, iono, tropo, w, resid, h = self._linearise_numpy(
                    pos_tx, x, b, rho_c, cn0, ura, e_cols, isb, corrections, iono_utc, tow, iono_scale,
                    s.code_var[idx])
            if n_aid:
                if not known:
                    return None
                ha, ra, wa = aid.rows(x, b, h.shape[1])
                h = np.vstack([h, ha])
                resid = np.concatenate([resid, ra])
                w = np.concatenate([w, wa])
            sw = np.sqrt(w)
            a = h * sw[:, None]
            try:
                dx, *_ = np.linalg.lstsq(a, resid * sw, rcond=None)
            except np.linalg.LinAlgError:
                return None
            if not np.all(np.isfinite(dx)):
                return None
            x = x + dx[:3]
            b = b + dx[3]
            isb = isb + dx[4:]
            if vnorm(dx) < self.CONVERGED_M:
                break
        else:
            return None
        # final residuals at the converged state (geometry unchanged within 0.1 mm)
        resid = resid - h @ dx
        ata = a.T @ a
        if np.linalg.cond(ata) > 1e12:
            return None
        hat_diag = np.einsum("ij,jk,ik->i", a, np.linalg.inv(ata), a)
        norm_res = sw * resid / np.sqrt(np.maximum(1.0 - hat_diag, 1e-6))
        ns = len(idx)
        # h_dop: the geometry of the DOPs: the satellite rows, plus the aiding rows scaled by the square
        # root of their weight (a constraint as good as a weight-1 satellite counts as one satellite)
        h_dop = h if not n_aid else np.vstack([h[:ns], h[ns:] * sw[ns:, None]])
        return dict(idx=idx, x=x, b=b, isb={s.systems[g]: float(v) for g, v in zip(extra, isb)},
                    resid=resid[:ns], norm_res=norm_res[:ns], aid_norm_res=norm_res[ns:], h=h[:ns],
                    red=np.clip(1.0 - hat_diag[:ns], 0.0, 1.0),
                    h_dop=h_dop, w=w[:ns], los=los, tau=tau, redundancy=len(resid) - h.shape[1],
                    az=az, el=el, iono=iono, tropo=tropo, rho_c=rho_c, iterations=it)

    def _leave_one_out(self, s: _Sats, active, x, b, corrections, iono_utc, tow, aid, rejected):
        """The WLS failed on the active satellites (no convergence, or converged far below the Earth's
        surface): a grossly wrong range - a corrupted ephemeris putting a satellite thousands of km off -
        drags the iteration away before the residual test can see it.  Leave each satellite out in turn and
        keep the solution whose largest normalised residual is smallest; the satellite left out is marked
        inactive and appended to ``rejected``.  Unaided, and only while at least 5 satellites remain (an
        over-determined fix, so the choice is checked by the residuals); None when no subset converges."""
        idx = np.flatnonzero(active)
        if aid is not None or len(idx) < 6:
            return None
        best = None
        for i in idx:
            trial = active.copy()
            trial[i] = False
            sol = self._wls(s, trial, x, b, corrections, iono_utc, tow)
            if sol is None or (corrections and sol["el"] is None):
                continue
            worst = float(np.max(np.abs(sol["norm_res"])))
            if best is None or worst < best[0]:
                best = (worst, i, sol)
        if best is None:
            return None
        active[best[1]] = False
        rejected.append(int(s.prn[best[1]]))
        return best[2]

    # -------------------------------------------------------------------------------------
    def fix(self, week, rx_tow, observations, ephemerides, iono_utc=None, x0=None, aid: Aiding | None = None,
            learn: bool = True):
        """Position/velocity/time fix at receiver time rx_tow (receiver clock, s of week).

        ephemerides: dict prn -> Ephemeris (or prn -> list of Ephemeris, the nearest healthy
        one is selected).  x0: initial ECEF position (e.g. the previous fix); without it the
        iteration starts from the Earth's centre.  aid: clock/height constraints (:class:`Aiding`; needs
        x0): with them 3 satellites can give a fix.  Returns a Fix or None (too few usable satellites, bad
        geometry, no convergence, or an aided fix failing its residual test).  learn (weighting_per_system
        vce): an unaided fix mixing systems adds its residuals to the variance factors' window; False for
        trial fixes (e.g. the assisted ambiguity search).
        """
        if aid is not None and (aid.count() == 0 or x0 is None):
            aid = None
        s = self._prepare(rx_tow, observations, ephemerides, week)
        if s is None or len(s) < (4 if aid is None else 3):
            return None
        base_var = s.code_var
        factors = self.vce_factors(s.systems)
        if factors:
            s.code_var = base_var * np.array([factors[c] for c in s.systems])[s.group]
        active = np.ones(len(s), dtype=bool)
        rejected = []
        start = self._initial_state(s, active, x0, iono_utc, rx_tow, rejected)
        if start is None:
            return None
        x, b = start
        # elevation mask, from the first position
        _, el0 = azel(x, earth_rotation(s.pos, np.linalg.norm(s.pos - x, axis=1) / C_LIGHT))
        active &= el0 >= np.radians(self.elevation_mask_deg)
        sol = self._solve_screened(s, active, x, b, iono_utc, rx_tow, aid, rejected)
        if sol is None:
            return None
        dops = self._dops(sol)
        if not dops[0] <= self.max_pdop:    # geometry too weak for a usable position (e.g. 4 satellites in a line)
            return None
        if aid is not None and not dops[0] <= aid.max_pdop:    # the same for an aided fix (its own limit)
            return None
        used = [s.systems[g] for g in sorted(set(s.group[sol["idx"]].tolist()))]
        if learn and aid is None and self._vce_on(used):
            self._vce_learn(int(week) * 604800.0 + float(rx_tow), s, sol, base_var)
        fix = self._build_fix(s, sol, dops, week, rx_tow, aid, rejected)
        fix.var_factors = factors
        return fix

    def _initial_state(self, s: _Sats, active, x0, iono_utc, rx_tow, rejected):
        """(x, b) to start the corrected iteration from: an uncorrected solution from the Earth's centre when
        x0 is missing or not a position, else x0 with the median clock bias over the satellites; None when the
        uncorrected solution fails (also with one satellite left out)."""
        if x0 is None or not np.all(np.isfinite(x0)) or vnorm(x0) < 5e6:
            first = self._wls(s, active, np.zeros(3), 0.0, False, iono_utc, rx_tow)
            if first is None:
                first = self._leave_one_out(s, active, np.zeros(3), 0.0, False, iono_utc, rx_tow, None, rejected)
            if first is None:
                return None
            return first["x"], first["b"]
        x = np.asarray(x0, dtype=float).copy()
        d = np.linalg.norm(earth_rotation(s.pos, 0.075) - x, axis=1)
        return x, _median_small(s.rho + C_LIGHT * s.clk - d)

    def _solve_screened(self, s: _Sats, active, x, b, iono_utc, rx_tow, aid, rejected):
        """The corrected WLS with the residual screening (see the class docstring and :class:`Aiding`): drops
        the worst satellite (marked inactive, appended to ``rejected``) and solves again until the residuals
        pass; the final solution dict, or None (no convergence, below the surface, an aided fix refused)."""
        while True:
            sol = self._wls(s, active, x, b, True, iono_utc, rx_tow, aid)
            if sol is None or sol["el"] is None:
                sol = self._leave_one_out(s, active, x, b, True, iono_utc, rx_tow, aid, rejected)
            if sol is None:
                return None
            x, b = sol["x"], sol["b"]
            if sol["el"] is None:            # converged far below the Earth's surface: no fix
                return None
            k = _argmax_abs(sol["norm_res"])
            if aid is None:
                if np.sum(active) > 5 and abs(sol["norm_res"][k]) > self.residual_threshold_m:
                    active[sol["idx"][k]] = False
                    rejected.append(int(s.prn[sol["idx"][k]]))
                    continue
                return sol
            # aided: test every row (satellites and constraints); exclude the worst satellite while the fix
            # stays over-determined, else refuse the fix (a bad range or a wrong constraint)
            worst = max(float(np.max(np.abs(sol["norm_res"]))),
                        float(np.max(np.abs(sol["aid_norm_res"]), initial=0.0)))
            if worst <= aid.residual_threshold_m:
                return sol
            if sol["redundancy"] >= 2 and np.sum(active) > 3 and \
                    abs(sol["norm_res"][k]) >= float(np.max(np.abs(sol["aid_norm_res"]), initial=0.0)):
                active[sol["idx"][k]] = False
                rejected.append(int(s.prn[sol["idx"][k]]))
                continue
            return None

    @staticmethod
    def _dops(sol):
        """(pdop, hdop, vdop, gdop), unweighted, in the local ENU frame of the solution's position; an aided
        fix's include its constraints (:class:`Aiding`)."""
        lat, lon, _ = ecef2lla(sol["x"])
        rot = enu_matrix(lat, lon)
        q = np.linalg.inv(sol["h_dop"].T @ sol["h_dop"])
        q_enu = rot @ q[:3, :3] @ rot.T
        hdop = float(np.sqrt(q_enu[0, 0] + q_enu[1, 1]))
        vdop = float(np.sqrt(q_enu[2, 2]))
        pdop = float(np.sqrt(np.trace(q_enu)))
        gdop = float(np.sqrt(np.trace(q)))
        return pdop, hdop, vdop, gdop

    @staticmethod
    def _velocity(s: _Sats, sol, aid):
        """Velocity and clock drift from Doppler on the solution's satellites: (rate_c corrected pseudorange
        rates, satellite velocities in the reception frame, v_rx, drift, per-satellite rate residuals); v_rx /
        drift NaN with fewer than 4 Dopplers (3 with a predicted drift in ``aid``)."""
        idx = sol["idx"]
        rate_raw = -s.doppler[idx] * LAMBDA_L1          # s.doppler: L1-equivalent Hz (see _prepare)
        rate_c = rate_raw + C_LIGHT * s.drift[idx]
        vel_sat = earth_rotation(s.vel[idx], sol["tau"])
        los = sol["los"]
        ok = np.isfinite(rate_c)
        v_rx = np.full(3, np.nan)
        drift = float("nan")
        v_res = np.full(len(idx), np.nan)
        drift_aid = aid is not None and aid.drift_mps is not None and np.sum(ok) >= 3
        if np.sum(ok) >= 4 or drift_aid:
            hv = np.hstack([-los[ok], np.ones((np.sum(ok), 1))])
            y = rate_c[ok] - np.sum(los[ok] * vel_sat[ok], axis=1)
            sw = np.sqrt(sol["w"][ok])
            ha, ya, swa = hv * sw[:, None], y * sw, None
            if drift_aid:           # the predicted clock drift as one more row
                swa = aid.rate_sigma_mps / aid.drift_sigma_mps
                ha = np.vstack([ha, [0.0, 0.0, 0.0, swa]])
                ya = np.append(ya, aid.drift_mps * swa)
            sv, *_ = np.linalg.lstsq(ha, ya, rcond=None)
            v_rx, drift = sv[:3], float(sv[3])
            v_res[ok] = y - hv @ sv
        return rate_c, vel_sat, v_rx, drift, v_res

    def _build_fix(self, s: _Sats, sol, dops, week, rx_tow, aid, rejected):
        """The :class:`Fix` of a screened solution: its DOPs, the Doppler velocity and the GPS time."""
        idx, x, b = sol["idx"], sol["x"], sol["b"]
        pdop, hdop, vdop, gdop = dops
        rate_c, vel_sat, v_rx, drift, v_res = self._velocity(s, sol, aid)
        tow = rx_tow - b / C_LIGHT
        gps_week, tow = normalize_week_tow(int(week), tow)
        return Fix(
            gps_week=gps_week, gps_tow=float(tow), ecef=x, velocity_ecef=np.asarray(v_rx, float),
            clock_bias_m=float(b), clock_drift_mps=drift, n_sats=len(idx),
            prns=[int(p) for p in s.prn[idx]], pdop=pdop, hdop=hdop, vdop=vdop, gdop=gdop,
            residuals_m=sol["resid"], elevations_deg=np.degrees(sol["el"]),
            azimuths_deg=np.degrees(sol["az"]),
            pseudoranges_m=sol["rho_c"] - sol["iono"] - sol["tropo"],
            pseudorange_rates_mps=rate_c, raw_pseudoranges_m=s.rho[idx],
            iono_m=sol["iono"], tropo_m=sol["tropo"], velocity_residuals_mps=v_res,
            rejected_prns=rejected, rx_tow=float(rx_tow), iterations=sol["iterations"], isb_m=sol["isb"],
            aiding=aid.kinds() if aid is not None else (),
            sat_pos_ecef=earth_rotation(s.pos[idx], sol["tau"]), sat_vel_ecef=vel_sat)
