"""VectorTracker: runs the channels under one navigation filter after the scalar-to-vector handover.

Chunk by chunk (``process(block, start)``):
  1. channel bookkeeping - channels the pipeline opened since the last chunk (re-acquisition) track scalar
     until they are locked and their satellite has an ephemeris, then join the vector loop; satellites
     with an ephemeris above the navigation elevation mask and no channel get a channel opened straight
     from the prediction (``vector.add_predicted``); vector channels whose satellite sets below
     ``vector.drop_elevation_deg`` are closed;
  2. the satellite geometry of the vector channels is refreshed (geometry.py);
  3. the compiled loop (loop.py) runs every vector epoch that fits in the block;
  4. records go back to the pipeline (``pll_lock`` of a vector channel = vector lock, loop.vector_locked:
     C/N0 above vector.lock_cn0_dbhz, or a weak GPS channel's slow detector), fixes are formed at
     navigation.rate_hz on round GPS times: mode 1 (vector) when at least 4 channels carry signal, else
     mode 2 (coast: the filter's prediction); n_sats = channels carrying signal.  While coasting, channels
     without signal only predict (vector.coast_mask).  When the coasting filter's 3D position sigma passes
     vector.reinit_sigma_m, ``reinit_needed`` is set and the pipeline falls back to scalar tracking
     (receiver.tracking.vector.Handover.fall_back).

Navigation interface used (receiver.navigation.engine.NavigationEngine): ``week()``, ``ephemerides(t)``,
``iono()``, ``iono_params()``, ``channels[prn].has_time / tx_offset / bit_offset`` (satellite memory),
``set_noncoherent``, ``resume``.

Vector channels are never dropped by the scalar lock detector (its loss timer is disabled): a blocked
channel keeps being predicted and is re-captured without re-acquisition when the signal returns.

Time: receiver time tau (s) counts from the handover reference sample s_ref, whose receiver clock reading
t_ref is the navigation engine's (rx_tow = tow0 + (s - s0)/fs), so the clock bias keeps its meaning:
GPS time = t_ref + tau - b / c.

Signals and systems: every channel carries its signal's constants into the compiled loop (chip rate, carrier
wavelength, code period, the IF and the input block of its stream: ``signals``, the run's SignalDefs in the
order of the pipeline's input blocks), so GPS and QZSS L1 C/A, BeiDou B1I and Galileo E1 channels share the
filter (a Galileo channel, receiver.tracking.gal_channels.GalTrack, brings a state row of the kernel's layout;
its epochs are the compiled Galileo ones of receiver.tracking.vector.galileo; channels are not opened from the
prediction for Galileo satellites: they join from the Galileo channel manager's acquisitions).  In a
run over several signals the channels are keyed like the navigation engine's (receiver.gnss.satid.sat_key;
the run's channel table, receiver.tracking.table.ChannelTable) and the filter gains one inter-system clock
bias state per system after the reference one, in the navigation solution's order and grouping (clock group =
the signal's system letter: QZSS shares GPS's clock, as in receiver.navigation.pvt), started from the
handover fix's ``isb_m``.

Why this module is long: the tracker's Python bookkeeping (channels joining and leaving, geometry,
diagnostics, fixes) is one class over one shared state (the filter, the channel arrays); the compiled epoch
loop is receiver.tracking.vector.loop.
"""
from __future__ import annotations

import math

import numpy as np

from .. import kernel as K
from ...gnss.geodesy import ecef2lla, enu_matrix
from ...runfile.record import FIX_DTYPE, VECTOR_ISB_SYSTEMS, VECTOR_LOG_DTYPE
from ...gnss.satid import MIXED, sat_label, split_key
from ...gnss.signals import C_LIGHT, GPS_L1CA
from ..scalar import Channel, to_records
from . import loop as L
from .geometry import satellite_polys
from .kalman import FORM_NONE
from .noise import channel_r

NEVER_LOST_MS = 1e15
MODE_VECTOR = 1               # FIX_DTYPE mode values (receiver.runfile.record)
MODE_COAST = 2
EPH_JUMP_M = 30.0             # a replacement ephemeris moving a locked satellite's range more than this is
                              # not used (_refresh_ephemerides)
PROMOTE_LOCKED_S = 1.0        # a scalar channel joins the vector loop after this long in lock
ISB_Q_M2_S = 1e-3             # random-walk PSD of an inter-system bias state (m^2/s: a hardware delay difference,
                              # constant but for temperature; 0.3 m after 100 s)
CLOCK_ORDER = "GJCE"          # the reference clock is the first of these (receiver.navigation.pvt._Sats)


#: BOC(1,1) code discriminator variance relative to BPSK's at the same E-L spacing (receiver.tracking.vector.noise)
BOC11_CODE_VAR = 1.0 / 3.0


def _galileo(sig) -> bool:
    """Whether a signal's vector channels run Galileo E1 epochs (receiver.tracking.vector.galileo)."""
    return sig.system == "E"


def _slow_lock_reset(cn0_dbhz: float = 0.0) -> np.ndarray:
    """A fresh slow lock detector state (loop.WK_*): waiting for a bit edge.  cn0_dbhz: the C/N0 it reports
    until its first window is complete (0: none, the channel counts as without signal until then); the
    detector clears it whenever the presence test finds the signal absent."""
    wk = np.zeros(L.N_WK)
    wk[L.WK_MS] = -1.0
    wk[L.WK_CN0] = cn0_dbhz
    return wk


