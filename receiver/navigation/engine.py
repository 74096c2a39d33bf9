"""Navigation engine: channel-epoch records -> LNAV bits -> transmit times -> observables -> fixes.

The engine is fed the records of every channel chunk by chunk (``add_records``) and produces fixes and
observables for all navigation epochs that every active channel has passed (``update``).

Each satellite's memory (bits, decoder, transmit-time reference, smoothed observables) is a
:class:`receiver.navigation.channel.ChannelNav`; ephemerides and ionospheric parameters come through
:class:`receiver.navigation.ephemeris_store.EphemerisStore`.

Time keeping
------------
* Transmit times: see receiver.navigation.channel.
* Receiver clock: sample counter.  Before the first fix, ``rx_tow = tow0 + (s - s0) / fs`` with tow0
  guessed from a 75 ms travel time; the first fix corrects tow0 by the estimated clock bias.  After the
  first fix the navigation epochs are placed (at fractional sample positions) where the predicted GPS time is
  a multiple of 1/rate, so fixes and observables fall on round GPS times.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from ..gnss.geodesy import ecef2lla
from ..runfile.record import FIX_DTYPE, OBS_DTYPE, fix_row
from ..gnss.signals import C_LIGHT
from . import assisted_search
from .channel import BIT_MS, ChannelNav, common_slope
from .ephemeris_store import EphemerisStore
from .config import default
from .pvt import Aiding, NavSolver, Observation, vnorm
from .pvt_filter import make_pvt_filter
from .lookahead import FixedLag

DEEP_ORBIT_SQRT_A = 6000.0    # sqrt(m): a GEO or IGSO orbit (BeiDou; ~6493), not a MEO (GPS ~5154, BeiDou ~5282)
AID_WINDOW_S = 1.0          # the constraints are predicted from the unaided fixes of this last span
AID_REF_SATS = 5            # ... and from the unaided solutions of aided epochs with this many satellites
FIRST_EPH_RANGE_M = 200.0   # a satellite's first decoded ephemeris whose range disagrees with the current fix by
FIRST_EPH_FIX_AGE_S = 30.0  # more than this (fix at most this old) is used only after a second reception



def first_ephemeris_range_error(eph, tx_tow: float, rx_gps_tow: float, rx_ecef) -> float:
    """Measured minus predicted range (m) of a satellite: the range measured from its transmit time (satellite
    clock, s of week) and the receiver's true GPS time, against the geometric range from the ephemeris to the
    receiver position (Earth rotation during the travel time applied).  Atmosphere and receiver noise leave
    tens of metres; a corrupted ephemeris (a miscorrected LNAV word) kilometres."""
    from ..gnss.ephemeris import earth_rotation, sat_state
    from ..gnss.time import wrap_week_seconds
    pos, _, clk, _ = sat_state(eph, tx_tow)
    rx = np.asarray(rx_ecef, float)
    measured = C_LIGHT * (float(wrap_week_seconds(rx_gps_tow - tx_tow)) + float(clk))
    tau = 0.075
    for _ in range(2):
        rho = float(np.linalg.norm(earth_rotation(np.asarray(pos, float), tau) - rx))
        tau = rho / C_LIGHT
    return measured - rho


class NavigationEngine(EphemerisStore):
    """Navigation of a run (see the module docstring): per-channel navigation state (ChannelNav, keyed by PRN
    or, for several signals, by receiver.gnss.satid.sat_key), receiver time, fixes at ``navigation.rate_hz``
    with the WLS solver or the PVT filter, and aiding from the recent unaided fixes."""
    def __init__(self, nav_cfg, fs: float, if_hz: float, first_sample: int, ephemerides=None,
                 iono_utc=None, week_hint: int | None = None, approx_tow0: float | None = None, signal=None,
                 signals=None):
        self.cfg = nav_cfg
        self.fs = fs
        self.if_hz = if_hz
        self.solver = NavSolver(nav_cfg)
        # C/N0 (dB-Hz) from which a channel's loss is seen by the tracking's signal-presence test (None: off)
        self.presence_cn0 = None
        self.pvt_filter = make_pvt_filter(nav_cfg)     # navigation.filter ekf|ckf (None: wls)
        self.channels: dict[int, ChannelNav] = {}
        self.signal = signal                # SignalDef of the channels (None: GPS L1 C/A)
        # a run over several signals: RINEX letter of the signal -> (SignalDef, IF Hz of its stream); the
        # channels are then keyed by receiver.gnss.satid.sat_key and the fixes solve an inter-system bias
        self.signals = dict(signals) if signals else None
        self.assisted = ephemerides is not None
        self.rinex_ephs = ephemerides or {}
        self.iono_utc = iono_utc            # the RINEX header's Klobuchar / UTC set (assisted mode), or None
        self.iono_fallback = None           # navigation.klobuchar_fallback: used while no broadcast set is known
        if getattr(nav_cfg, "ionosphere", default("ionosphere")) == "klobuchar" and \
                getattr(nav_cfg, "klobuchar_fallback", default("klobuchar_fallback")):
            from ..gnss.atmosphere import FALLBACK_KLOBUCHAR_ALPHA, FALLBACK_KLOBUCHAR_BETA
            from ..gnss.ephemeris import IonoUtc
            self.iono_fallback = IonoUtc(alpha=FALLBACK_KLOBUCHAR_ALPHA, beta=FALLBACK_KLOBUCHAR_BETA)
        self.week_hint = week_hint
        self.rate = nav_cfg.rate_hz
        self.next_s = float(first_sample + int(round(fs / self.rate)))
        self.tow0 = None            # rx_tow at sample s0
        self.s0 = None
        self.last_fix = None        # (sample, Fix)
        self._first_fix_search = assisted_search.Retries()
        self.epoch = 0
        self.x0 = None
        self.aid_cfg = getattr(nav_cfg, "aiding", None)
        if self.aid_cfg is not None and not self.aid_cfg.enabled:
            self.aid_cfg = None
        # (t_s, clock bias m, drift m/s, height m, up speed m/s, TDOP, VDOP) of unaided fixes
        self.aid_hist = deque()
        self.n_aided = 0
        self.first_eph_checks = []  # (prn, receiver time s, range error m) of first ephemerides checked
        # assisted mode: approximate GPS TOW of file sample 0 (input.start_gps_tow_s) lets transmit times
        # be resolved from bit synchronisation alone, before any subframe has been decoded
        self.approx_tow0 = approx_tow0
        self.fixed_lag = FixedLag.for_run(nav_cfg, self.solver, self.aid_cfg, self.pvt_filter, fix_row)
        self._la_ctx = self._la_aid = None

    def channel(self, prn: int) -> ChannelNav:
        """The ChannelNav of channel key ``prn`` (created on first use, with its first-ephemeris check)."""
        if prn not in self.channels:
            if self.signals:
                from ..gnss.satid import split_key
                letter, sig_prn = split_key(prn)
                sig, if_hz = self.signals[letter]
                ch = self.channels[prn] = ChannelNav(prn, self.week_hint, if_hz, self.fs, sig, sig_prn)
            else:
                ch = self.channels[prn] = ChannelNav(prn, self.week_hint, self.if_hz, self.fs, self.signal)
            ch.decoder.first_check = lambda eph, tow, bit_index, ch=ch: self._first_ephemeris_ok(
                ch, eph, tow, bit_index)
        return self.channels[prn]

    def _first_ephemeris_ok(self, ch: ChannelNav, eph, tow: float, bit_index: int):
        """A satellite's first decoded ephemeris against the current fix (LnavDecoder.first_check): False when
        the range it predicts for the channel's latest measurement differs from the measured one by more than
        FIRST_EPH_RANGE_M (the decoder then waits for a second reception of the same set); None (no opinion)
        without a fix of at most FIRST_EPH_FIX_AGE_S or a measurement."""
        if self.last_fix is None or ch.bit_offset < 0 or ch.last_sample < 0:
            return None
        s = float(ch.last_sample)
        m = ch.measure(s)
        s_fix, fix = self.last_fix
        dt = (s - s_fix) / self.fs
        if m is None or not 0.0 <= dt <= FIRST_EPH_FIX_AGE_S:
            return None
        rx = np.asarray(fix.ecef, float)
        v = np.asarray(fix.velocity_ecef, float)
        if np.all(np.isfinite(v)):
            rx = rx + v * dt
        tx = tow - (ch.bit_offset + ch.bit_ms * bit_index) * 1e-3 + m[0]
        err = first_ephemeris_range_error(eph, tx, self.gps_time(s), rx)
        self.first_eph_checks.append((ch.prn, s / self.fs, err))
        return abs(err) <= FIRST_EPH_RANGE_M

    def add_records(self, prn: int, recs, bit_offset: int, dll_hold_s: float = 0.0):
        """Feed a chunk of channel ``prn``'s epoch records (EPOCH_DTYPE) with its bit offset (code period of
        bit 0, -1 unknown) to its ChannelNav (ChannelNav.add); dll_hold_s: the tracking channel's DLL keeps a
        wider bandwidth this long after its pull-in (its measurements settle after that)."""
        self.channel(prn).add(recs, bit_offset, dll_hold_s)

    def set_noncoherent(self, prn: int, from_sample):
        """Channel prn is frequency-locked from from_sample on (None: phase-locked again)."""
        self.channel(prn).set_noncoherent(from_sample)

    def suspend(self, prn: int):
        """prn's channel lost the signal: its navigation memory stays (ephemeris, transmit-time reference)."""
        if prn in self.channels:
            self.channels[prn].suspend()

    def resume(self, prn: int, continuous: bool, settle_s: float | None = None):
        """A new channel tracks prn (see ChannelNav.resume)."""
        if prn in self.channels:
            self.channels[prn].resume(continuous, settle_s)

    def drop(self, prn: int):
        """Forget prn entirely (its memory too); the pipeline uses suspend/resume instead."""
        self.channels.pop(prn, None)

    def gps_time(self, s: float):
        """Predicted GPS time at sample s from the last fix (None before the first fix)."""
        if self.last_fix is None:
            return None
        s_fix, fix = self.last_fix
        return fix.gps_tow + (s - s_fix) / self.fs * (1 - fix.clock_drift_mps / C_LIGHT)

    def satellite_los(self, prn: int, s: float):
        """(range rate m/s of a receiver standing at the last fix, elevation deg, range m) of prn at sample s,
        from its ephemeris; None without a fix or an ephemeris."""
        from ..gnss.ephemeris import sat_state
        t = self.gps_time(s)
        if t is None:
            return None
        eph = self.ephemeris(prn, t)
        if eph is None:
            return None
        _, fix = self.last_fix
        pos, vel, _, _ = sat_state(eph, t - 0.075)
        d = np.asarray(pos, float) - np.asarray(fix.ecef, float)
        rng = vnorm(d)
        u = d / rng
        up = np.asarray(fix.ecef, float) / vnorm(fix.ecef)     # geocentric (within 0.2 deg)
        el = math.degrees(math.asin(max(-1.0, min(1.0, float(u @ up)))))
        return float(u @ np.asarray(vel, float)), el, rng

    def update(self, up_to_sample: int):
        """Fixes and observables for all navigation epochs before up_to_sample (all channels passed)."""
        done = []
        active = [ch for ch in self.channels.values() if ch.active and ch.last_sample >= 0]
        if not active:
            return np.zeros(0, FIX_DTYPE), np.zeros(0, OBS_DTYPE)
        horizon = min(up_to_sample, min(ch.last_sample for ch in active))
        while self.next_s <= horizon:
            s = self.next_s
            self._la_ctx = self._la_aid = None
            f, o = self._epoch(s)
            if self.fixed_lag is None:
                done.append((f, o))
            else:
                done += self.fixed_lag.hold(s / self.fs, f, o, self._la_ctx)
            self._advance()
        return self._arrays(done)

    def flush(self):
        """The fixes and observables still held for navigation.lookahead_s (at the end of the input)."""
        return self._arrays(self.fixed_lag.release() if self.fixed_lag is not None else [])

    @staticmethod
    def _arrays(pairs):
        """FIX_DTYPE and OBS_DTYPE arrays of [(fix row or None, observable rows), ...]."""
        fixes = [f for f, _ in pairs if f is not None]
        obs = [r for _, o in pairs for r in o]
        fa = np.zeros(len(fixes), FIX_DTYPE)
        for i, f in enumerate(fixes):
            fa[i] = f
        oa = np.zeros(len(obs), OBS_DTYPE)
        for i, o in enumerate(obs):
            oa[i] = o
        return fa, oa

    def _advance(self):
        step = 1.0 / self.rate
        if self.last_fix is None:
            self.next_s += self.fs * step
            return
        s_fix, fix = self.last_fix
        # the round GPS time after the one nearest the current epoch (0.5-1.5 steps ahead: an epoch that
        # lands a little before its round time -- a first fix anywhere, a clock running slow -- is not
        # followed by a second fix a few microseconds later), mapped to a sample with the estimated drift
        t_now = fix.gps_tow + (self.next_s - s_fix) / self.fs * (1 - fix.clock_drift_mps / C_LIGHT)
        t_next = (math.floor(t_now * self.rate + 0.5) + 1) / self.rate
        scale = self.fs / (1 - fix.clock_drift_mps / C_LIGHT)
        self.next_s = s_fix + (t_next - fix.gps_tow) * scale

    def _resolve_assisted(self, s: float):
        """Give transmit times to bit-synchronised channels without frame sync (assisted mode).

        First fix: the 20 ms ambiguity of every channel is fixed jointly by trying common travel times
        of 60..95 ms at the approximate receiver time, then travel times predicted from a rough position
        (receiver.navigation.assisted_search), and keeping the assignment whose least-squares fix (clock bias
        within 10 ms, no satellite rejected) uses the most satellites, then has the smallest residuals; the
        satellites it used get their offsets.  Later channels: the ambiguity is taken from the current fix.
        Frame sync, when it comes, replaces (and checks) the assisted value."""
        from ..gnss.ephemeris import select
        pending = [ch for ch in self.channels.values()
                   if not ch.has_time and ch.bit_offset >= 0 and ch.locked
                   and ch.settled(s, self.cfg.settle_s)]
        if not pending:
            return
        if self.last_fix is not None:
            self._resolve_from_fix(s, pending)
            return
        if len(pending) < 5 or not self._first_fix_search.due(s / self.fs):
            return
        T = self.approx_tow0 + s / self.fs
        week = self._week()
        if week is None:
            return
        best = None
        tried = set()          # travel times that give the same 20-ms assignments give the same fix
        # BeiDou GEO/IGSO satellites (orbit radius ~42 000 km) are 119-138 ms away, MEO (and GPS) 67-90 ms: a
        # second common travel time for them (GPS: none, the search is the one-dimensional one)
        cand = []              # (channel, ephemeris, relative transmit time) of the channels with a measurement
        for ch in pending:
            if ch.bit_ms < BIT_MS:
                continue       # BeiDou D2 (GEO): 2-ms symbols, no common travel time resolves them (frame sync)
            m = ch.measure(s) if ch.bit_offset >= 0 else None
            e = select(self.rinex_ephs[ch.prn], T) if ch.prn in self.rinex_ephs else None
            if m is not None and e is not None:
                cand.append((ch, e, m[0]))
        deep = {ch.prn for ch, e, _ in cand if getattr(e, "sqrt_a", 0.0) > DEEP_ORBIT_SQRT_A}
        for guess in assisted_search.guesses(cand, T, deep):      # (common, then predicted travel times)
            offs, obs = {}, []
            for ch, _, txrel in cand:
                off = ch.offset_nearest(guess[ch.prn], txrel)
                offs[ch.prn] = off
                obs.append(Observation(prn=ch.prn, tx_tow=off + txrel, cn0_dbhz=ch.cn0, system=ch.signal.system))
            key = tuple(offs.items())
            if len(obs) < 5 or key in tried:
                continue
            tried.add(key)
            ephs = {o.prn: select(self.rinex_ephs[o.prn], T) for o in obs}
            fix = self.solver.fix(week, T, obs, ephs, self.iono(), learn=False)
            # a common 20 ms shift of every transmit time fits almost as well (only the satellites'
            # along-track motion differs) but needs a 20 ms clock bias: input.start_gps_tow_s must be
            # within +/-10 ms for the search to pick the right assignment
            if fix is None or fix.rejected_prns or fix.n_sats < 5 or \
                    abs(fix.clock_bias_m) > 0.01 * C_LIGHT:
                continue
            # the most satellites, then the smallest residuals: a wrong assignment puts the fix where few
            # satellites are above the elevation mask, and the few left fit any position
            rms = float(np.sqrt(np.mean(np.square(fix.residuals_m))))
            if best is None or (fix.n_sats, -rms) > (len(best[2]), -best[0]):
                best = (rms, offs, fix.prns)
        found = best is not None and best[0] < 100.0
        self._first_fix_search.done(s / self.fs, found)
        if found:
            # only the satellites the fix used (and so checked); the others (e.g. below the elevation mask)
            # take theirs from the fix at the next epoch (_resolve_from_fix)
            for prn in best[2]:
                self.channels[prn].set_assisted_offset(best[1][prn])

    def _resolve_from_fix(self, s: float, pending=None):
        """Transmit times of bit-synchronised channels without one, from the range predicted with the last
        fix (receiver position and clock) and the satellite's ephemeris: the 20-ms ambiguity is the multiple of
        20 ms (bit edges) nearest the prediction (valid while the prediction is within +/-10 ms, i.e. the
        receiver within ~3000 km of the last fix).  Frame sync, when it comes, checks it."""
        from ..gnss.ephemeris import sat_state
        if pending is None:
            pending = [ch for ch in self.channels.values()
                       if ch.active and not ch.has_time and ch.bit_offset >= 0 and ch.locked
                       and ch.settled(s, self.cfg.settle_s)]
        if not pending:
            return
        s_fix, fix = self.last_fix
        rx_tow = self.tow0 + (s - self.s0) / self.fs
        ephs = self._ephemerides(rx_tow)
        for ch in pending:
            eph = ephs.get(ch.prn)
            if eph is None:
                continue
            pos = sat_state(eph, self.gps_time(s) - 0.075)[0]
            rng = vnorm(np.asarray(pos, float) - np.asarray(fix.ecef, float))
            guess = rx_tow - (rng + fix.clock_bias_m) / C_LIGHT
            off, _ = ch.offset_candidates(s, guess)
            if off is not None:
                ch.set_assisted_offset(off)

    def _remember(self, t_s: float, fix):
        """Keep an unaided fix's clock and height for the constraints of later aided fixes."""
        if fix.aiding or (self.aid_hist and t_s <= self.aid_hist[-1][0]) or \
                not (np.isfinite(fix.clock_drift_mps) and np.all(np.isfinite(fix.velocity_ecef))):
            return
        lat, lon, h = ecef2lla(fix.ecef)
        from ..gnss.geodesy import enu_matrix
        v_up = float(enu_matrix(float(lat), float(lon))[2] @ np.asarray(fix.velocity_ecef, float))
        tdop = math.sqrt(max(fix.gdop ** 2 - fix.pdop ** 2, 1e-6))
        self.aid_hist.append((t_s, fix.clock_bias_m, fix.clock_drift_mps, float(h), v_up, tdop, fix.vdop))
        while self.aid_hist and self.aid_hist[0][0] < t_s - AID_WINDOW_S:
            self.aid_hist.popleft()

    def _aiding(self, t_s: float) -> Aiding | None:
        """Clock-bias (and drift) and height constraints predicted at receiver time t_s from the unaided fixes
        of the last AID_WINDOW_S before the latest one (each extrapolated with its own drift / vertical speed,
        weighted by 1/TDOP^2 resp. 1/VDOP^2); the standard deviations grow with the age of the latest
        unaided fix (clock: a random-walk frequency, sigma ~ age^1.5; height: a vertical speed error).
        None: aiding off or the latest unaided fix older than navigation.aiding.max_age_s."""
        c = self.aid_cfg
        if c is None or not self.aid_hist:
            return None
        age = t_s - self.aid_hist[-1][0]
        if age > c.max_age_s or age < 0:
            return None
        h = np.array(self.aid_hist)
        dt = t_s - h[:, 0]
        aid = Aiding(code_sigma_m=c.code_sigma_m, residual_threshold_m=c.residual_threshold_m,
                     max_pdop=getattr(c, "max_pdop", default("aiding.max_pdop")),
                     rate_sigma_mps=c.rate_sigma_mps)
        w = 1.0 / h[:, 5] ** 2
        # the drift: the velocity of a fix from 3 Dopplers needs it (and the epoch placement a finite drift)
        aid.drift_mps = float(np.sum(w * h[:, 2]) / np.sum(w))
        aid.drift_sigma_mps = math.hypot(c.drift_sigma_mps, 1.5 * c.clock_growth * age ** 0.5)
        if c.clock:
            aid.clock_m = float(np.sum(w * (h[:, 1] + h[:, 2] * dt)) / np.sum(w))
            aid.clock_sigma_m = math.hypot(c.clock_sigma_m, c.clock_growth * age ** 1.5)
        if c.height:
            w = 1.0 / h[:, 6] ** 2
            aid.height_m = float(np.sum(w * (h[:, 3] + h[:, 4] * dt)) / np.sum(w))
            aid.height_sigma_m = math.hypot(c.height_sigma_m, c.height_rate_mps * age)
        return aid if aid.count() else None

    def _solve(self, week, rx_tow, t_s, observations, ephs):
        """The epoch's fix: unaided from >= 4 satellites; aided (navigation.aiding) when at most
        aiding.max_sats satellites are measured or the unaided fix is refused (weak geometry), e.g. from 3."""
        n = len(observations)
        fix = None
        if n >= 4:
            fix = self.solver.fix(week, rx_tow, observations, ephs, self.iono(), x0=self.x0)
        if self.last_fix is None:
            # the first fix: nothing before it checks it, and it starts the aiding and the filters
            return fix if fix is not None and fix.pdop <= self.cfg.first_fix_max_pdop else None
        if fix is not None and n > self.aid_cfg.max_sats:
            return fix
        if fix is not None and fix.n_sats >= AID_REF_SATS:
            self._remember(t_s, fix)        # over-determined on its own: a reference for the prediction
        aid = self._aiding(t_s)
        if aid is None:
            return fix
        aided = self.solver.fix(week, rx_tow, observations, ephs, self.iono(), x0=self.x0, aid=aid)
        self._la_aid = aid if aided is not None else None
        return aided if aided is not None else fix

    def _epoch(self, s: float):
        if self.assisted and self.approx_tow0 is not None:
            self._resolve_assisted(s)
        elif self.last_fix is not None:
            self._resolve_from_fix(s)
        meas = {}
        dt = 1.0 / self.rate
        window = int(round(self.cfg.smoothing_s * self.rate))
        for prn, ch in self.channels.items():
            # (a lock gap keeps the carrier-smoothing fit: ChannelNav.smooth_update decides on the next epoch)
            if not ch.settled(s, self.cfg.settle_s):
                ch.hatch = None
                continue
            if not ch.locked_at(s, presence_cn0=self.presence_cn0):
                continue
            m = ch.measure_track(s)
            if m is None:
                ch.hatch = None
                continue
            ch.smooth_update(s, m[0], m[2], window, m[3], ch.cn0_at(s))
            if not ch.has_time:
                continue
            prev = ch.measure_track(s - dt * self.fs)
            dop = (m[2] - prev[2]) / dt if prev is not None and prev[3] == m[3] else m[1]
            meas[prn] = (m, dop, ch)
        # common code-minus-carrier drift (clock-rate mismatch between code and carrier), weighted
        slope = common_slope([i for i in (ch.slope_info() for ch in self.channels.values()) if i is not None])
        unsmoothed = {}             # unsmoothed minus smoothed pseudorange (m), for navigation.filter ekf/ckf
        raw = {}                    # navigation.lookahead_s: each satellite's raw code and its smoothing fit
        for prn, (m, dop, ch) in list(meas.items()):
            txrel = ch.smooth_value(s, m[0], m[2], slope)
            meas[prn] = ((ch.tx_offset + txrel, dop, m[2]), ch)
            unsmoothed[prn] = C_LIGHT * (txrel - m[0])
            raw[prn] = (ch, s, m[0], m[2], txrel, ch.hatch)
        if len(meas) < (3 if self.aid_cfg is not None and self.last_fix is not None else 4):
            return None, []
        if self.tow0 is None:
            if self.approx_tow0 is not None:
                # receiver clock = nominal start time + sample count: clock_bias_m is then the receiver
                # clock error against the recording's time stamp (comparable with simulator truth)
                self.tow0, self.s0 = self.approx_tow0, 0.0
            else:
                self.tow0 = max(m[0] for m, _ in meas.values()) + 0.075
                self.s0 = s
        rx_tow = self.tow0 + (s - self.s0) / self.fs
        week = self._week()
        ephs = self._ephemerides(rx_tow)
        observations = [Observation(prn=prn, tx_tow=m[0], doppler_hz=m[1], cn0_dbhz=ch.cn0,
                                    carrier_phase_cycles=m[2], wavelength_m=ch.wavelength,
                                    system=ch.signal.system)
                        for prn, (m, ch) in sorted(meas.items()) if prn in ephs]
        fix = None
        if week is not None:
            if self.aid_cfg is None:
                if len(observations) >= 4:
                    fix = self.solver.fix(week, rx_tow, observations, ephs, self.iono(), x0=self.x0)
            else:
                fix = self._solve(week, rx_tow, s / self.fs, observations, ephs)
        if fix is None:
            return None, []
        if self.last_fix is None and (self.approx_tow0 is None or abs(fix.clock_bias_m) > C_LIGHT):
            # first fix: take the clock bias out of the receiver time and solve again
            self.tow0 -= fix.clock_bias_m / C_LIGHT
            rx_tow = self.tow0 + (s - self.s0) / self.fs
            fix = self.solver.fix(week, rx_tow, observations, ephs, self.iono(), x0=fix.ecef)
            if fix is None:
                return None, []
        self.x0 = fix.ecef
        if self.last_fix is None or np.isfinite(fix.clock_drift_mps):    # epoch placement needs the drift
            self.last_fix = (s, fix)
        t_s = s / self.fs
        if self.aid_cfg is not None:
            if not fix.aiding:
                self._remember(t_s, fix)
            self.n_aided += bool(fix.aiding)
        # ekf/ckf: filtered position/velocity/clock (started at the first fix, after the clock re-basing);
        # epoch placement, x0 and the observables stay on the WLS fix
        out = self.pvt_filter.step(t_s, fix, unsmoothed) if self.pvt_filter is not None else fix
        row = fix_row(out, fix, t_s, self.iono_params())
        used = set(fix.prns)
        el = dict(zip(fix.prns, fix.elevations_deg))
        az = dict(zip(fix.prns, fix.azimuths_deg))
        res = dict(zip(fix.prns, fix.residuals_m))
        obs_rows = []
        for o in observations:
            ch = meas[o.prn][1]
            pr = (rx_tow - o.tx_tow) * C_LIGHT
            obs_rows.append((self.epoch, fix.gps_week, fix.gps_tow, t_s, o.prn, pr,
                             -o.doppler_hz * ch.wavelength, o.doppler_hz, o.carrier_phase_cycles, o.cn0_dbhz,
                             t_s - (ch.lock_start_s if ch.lock_start_s is not None else t_s),
                             1 if ch.polarity != 0 else 0, 1 if o.prn in used else 0,
                             el.get(o.prn, np.nan), az.get(o.prn, np.nan), res.get(o.prn, np.nan)))
        self.epoch += 1
        if self.fixed_lag is not None:      # (what solving this epoch again later needs)
            self._la_ctx = (week, rx_tow, observations, ephs, self.iono(), fix, raw, self._la_aid)
        return row, obs_rows