class VectorTracker:
    """The vector tracking stage after the scalar-to-vector handover (see the module docstring):
    :meth:`process` runs a chunk's vector channels under the navigation filter ``filt``."""
    # (class defaults: GPS L1 C/A alone, one clock; __init__ sets them from its arguments)
    signals = [(GPS_L1CA, 0.0)]
    block_of = {"G": 0}
    multi = False
    system = "G"
    isb_systems: list = []
    isb_index: dict = {}

    def __init__(self, cfg, channels, nav, filt, fs, s_ref, t_ref, nav0, sig, start_sample, log=None,
                 signals=None, isb=None):
        """nav0 = (r, v, b, d, delta) at sample s_ref (receiver clock reading t_ref); sig: initial sigmas;
        signals: [(SignalDef, IF Hz of its stream)] in the order of process()'s blocks (None: GPS L1 C/A on
        the navigation engine's IF); isb: the handover fix's inter-system biases {system letter: m}."""
        self.cfg = cfg
        self.v = cfg.vector
        self.fs = float(fs)
        self.if_hz = float(getattr(nav, "if_hz", cfg.input.if_hz))    # 0 after the decimating stage
        if signals is None:
            signals = [(getattr(nav, "signal", None) or GPS_L1CA, self.if_hz)]
        self.signals = [(s_, float(f)) for s_, f in signals]
        self.block_of = {s_.system: i for i, (s_, _) in enumerate(self.signals)}
        self.multi = len(self.signals) > 1
        self.system = MIXED if self.multi else self.signals[0][0].system      # of the channel keys (labels)
        self.channels = channels            # the run's channel table (shared with the pipeline)
        self.nav = nav
        self.filt = filt
        self.s_ref = float(s_ref)
        self.t_ref = float(t_ref)
        self._sig = sig
        # clock groups: one bias per system of the run's signals after the reference one (navigation order)
        letters = sorted(self.block_of, key=lambda c: CLOCK_ORDER.index(c) if c in CLOCK_ORDER else 9)
        self.isb_systems = letters[1:]
        self.n = filt.n + len(self.isb_systems)
        self.isb_index = {c: filt.n + i for i, c in enumerate(self.isb_systems)}
        self._isb0 = dict(isb or {})
        x, P = self._augment(*filt.initial(*nav0, sig))
        self.x, self.P = np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(P, dtype=float)
        self.tau_state = 0.0
        F, Q, QB = filt.matrices()
        self.F, self.Q, self.QB = (np.ascontiguousarray(a, dtype=float) for a in self._augment_matrices(F, Q, QB))
        self.lay = filt.layout()
        self.T_ms = int(self.v.integration_ms)
        self.step = self.T_ms * 1e-3 * self.fs
        self.log = log or (lambda msg: None)
        self.prns: list[int] = []           # vector channels, in array order
        self.info: dict[int, dict] = {}     # prn -> {A, Rc, Rf, window...}
        self.pending_since: dict[int, float] = {}
        self.ephs: dict = {}                # prn -> Ephemeris
        self._rejected: dict = {}           # prn -> a replacement Ephemeris not taken (_refresh_ephemerides)
        self.week = None
        self.rate = float(cfg.navigation.rate_hz)
        self.next_fix = None
        self.stats = {"epochs": 0, "fired": 0}
        self.reinit_needed = False           # the filter cannot bridge the current outage (see process)
        self.last_diag = None                # decimated diagnostics of the last chunk (see diagnostics())
        self.last_log = None
        self._arrays_dirty = True
        self._refresh_ephemerides(self._gps_time(0.0))
        for prn, ch in list(channels.items()):      # initial vector channel set
            if self._eligible(prn, ch):
                self._promote(prn, ch)
        origin = min((float(channels[p].st[K.S_NEXT_SAMPLE]) for p in self.prns),
                     default=float(start_sample))
        self.grid_next = origin + self.step
        # the filter state starts at the grid origin
        tau0 = (origin - self.s_ref) / self.fs
        r, v, b, d, dl = nav0
        x, P = self._augment(*filt.initial(np.asarray(r) + np.asarray(v) * tau0, v, b + (d + dl) * tau0, d, dl,
                                           sig))
        self.x, self.P = np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(P, dtype=float)
        self.tau_state = tau0

    # ================================================================== helpers
    def _augment(self, x, P):
        """The variant's (x, P) with the inter-system bias states appended (from the handover fix's isb_m;
        a system the fix did not use starts at 0 with a 1-km sigma)."""
        k = len(self.isb_systems)
        if not k:
            return x, P
        n0 = len(x)
        xa = np.concatenate([x, [float(self._isb0.get(c, 0.0)) for c in self.isb_systems]])
        Pa = np.zeros((n0 + k, n0 + k))
        Pa[:n0, :n0] = P
        for i, c in enumerate(self.isb_systems):
            Pa[n0 + i, n0 + i] = float(self._sig["b"]) ** 2 if c in self._isb0 else 1e6
        return xa, Pa

    def _augment_matrices(self, F, Q, QB):
        k = len(self.isb_systems)
        if not k:
            return F, Q, QB
        n0 = F.shape[0]
        out = []
        for M, diag in ((F, 1.0), (Q, ISB_Q_M2_S * self.filt.T), (QB, 0.0)):
            A = np.zeros((n0 + k, n0 + k))
            A[:n0, :n0] = M
            A[range(n0, n0 + k), range(n0, n0 + k)] = diag
            out.append(A)
        return out

    def label(self, key) -> str:
        """RINEX label of a channel key (G05, J01, C12)."""
        return sat_label(key, self.system)

    def _signal(self, key):
        """(SignalDef, IF Hz, signal PRN) of a channel key."""
        if self.multi:
            letter, prn = split_key(key)
            sig, f = self.signals[self.block_of[letter]]
            return sig, f, prn
        sig, f = self.signals[0]
        return sig, f, key

    def _isb_state(self, sig) -> int:
        return self.isb_index.get(sig.system, -1)

    def _max_int_ms(self, sig, sig_prn) -> int:
        """The channel's coherent integration under the vector loop: the longest that divides its data
        symbol and is at most vector.integration_ms (L1 C/A, B1I D1: T; B1I D2 GEO: its 2-ms symbols)."""
        bit_ms = int(sig.bit_ms(sig_prn))
        return max(d for d in range(1, min(self.T_ms, bit_ms) + 1) if bit_ms % d == 0)
    def _gps_time(self, tau):
        r, v, b, d, dl = self.filt.nav_state(self.x)
        return self.t_ref + tau - b / C_LIGHT

    def _refresh_ephemerides(self, t_gps):
        """The navigation engine's ephemerides; a replacement set that moves a satellite's predicted range
        by more than EPH_JUMP_M while its vector channel is in vector lock is not taken (see below)."""
        nav = self.nav
        tau = (self.grid_next - self.s_ref) / self.fs if hasattr(self, "grid_next") else self.tau_state
        for prn, e in nav.ephemerides(t_gps).items():
            old = self.ephs.get(prn)
            if old is None or e is old or e == old or self._rejected.get(prn) is e:
                self.ephs[prn] = old if self._rejected.get(prn) is e else e
                continue
            jump = self._predict_prn(prn, tau, e)[0] - self._predict_prn(prn, tau, old)[0]
            locked = self._vector_lock(prn)
            if abs(jump) > EPH_JUMP_M and locked:
                # the channel follows the signal with the set in use (its innovations are small): the new
                # one disagrees with the signal - a decoding error that passed parity (low C/N0, words
                # assembled across frames) - and would steer the channel off it
                self._rejected[prn] = e
                self.log(f"vector: {self.label(prn)} new ephemeris (IODE {e.iode}) moves the predicted range by "
                         f"{jump:+.0f} m while the channel is locked with the one in use (IODE {old.iode}): "
                         f"not used")
                continue
            self._rejected.pop(prn, None)
            self.ephs[prn] = e
        w = nav.week()
        if w is not None:
            self.week = int(w)

    def _eligible(self, prn, ch) -> bool:
        if ch.lost or prn not in self.ephs:
            return False
        locked = ch.st[K.S_LOCK] > 0 and ch.st[K.S_MODE] in (K.MODE_TRACK, K.MODE_BIT_SYNC)
        return bool(locked)

    def _predict_prn(self, prn, tau, eph=None):
        """(pseudorange m, pseudorange rate m/s, LOS unit vector, elevation rad) of a satellite at tau (with
        the ephemeris in use, or eph)."""
        r, v, b, d, dl = self.filt.nav_state(self.x)
        sig = self._signal(prn)[0]
        ig = self._isb_state(sig)
        if ig >= 0:                         # the channel's clock: the reference one plus its system's bias
            b = b + float(self.x[ig])
        dt = tau - self.tau_state
        pos = r + v * dt
        eph = self.ephs[prn] if eph is None else eph
        poly, atm, el = satellite_polys([eph], self.t_ref, tau, 0.05, b + (d + dl) * dt, d + dl, pos,
                                        self.nav.iono(), self.cfg.navigation, [sig.carrier_hz])
        sp, sv = poly[0, 0], poly[0, 1]
        los = sp[:3] - pos
        rng = float(np.linalg.norm(los))
        e = los / rng
        rho = rng + atm[0] + b + (d + dl) * dt - sp[3]
        rate = float(e @ (sv[:3] - v)) + d - sv[3]
        return rho, rate, e, float(el[0])

    def _tx_offset(self, prn, ch):
        """A_j: relative transmit time of the channel's code period 0 (a whole number of code periods of GPS
        time: L1 C/A and B1I have 1-ms codes; B1I's BDT is GPS time - 14 s)."""
        sig = self._signal(prn)[0]
        per = sig.code_len / sig.chip_rate          # s (1e-3 to the bit for both signals)
        pps = sig.chip_rate / sig.code_len          # code periods per second (1000.0 exactly)
        s = float(ch.st[K.S_NEXT_SAMPLE])
        tau = (s - self.s_ref) / self.fs
        rho, _, _, _ = self._predict_prn(prn, tau)
        tx_abs = self.t_ref + tau - rho / C_LIGHT
        t0 = tx_abs - ch.st[K.S_CODE_PERIOD] * per - ch.st[K.S_CODE_PHASE] / sig.chip_rate
        A = round(t0 * pps) / pps - self.t_ref
        cn = self.nav.channels.get(prn)
        if cn is not None and cn.has_time:
            A_dec = cn.tx_offset - self.t_ref
            if abs(A_dec - A) > 1e-6:
                self.log(f"vector: {self.label(prn)} decoded transmit time disagrees with the prediction by "
                         f"{(A_dec - A) * 1e3:.3f} ms; using the prediction")
        return A

    def _promote(self, prn, ch):
        """Hand a channel's NCOs to the vector loop."""
        # a channel the scalar lock detectors hold locked hands its C/N0 to the slow lock detector, which
        # would otherwise count it as without signal for its first window (weak_lock_window_ms)
        handed_cn0 = float(ch.st[K.S_CN0]) if ch.st[K.S_LOCK] > 0 else 0.0
        ch.set_external(True, True)
        ch.cfg[K.C_LOST_MS] = NEVER_LOST_MS
        ch.cfg[K.C_PRES_LOST_MS] = NEVER_LOST_MS        # (the presence test still zeroes C/N0: coast at once)
        ch.cfg[K.C_CN0_EST] = 1.0                       # M2M4: phase-lock independent
        ch.cfg[K.C_CN0_WIN_MS] = float(self.v.cn0_window_ms)
        sig, _, sig_prn = self._signal(prn)
        max_int = 1 if _galileo(sig) else self._max_int_ms(sig, sig_prn)    # (Galileo: one 4-ms period per epoch)
        ch.cfg[K.C_MAX_INT_MS] = max_int
        if ch.st[K.S_INT_MS] > max_int:
            ch.st[K.S_INT_MS] = 1
            # the C/N0 window's partial sums hold epochs of the longer integration: M2M4 over a mix of two
            # integration times reads nonsense (0 dB-Hz for ~0.4 s: the channel counted as without signal)
            for i in (K.S_ACC_ABSI, K.S_ACC_Q2, K.S_ACC_I2, K.S_ACC_M2, K.S_ACC_M4, K.S_ACC_N):
                ch.st[i] = 0.0
        self.info[prn] = {"A": self._tx_offset(prn, ch), "Rc": self.filt.r_code, "Rf": self.filt.r_carr,
                          "W": np.zeros((2, self.filt.window)), "WI": 0, "WN": 0, "WS": np.zeros(2),
                          "WK": _slow_lock_reset(handed_cn0)}
        self.prns.append(prn)
        self.pending_since.pop(prn, None)
        self._arrays_dirty = True
        if self.nav is not None:                        # frequency-locked from now: differential bits
            self.nav.set_noncoherent(prn, int(ch.st[K.S_NEXT_SAMPLE]))

    def _open_predicted(self, prn, s):
        s = float(math.floor(s))
        sig, if_hz, sig_prn = self._signal(prn)
        pps = sig.chip_rate / sig.code_len          # code periods per second (1000.0 exactly)
        bit_ms = int(sig.bit_ms(sig_prn))
        tau = (s - self.s_ref) / self.fs
        rho, rate, _, _ = self._predict_prn(prn, tau)
        tx_abs = self.t_ref + tau - rho / C_LIGHT
        code_phase = ((tx_abs * pps) % 1.0) * sig.code_len
        doppler = -rate / (C_LIGHT / sig.carrier_hz)
        ch = Channel(sig_prn, doppler, code_phase, int(s), self.cfg.tracking, self.fs, if_hz,
                     channel_id=len(self.channels), signal=sig)
        ch.st[K.S_MODE] = K.MODE_TRACK
        # continue the satellite's code-period count of its navigation memory (transmit-time reference,
        # bit alignment), else start a new one there
        cn = self.nav.channels.get(prn)
        continuous = False
        if cn is not None and cn.has_time and cn.bit_offset >= 0:
            s1 = float(ch.st[K.S_NEXT_SAMPLE])
            rho1, _, _, _ = self._predict_prn(prn, (s1 - self.s_ref) / self.fs)
            tx1 = self.t_ref + (s1 - self.s_ref) / self.fs - rho1 / C_LIGHT
            ch.st[K.S_CODE_PERIOD] = round((tx1 - cn.tx_offset - ch.st[K.S_CODE_PHASE] / sig.chip_rate) * pps)
            ch.st[K.S_BIT_OFFSET] = cn.bit_offset
            ch.hist[cn.bit_offset % 20] = 12
            continuous = True
        else:
            # no memory of the satellite: the data-bit edges from the predicted transmit time (bits start
            # at whole 20 ms of GPS time -- B1I D1 bits and NH code periods too (BDT = GPS time - 14 s), D2
            # symbols at whole 2 ms; the prediction is good to far better than 0.5 ms), so the channel
            # integrates 10-20 ms at once (B1I: NH wiped off) instead of waiting ~1 s for a bit sync
            # t0: the transmit code period (ms of GPS time) in progress at sample s; the channel's code period
            # 0 is the NEXT one (Channel starts at the first code-period start at or after s), t0 + 1
            t0 = round((tx_abs - code_phase / sig.chip_rate) * pps)
            ch.st[K.S_BIT_OFFSET] = (-(t0 + 1)) % bit_ms
            ch.st[K.S_MODE] = K.MODE_BIT_SYNC
            ch.hist[int(ch.st[K.S_BIT_OFFSET])] = 12
        if cn is not None:
            self.nav.resume(prn, continuous)
        self.channels[prn] = ch
        self._promote(prn, ch)
        self.log(f"vector: opened predicted channel {self.label(prn)} (Doppler {doppler:.0f} Hz)")

    # ================================================================== arrays
    def _build_arrays(self):
        self._save_arrays()
        prns = self.prns
        m = len(prns)
        chans = [self.channels[p] for p in prns]
        self.ST = np.zeros((m, K.N_STATE))
        self.CF = np.zeros((m, K.N_CONFIG))
        # codes of different signals differ in length (B1I: 2046 chips and the NH-modulated section): the
        # rows are zero-padded to the longest (each channel's kernel stays inside its own code)
        L_code = max((ch.code_ext.shape[0] for ch in chans), default=1)
        self.CODE = np.zeros((m, L_code), np.float32)
        self.SIG = np.zeros((m, L.N_SIG))
        self.HIST = np.zeros((m, 20), np.int64)
        for i, ch in enumerate(chans):
            self.ST[i] = ch.st
            self.CF[i] = ch.cfg
            self.CODE[i, :ch.code_ext.shape[0]] = ch.code_ext
            sig, if_hz, _ = self._signal(prns[i])
            self.SIG[i, L.SIG_CHIP] = sig.chip_rate
            self.SIG[i, L.SIG_LAMBDA] = C_LIGHT / sig.carrier_hz
            self.SIG[i, L.SIG_PERIOD] = sig.code_len / sig.chip_rate
            self.SIG[i, L.SIG_IF] = if_hz
            self.SIG[i, L.SIG_BLOCK] = self.block_of[sig.system]
            self.SIG[i, L.SIG_ISB] = self._isb_state(sig)
            self.SIG[i, L.SIG_KIND] = L.KIND_GAL_E1 if _galileo(sig) else L.KIND_KERNEL
            _, _, sig_prn = self._signal(prns[i])
            self.SIG[i, L.SIG_SLOW] = float(not _galileo(sig) and sig.secondary(sig_prn) is None
                                            and int(sig.bit_ms(sig_prn)) == 20)
            self.HIST[i, :len(ch.hist)] = ch.hist
            ch.st = self.ST[i]                 # the channel now lives in the shared arrays
            ch.cfg = self.CF[i]
            ch.hist = self.HIST[i]
        N = self.filt.window
        self.CA = np.array([self.info[p]["A"] for p in prns], float)
        self.RC = np.array([self.info[p]["Rc"] for p in prns], float)
        self.RF = np.array([self.info[p]["Rf"] for p in prns], float)
        self.W = np.zeros((m, 2, N))
        self.WI = np.zeros(m, np.int64)
        self.WN = np.zeros(m, np.int64)
        self.WS = np.zeros((m, 2))
        self.WK = np.zeros((m, L.N_WK))
        for i, p in enumerate(prns):
            d = self.info[p]
            self.W[i], self.WI[i], self.WN[i], self.WS[i] = d["W"], d["WI"], d["WN"], d["WS"]
            self.WK[i] = d["WK"]
        self.ACTIVE = np.ones(m, np.int64)
        self._arr_prns = list(prns)
        self._arrays_dirty = False

    def _cn0_r(self):
        """vector.r_model cn0: each channel's R from its C/N0 estimate and integration (noise.py); an
        adaptive variant's channel keeps its own estimate once its window is filled."""
        m = len(self.prns)
        # (integration in ms: code periods x the period, 4 ms for Galileo; BOC(1,1)'s code variance is a third
        # of BPSK's at the same spacing, receiver.tracking.vector.noise)
        gal = self.SIG[:, L.SIG_KIND] == L.KIND_GAL_E1
        int_ms = self.ST[:, K.S_INT_MS] * np.round(self.SIG[:, L.SIG_PERIOD] * 1e3)
        r_code, r_rate = channel_r(self.ST[:, K.S_CN0], int_ms, self.T_ms,
                                   self.CF[:, K.C_EL_SPACING], self.v.r_cn0,
                                   C_LIGHT / self.SIG[:, L.SIG_CHIP], self.SIG[:, L.SIG_LAMBDA],
                                   code_factor=np.where(gal, BOC11_CODE_VAR, 1.0))
        own = np.zeros(m, bool)
        if self.filt.adaptive_form != FORM_NONE:
            own = self.WN >= min(self.filt.window, 100)
        self.RC[~own] = r_code[~own]
        self.RF[~own] = r_rate[~own]

    def _save_arrays(self):
        """Keep the adaptive-R state of the channels of the current arrays (before a rebuild)."""
        for i, p in enumerate(getattr(self, "_arr_prns", [])):
            d = self.info.get(p)
            if d is None:
                continue
            d["Rc"], d["Rf"] = float(self.RC[i]), float(self.RF[i])
            d["W"], d["WI"], d["WN"], d["WS"] = self.W[i].copy(), int(self.WI[i]), int(self.WN[i]), \
                self.WS[i].copy()
            d["WK"] = self.WK[i].copy()

    def _remove(self, prn, mark_lost):
        if prn in self.prns:
            ch = self.channels.get(prn)
            if ch is not None:
                ch.st = ch.st.copy()
                ch.cfg = ch.cfg.copy()
                ch.hist = ch.hist.copy()
                if mark_lost:
                    ch.st[K.S_MODE] = K.MODE_LOST
                elif self.nav is not None:              # back to its scalar loop
                    self.nav.set_noncoherent(prn, None)
            self.prns.remove(prn)
            self.info.pop(prn, None)
            self._arrays_dirty = True

    # ================================================================== per chunk
    def process(self, blocks, start):
        """One chunk: blocks = the chunk's samples of each signal's stream (the order of ``signals``; one
        array for a one-signal run).  Returns (records per channel key, fixes)."""
        if isinstance(blocks, np.ndarray) and blocks.ndim == 1:
            blocks = [blocks]
        block = blocks[0]
        # one 2-D array for the compiled loop (a view without copying for one signal)
        B = block[None, :] if len(blocks) == 1 else np.ascontiguousarray(np.stack(blocks))
        fs = self.fs
        tau_now = (self.grid_next - self.s_ref) / fs
        self._refresh_ephemerides(self._gps_time(tau_now))
        # channels the pipeline dropped
        for prn in [p for p in self.prns if p not in self.channels]:
            self._remove(prn, False)
        recs = self._step_pending(blocks, start)
        # geometry of all satellites with ephemeris (elevations), predicted channels, setting satellites
        r, v, b, d, dl = self.filt.nav_state(self.x)
        self._open_predicted_channels(start, tau_now, r, b, d + dl)
        if self._arrays_dirty:
            self._build_arrays()
        m = len(self.prns)
        # satellite polynomials over this block
        blk_end = start + len(block)
        tau_a = (self.grid_next - self.step - self.s_ref) / fs
        span = max((blk_end - (self.grid_next - self.step)) / fs, 0.05)
        ephs = [self.ephs[p] for p in self.prns]
        POLY, ATM, EL = satellite_polys(ephs, self.t_ref, tau_a, span / 2.0, b, d + dl, r,
                                        self.nav.iono(), self.cfg.navigation,
                                        [self._signal(p)[0].carrier_hz for p in self.prns])
        TAU_A = np.full(m, tau_a)
        self._geo = (list(self.prns), POLY, tau_a)
        cap = int(len(block) / fs * 1000.0) + 8
        REC = np.zeros((m, cap, K.N_OUT))
        NREC = np.zeros(m, np.int64)
        max_ep = int(len(block) / self.step) + 2
        n = self.n
        LOG = np.zeros((max_ep, L.N_LOG))
        LX = np.zeros((max_ep, n))
        LPD = np.zeros((max_ep, n))
        LR = np.zeros((max_ep, m, 2))
        prm = self._prm = self._chunk_params()
        if m and self.v.r_model == "cn0":
            self._cn0_r()
        if m:
            chans = (self.ST, self.CF, self.CODE, self.HIST, self.CA, self.ACTIVE, self.SIG, self.WK)
            filt = (self.x, self.P, self.F, self.Q, self.QB, self.lay, self.RC, self.RF, self.W, self.WI, self.WN,
                    self.WS)
            nep, self.grid_next = L.run_chunk(B, start, prm, self.grid_next, max_ep, chans, (POLY, TAU_A, ATM),
                                              filt, (REC, NREC, LOG, LX, LPD, LR))
        else:                                   # nothing to track: coast the filter over the block
            nep = self._coast(prm, blk_end, max_ep, LOG, LX, LPD)
        if nep:
            self.tau_state = float(LOG[nep - 1, L.L_TAU])
            # an outage longer than the filter can bridge: coasting and the position sigma past the limit
            ip = self.lay[0]
            sig_pos = float(np.sqrt(max(LPD[nep - 1, ip:ip + 3].sum(), 0.0)))
            lim = float(self.v.reinit_sigma_m)
            if lim > 0 and LOG[nep - 1, L.L_NLOCK] < 4 and sig_pos > lim:
                self.reinit_needed = True
        self.last_diag = self._diagnostics(LOG[:nep], LPD[:nep], LR[:nep], self.stats["epochs"], LX[:nep])
        self.stats["epochs"] += nep
        self.stats["fired"] += int(LOG[:nep, L.L_FIRED].sum())
        for i, prn in enumerate(self.prns):
            rec = to_records(REC[i, :NREC[i]])          # pll_lock: vector lock (loop.vector_locked)
            if prn in recs and len(recs[prn]):          # promoted in this chunk: scalar records first
                rec = np.concatenate([recs[prn], rec])
            recs[prn] = rec
        fixes = self._fixes(LOG[:nep], LX[:nep], LPD[:nep])
        self.last_log = (LOG[:nep], LX[:nep], LPD[:nep], LR[:nep], list(self.prns))
        # satellites that set: close their channels (the pipeline drops lost channels)
        for i, prn in enumerate(list(self.prns)):
            if np.degrees(EL[i]) < self.v.drop_elevation_deg:
                self.log(f"vector: {self.label(prn)} set below {self.v.drop_elevation_deg:g} deg, channel closed")
                self._remove(prn, True)
        return recs, fixes

    def _step_pending(self, blocks, start) -> dict:
        """The scalar (pending) channels track the chunk and join the vector loop once locked long enough;
        returns their records by channel key."""
        fs, recs = self.fs, {}
        for prn, ch in list(self.channels.items()):
            if prn in self.prns:
                continue
            recs[prn] = ch.process(blocks[self.block_of[ch.signal.system]], start)
            if ch.lost:
                continue
            locked = ch.st[K.S_LOCK] > 0
            if locked:
                t0 = self.pending_since.setdefault(prn, start / fs)
                if start / fs - t0 >= PROMOTE_LOCKED_S and self._eligible(prn, ch):
                    self._promote(prn, ch)
                    self.log(f"vector: {self.label(prn)} joined the vector loop")
            else:
                self.pending_since.pop(prn, None)
        return recs

    def _open_predicted_channels(self, start, tau_now, r, b, drift):
        """Channels opened from the prediction for satellites with ephemeris above the elevation mask
        (vector.add_predicted), highest first, while channels are free."""
        if not (self.v.add_predicted and len(self.channels) < self.cfg.tracking.max_channels):
            return
        # (Galileo satellites: their channels come from the Galileo channel manager's acquisitions only)
        cand = [p for p in sorted(self.ephs) if p not in self.channels and not _galileo(self._signal(p)[0])]
        if not cand:
            return
        _, _, el = satellite_polys([self.ephs[p] for p in cand], self.t_ref, tau_now, 0.1, b,
                                   drift, r, self.nav.iono(), self.cfg.navigation)
        order = np.argsort(-el)
        for i in order:
            if len(self.channels) >= self.cfg.tracking.max_channels:
                break
            if np.degrees(el[i]) >= self.cfg.navigation.elevation_mask_deg:
                self._open_predicted(cand[i], max(self.grid_next - self.step, float(start)))

    def _chunk_params(self) -> np.ndarray:
        """The compiled loop's scalar parameters (receiver.tracking.vector.loop P_* slots)."""
        prm = np.zeros(L.N_PRM)
        prm[L.P_FS] = self.fs
        prm[L.P_IF] = self.if_hz
        prm[L.P_GRID] = self.step
        prm[L.P_SREF] = self.s_ref
        # (a Galileo channel's 4-ms epoch may start just before a grid point and end 4 ms after it)
        longest = 4 if any(_galileo(self._signal(p)[0]) for p in self.prns) else self.T_ms
        prm[L.P_MARGIN] = (max(self.T_ms, longest) + 1.0) * 1e-3 * self.fs
        prm[L.P_CHI2] = self.filt.chi2_threshold
        prm[L.P_CN0_MASK] = -1e9 if self.v.cn0_mask_dbhz is None else float(self.v.cn0_mask_dbhz)
        if self.v.r_model == "cn0":         # below min_cn0_dbhz a channel has no weight to give
            prm[L.P_CN0_MASK] = max(prm[L.P_CN0_MASK], float(self.v.r_cn0.min_cn0_dbhz))
        prm[L.P_LOCK_CN0] = float(self.v.lock_cn0_dbhz)
        prm[L.P_FORM] = self.filt.adaptive_form
        prm[L.P_FLOOR_C] = self.filt.floor_code
        prm[L.P_FLOOR_F] = self.filt.floor_carr
        prm[L.P_MIN_FILL] = min(self.filt.window, 100)
        prm[L.P_GATE] = float(self.v.innovation_gate_sigma)
        prm[L.P_COAST_MASK] = 1.0 if self.v.coast_mask else 0.0
        prm[L.P_SLOW_CN0] = float(self.v.weak_lock_cn0_dbhz)
        prm[L.P_SLOW_BITS] = max(1.0, round(float(self.v.weak_lock_window_ms) / 20.0))
        return prm

    def _vector_lock(self, prn) -> bool:
        """Whether the vector channel of a key carries signal now (loop.vector_locked)."""
        if prn not in self.prns or getattr(self, "_arr_prns", None) != list(self.prns):
            ch = self.channels.get(prn)
            return ch is not None and prn in self.prns and ch.st[K.S_CN0] >= float(self.v.lock_cn0_dbhz)
        i = self.prns.index(prn)
        prm = getattr(self, "_prm", None)
        if prm is None:
            prm = self._prm = self._chunk_params()
        return bool(L.vector_locked(self.ST[i], self.WK[i], self.SIG[i], prm))

    def _coast(self, prm, blk_end, max_ep, LOG, LX, LPD) -> int:
        """Nothing to track: predict the filter over the block's epochs; returns the epoch count."""
        from .kalman import kf_predict
        nep = 0
        while self.grid_next + prm[L.P_MARGIN] <= blk_end and nep < max_ep:
            kf_predict(self.x, self.P, self.F, self.Q)
            LOG[nep, L.L_TAU] = (self.grid_next - self.s_ref) / self.fs
            LX[nep] = self.x
            LPD[nep] = np.diag(self.P)
            self.grid_next += self.step
            nep += 1
        return nep

    # ================================================================== diagnostics
    def _diagnostics(self, LOG, LPD, LR, first_epoch, LX=None):
        """VECTOR_LOG_DTYPE rows of this chunk's epochs, every round(1 / (output.vector_log_hz T)) epochs."""
        hz = float(self.cfg.output.vector_log_hz)
        if hz <= 0 or not len(LOG):
            return np.zeros(0, VECTOR_LOG_DTYPE)
        step = max(1, int(round(1000.0 / (hz * self.T_ms))))
        k = np.flatnonzero((first_epoch + np.arange(len(LOG))) % step == 0)
        out = np.zeros(len(k), VECTOR_LOG_DTYPE)
        out["time_s"] = (self.s_ref + LOG[k, L.L_TAU] * self.fs) / self.fs
        out["tag_code"], out["tag_carrier"] = LOG[k, L.L_TAGP], LOG[k, L.L_TAGV]
        out["manoeuvre"], out["n_valid"] = LOG[k, L.L_FIRED], LOG[k, L.L_NVALID]
        out["n_lock"] = LOG[k, L.L_NLOCK]
        ip, iv, ib, idd, _ = self.lay
        sd = np.sqrt(np.maximum(LPD[k], 0.0))
        out["sigma_pos_m"], out["sigma_vel_mps"] = sd[:, ip:ip + 3], sd[:, iv:iv + 3]
        out["sigma_bias_m"], out["sigma_drift_mps"] = sd[:, ib], sd[:, idd]
        out["r_code_m2"] = np.nan
        out["r_carrier_m2s2"] = np.nan
        out["isb_m"] = np.nan
        out["sigma_isb_m"] = np.nan
        for c, i in self.isb_index.items():
            if c in VECTOR_ISB_SYSTEMS and LX is not None:
                col = VECTOR_ISB_SYSTEMS.index(c)
                out["isb_m"][:, col] = LX[k, i]
                out["sigma_isb_m"][:, col] = sd[:, i]
        for j, prn in enumerate(list(getattr(self, "_arr_prns", self.prns))[:LR.shape[1]]):
            if 1 <= prn <= 32:
                out["r_code_m2"][:, prn - 1] = LR[k, j, 0]
                out["r_carrier_m2s2"][:, prn - 1] = LR[k, j, 1]
        return out

    # ================================================================== fixes
    def _fixes(self, LOG, LX, LPD):
        if not len(LOG) or self.week is None:
            return np.zeros(0, FIX_DTYPE)
        rows = []
        step = 1.0 / self.rate
        # GPS time of every epoch at once (the same float64 operations as per epoch); the state is unpacked
        # only at the epochs where a fix falls due (a few per block, not every epoch)
        ib = int(self.filt.layout()[2])
        t_all = self.t_ref + LOG[:, L.L_TAU] - LX[:, ib] / C_LIGHT
        for k in range(len(LOG)):
            t_gps = float(t_all[k])
            if self.next_fix is None:
                self.next_fix = math.ceil(t_gps * self.rate - 1e-9) / self.rate
            if self.next_fix > t_gps + 1e-12:
                continue
            tau = float(LOG[k, L.L_TAU])
            r, v, b, d, dl = self.filt.nav_state(LX[k])
            while self.next_fix <= t_gps + 1e-12:
                back = t_gps - self.next_fix                # s of GPS time before epoch k
                tau_f = tau - back * (1.0 + (d + dl) / C_LIGHT)
                rf = r - v * back
                bf = b - (d + dl) * back
                rows.append(self._fix_row(tau_f, rf, v, bf, d, int(LOG[k, L.L_NLOCK]), self.next_fix))
                self.next_fix = round((self.next_fix + step) * self.rate) / self.rate
        out = np.zeros(len(rows), FIX_DTYPE)
        for i, row in enumerate(rows):
            out[i] = row
        return out

    def _fix_row(self, tau, r, v, b, d, nsat, tow):
        """Mode 1 (vector) with at least 4 channels carrying signal, else 2 (coast); n_sats = those channels."""
        week = self.week
        if tow >= 604800.0:
            tow, week = tow - 604800.0, week + 1
        lat, lon, h = ecef2lla(r)
        dops = self._dops(tau, r, lat, lon)
        t_s = (self.s_ref + tau * self.fs) / self.fs
        mode = MODE_VECTOR if nsat >= 4 else MODE_COAST
        # the Klobuchar set of this block's satellite polynomials (nav.iono() does not change during a block)
        return (week, tow, t_s, r, v, b, d, nsat, *dops, mode, float(lat), float(lon), float(h),
                self.nav.iono_params())

    def _dops(self, tau, r, lat, lon):
        """(pdop, hdop, vdop, gdop) of the channels in vector lock (NaN below 4), from this chunk's satellite
        polynomials (the geometry the loop itself used at receiver time tau)."""
        prns, POLY, tau_a = self._geo
        rows = [i for i, p in enumerate(prns) if p in self.channels and p in self.ephs and self._vector_lock(p)]
        if len(rows) < 4:
            return (np.nan,) * 4
        c = POLY[rows, :, :3]
        dt = tau - tau_a
        los = c[:, 0] + (c[:, 1] + c[:, 2] * dt) * dt - r
        E = los / np.linalg.norm(los, axis=1)[:, None]
        H = np.hstack([-E, np.ones((len(E), 1))])
        if self.isb_systems:            # one inter-system bias column per other system among them
            letters = [self._signal(prns[i])[0].system for i in rows]
            extra = [c for c in self.isb_systems if c in letters]
            if extra:
                H = np.hstack([H, np.array([[float(c == x) for x in extra] for c in letters])])
            if len(rows) < H.shape[1]:
                return (np.nan,) * 4
        try:
            Qm = np.linalg.inv(H.T @ H)
        except np.linalg.LinAlgError:
            return (np.nan,) * 4
        R = enu_matrix(lat, lon)
        qe = R @ Qm[:3, :3] @ R.T
        return (float(np.sqrt(np.trace(qe))), float(np.sqrt(qe[0, 0] + qe[1, 1])),
                float(np.sqrt(qe[2, 2])), float(np.sqrt(np.trace(Qm))))
