"""Navigation engine: channel-epoch records -> LNAV bits -> transmit times -> observables -> fixes.

The engine is fed the records of every channel chunk by chunk (``add_records``) and produces fixes and
observables for all navigation epochs that every active channel has passed (``update``).

Time keeping
------------
* Transmit time of a record's first sample: frame sync ties bit ``b`` of a channel to GPS TOW, so the code
  period ``bit_offset + 20 b`` started at that TOW; a record then transmits
  ``tow_ref + (code_period - cp_ref) * 1 ms + code_phase_chips / 1.023 MHz`` (satellite clock).
* Receiver clock: sample counter.  Before the first fix, ``rx_tow = tow0 + (s - s0) / fs`` with tow0
  guessed from a 75 ms travel time; the first fix corrects tow0 by the estimated clock bias.  After the
  first fix the navigation epochs are placed (at fractional sample positions) where the predicted GPS time is
  a multiple of 1/rate, so fixes and observables fall on round GPS times.
"""
from __future__ import annotations

import math
from bisect import bisect_right
from collections import deque

import numpy as np

from ..gnss.geodesy import ecef2lla
from ..runfile.record import FIX_DTYPE, OBS_DTYPE, IONO_BROADCAST, IONO_FALLBACK, IONO_NONE
from ..runfile.record import STATE_BIT_SYNC
from ..gnss.signals import C_LIGHT, GPS_L1CA
from ..gnss.lnav import LnavDecoder, SubframeEvent
from .bits_jit import bit_segments
from .config import default
from .pvt import Aiding, NavSolver, Observation, vnorm
from .pvt_filter import make_pvt_filter

BIT_MS = 20
DEEP_ORBIT_SQRT_A = 6000.0    # sqrt(m): a GEO or IGSO orbit (BeiDou; ~6493), not a MEO (GPS ~5154, BeiDou ~5282)
LOCK_GUARD_S = 0.1           # a measurement needs lock this long after its epoch too (detector lag)
LOCK_GUARD_PRESENT_S = 0.04  # the same for a channel judged by the signal-presence test (lock gone <= 35 ms)
PRESENCE_MARGIN_DB = 3.0     # ... i.e. its C/N0 this far above tracking.presence.min_cn0_dbhz
SLOPE_OUTLIER_MPS = 2.0     # channels' code-minus-carrier drifts this far from the weighted median: not common
ROT_KEEP = 0.8              # decay per bit of the rotation estimate (about 5 bits, 100 ms)
MODE_AIDED = 3              # FIX_DTYPE mode of a scalar fix that used clock/height constraints (navigation.aiding)
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


def common_slope(info):
    """The common code-minus-carrier drift (m/s) from the channels' (slope, weight) pairs: their weighted mean,
    without the channels whose own drift is more than SLOPE_OUTLIER_MPS from the weighted median (when more
    than two): such a channel does not measure the common clock-rate mismatch -- a cross-correlation lock, whose
    code and carrier follow different signals (a B1I IGSO channel held at the GEO satellites' Doppler drifted
    -67 m/s and pulled every smoothed pseudorange of the run by up to 60 m).  None without channels."""
    if not info:
        return None
    w = np.array([i[1] for i in info], float)
    v = np.array([i[0] for i in info], float)
    if len(v) > 2:
        o = np.argsort(v, kind="stable")
        med = float(v[o][min(int(np.searchsorted(np.cumsum(w[o]), 0.5 * np.sum(w))), len(v) - 1)])
        keep = np.abs(v - med) <= SLOPE_OUTLIER_MPS
        w, v = w[keep], v[keep]
    return float(np.sum(w * v) / np.sum(w))


def _columns(recs) -> tuple:
    """(recs, sample_index, code_period, code_phase_chips, code_rate_hz, doppler_hz, carrier_phase_cycles,
    pll_lock, cn0_dbhz) of channel records, the columns as Python lists (exact: int64 -> int, float64 ->
    float, float32 -> the same value as a float)."""
    return (recs,) + tuple(recs[k].tolist() for k in (
        "sample_index", "code_period", "code_phase_chips", "code_rate_hz", "doppler_hz", "carrier_phase_cycles",
        "pll_lock", "cn0_dbhz"))


class ChannelNav:
    """One satellite's navigation memory and its current track's bit assembly.

    The object lives as long as the run (it is never dropped with a channel): the LNAV decoder (decoded
    ephemeris, iono/UTC, week, frame alignment) and the transmit-time reference (``tow_ref`` at code period
    ``cp_ref``, the channel's code-period count) survive a loss of signal.  ``suspend`` marks the satellite
    untracked; ``resume`` starts a new track: when the new channel continues the old channel's code-period
    count (hot/warm re-acquisition from the predicted transmit time, receiver.tracking.channels) the bit
    alignment and the transmit-time reference stay valid and pseudoranges resume after the new track's pull-in
    and ``settle_s``, without waiting for a subframe; the next decoded subframe checks them
    (``time_mismatches``).  Otherwise the transmit time is resolved again from the predicted range
    (:meth:`NavigationEngine._resolve_from_fix`) or frame sync.
    """

    def __init__(self, prn: int, week_hint: int | None, if_hz: float, fs: float, signal=None,
                 sig_prn: int | None = None):
        self.prn = prn              # the engine's key (a run over several signals: receiver.gnss.satid.sat_key)
        self.sig_prn = prn if sig_prn is None else sig_prn     # the signal's PRN (code, message type)
        sig = signal if signal is not None else GPS_L1CA
        self.signal = sig
        self.bit_ms = sig.bit_ms(self.sig_prn)    # LNAV / BeiDou D1: 20 ms; BeiDou D2: 2 ms
        self.chip_rate = sig.chip_rate
        self.wavelength = C_LIGHT / sig.carrier_hz
        self.decoder = self._new_decoder(week_hint)
        self.if_hz = if_hz
        self.fs = fs
        self.bit_offset = -1
        self.cur_bit = None
        self.cur_ms = 0
        self.cp_ref = None          # code period at the start of a subframe with known TOW
        self.tow_ref = None
        self.polarity = 0
        self.recent = deque()       # recent records (for interpolation at navigation epochs)
        self.recent_track = deque()  # the track (self.tracks) each of them belongs to
        self._cols = {}             # id(records) -> _columns(records) of those in recent
        self.last_sample = -1
        self.lock_start_s = None
        self.locked = False
        self.hatch = None           # carrier-smoothing state
        self.time_assisted = False  # transmit time resolved without frame sync (assisted mode)
        self.track_start_s = None   # end of the pull-in (receiver time)
        self.time_mismatches = 0
        # frequency-locked (vector) tracking from this sample on: bits by differential detection
        self.noncoherent_from = None
        self.cur_a = self.cur_b = 0j    # prompt sums over the first / second half of the current bit
        self.cur_nc = False         # the current bit has frequency-locked epochs
        self.prev_bit = None        # (bit index, second-half sum, soft value) of the last complete bit
        self.rot = 0j               # phase rotation over 10 ms (sum of B conj(A), decaying)
        self.cn0 = 0.0
        self.active = True          # a channel tracks this satellite
        self.settle_s = None        # settle time of the current track (None: navigation.settle_s)
        self.tracks = 1             # tracks (channels) of this satellite so far
        self.prev_track = None      # (track_start_s, settle_s, last sample) of the previous track (resume)
        self.resumed_with_time = 0  # re-acquisitions that kept the transmit-time reference

    def _new_decoder(self, week_hint):
        """LNAV for L1 C/A (GPS, QZSS); D1/D2 for BeiDou B1I (receiver.gnss.bds_nav)."""
        if self.signal.system == "C":
            from ..gnss.bds_nav import BdsDecoder
            return BdsDecoder(self.sig_prn, week_hint=week_hint, geo=self.bit_ms != BIT_MS)
        return LnavDecoder(self.sig_prn, week_hint=week_hint)

    def suspend(self):
        """The channel lost the signal: keep the memory; the track's records stay for the epochs before the
        loss that are not computed yet (the channel manager handles losses before the chunk's navigation
        epochs); measure() returns nothing beyond them."""
        self.active = False
        self.locked = False
        self.hatch = None

    def resume(self, continuous: bool, settle_s: float | None = None):
        """A new channel tracks this satellite.  continuous: it continues the old channel's code-period
        count (same bit offset, transmit-time reference still valid)."""
        self.active = True
        self.tracks += 1
        keep = continuous and self.has_time
        # a continuous track keeps the old records (same code-period count, same transmit-time reference)
        # for the not yet computed epochs before the loss; they are judged by the old track's settle state
        self.prev_track = (self.track_start_s, self.settle_s, self.last_sample) if keep and self.recent else None
        if not keep:
            self.recent.clear()
            self.recent_track.clear()
            self._cols = {}
        self.last_sample = -1
        self.track_start_s = None
        self.lock_start_s = None
        self.locked = False
        self.hatch = None
        self.cur_bit, self.cur_ms, self.cur_nc = None, 0, False
        self.cur_a = self.cur_b = 0j
        self.prev_bit = None
        self.rot = 0j
        self.noncoherent_from = None
        self.settle_s = settle_s
        self.polarity = 0           # a re-locked PLL may sit on the other half cycle: the next subframe says
        if continuous and self.has_time:
            self.time_assisted = True       # verified by the next subframe
            self.resumed_with_time += 1
        else:
            self.cp_ref = self.tow_ref = None
            self.time_assisted = False
            self.bit_offset = -1
            old = self.decoder              # bit indices restart: new frame sync, same decoded data
            self.decoder = self._new_decoder(old.week_hint)
            self.decoder.ephemeris, self.decoder.iono_utc, self.decoder.week = \
                old.ephemeris, old.iono_utc, old.week
            self.decoder.parity_failures = old.parity_failures
            self.decoder.first_check = getattr(old, "first_check", None)

    def set_assisted_offset(self, tx_offset: float):
        """Transmit-time offset found by the assisted ambiguity search (until frame sync confirms)."""
        self.cp_ref = 0
        self.tow_ref = tx_offset
        self.time_assisted = True

    def offset_candidates(self, s: float, tx_guess: float):
        """tx_offset making the transmit time at sample s nearest tx_guess, given bit synchronisation:
        bit edges are transmitted at multiples of the bit duration (20 ms; BeiDou D2 2 ms) of GPS time."""
        m = self.measure(s)
        if m is None or self.bit_offset < 0:
            return None, None
        return self.offset_nearest(tx_guess, m[0]), m[0]

    def offset_nearest(self, tx_guess: float, txrel: float) -> float:
        """:meth:`offset_candidates` for a measured relative transmit time txrel."""
        base = -self.bit_offset * 1e-3
        tb = self.bit_ms * 1e-3
        k = round((tx_guess - txrel - base) / tb)
        return base + tb * k

    def add(self, recs: np.ndarray, bit_offset: int):
        if len(recs) == 0:
            return
        self.recent.append(recs)
        self.recent_track.append(self.tracks)
        while len(self.recent) > 3:
            self.recent.popleft()
            self.recent_track.popleft()
        self._cols = {id(r): self._cols.get(id(r)) or _columns(r) for r in self.recent}
        self.last_sample = int(recs["sample_index"][-1])
        if self.track_start_s is None:
            st = np.flatnonzero(recs["state"] != 0)          # first epoch after the FLL pull-in
            if len(st):
                self.track_start_s = float(recs["time_s"][st[0]])
        self.cn0 = float(recs["cn0_dbhz"][-1])
        locked = bool(recs["pll_lock"][-1])
        if locked and not self.locked:
            self.lock_start_s = float(recs["time_s"][-1])
        self.locked = locked
        if bit_offset < 0:
            return
        self.bit_offset = bit_offset
        sync = recs["state"] == STATE_BIT_SYNC
        nc_from = self.noncoherent_from
        if nc_from is not None:
            # a vector channel coasting through an outage keeps demodulating: its epochs with the signal
            # absent (the presence test zeroes C/N0) are noise - bits from them are a gap, not data
            # (random words pass parity half the time with single-bit correction)
            sync &= ~((recs["sample_index"] >= nc_from) & (recs["cn0_dbhz"] <= 0.0))
        if not sync.any():
            return
        r = recs[sync]
        bit_ms = self.bit_ms
        # per bit index: the prompt sums over its two 10-ms halves (their sum decides a phase-locked bit,
        # both enter the differential detection) and the integration time (compiled, the sums bit-identical
        # to numpy's reduceat: receiver.navigation.bits_jit), then the bits in order (a few per chunk),
        # continuing the bit left incomplete by the last chunk.  An epoch's halves (prompt1/2) go to the
        # half-bit their start lies in (epochs of 1-10 ms, or 20 ms split in the middle).
        seg_bit, ar, ai, br, bi, seg_ms, ncs = bit_segments(
            r["code_period"], r["integration_ms"], r["sample_index"], r["prompt1_i"], r["prompt1_q"],
            r["prompt2_i"], r["prompt2_q"], int(bit_offset), int(bit_ms), -1 if nc_from is None else int(nc_from))
        seg = zip(seg_bit.tolist(), (ar + 1j * ai).tolist(), (br + 1j * bi).tolist(), seg_ms.tolist(), ncs.tolist())
        out_bits, first = [], None
        for b, a, bb, ms, n in seg:
            if self.cur_bit is None or b != self.cur_bit:
                if self.cur_bit is not None and self.cur_ms == bit_ms:
                    v = self._soft_bit()
                    if first is None:
                        first = self.cur_bit
                    if self.cur_bit == first + len(out_bits):
                        out_bits.append(v)
                    else:                   # gap: flush what we have
                        self._feed(out_bits, first)
                        out_bits, first = [v], self.cur_bit
                self.cur_bit, self.cur_ms, self.cur_nc = b, 0, False
                self.cur_a = self.cur_b = 0j
            self.cur_a += a
            self.cur_b += bb
            self.cur_ms += ms
            self.cur_nc |= n
        if out_bits:
            self._feed(out_bits, first)

    def set_noncoherent(self, from_sample):
        """The channel's carrier is frequency-locked (vector loop) from this sample on (None: phase-locked).

        A phase-locked channel's bit is the sign of the in-phase prompt sum.  A frequency-locked channel's
        prompt phase wanders, so its bits are detected differentially, between adjacent half-bits: with
        A_k, B_k the prompt sums over the first and second 10 ms of bit k, the sign of
        Re(A_k conj(B_k-1) conj(u)) says whether bit k equals bit k-1, u being the phase rotation over
        10 ms measured inside the bits (B_k conj(A_k), data-free, averaged over a few bits).  Residual
        frequencies up to +/-50 Hz are tolerated (+/-12.5 Hz for whole-bit products).  The absolute
        polarity is resolved by the LNAV preamble and parity as for a phase-locked channel.
        """
        self.noncoherent_from = None if from_sample is None else int(from_sample)

    def _soft_bit(self) -> float:
        """Soft value of the completed current bit (negative = 1), coherent or differential."""
        a, b = self.cur_a, self.cur_b
        self.rot = ROT_KEEP * self.rot + b * a.conjugate()       # 10-ms rotation, |A|^2-weighted
        prev = self.prev_bit
        if not self.cur_nc:
            v = (a + b).real
        elif prev is not None and prev[0] == self.cur_bit - 1 and abs(prev[1]) > 0.0 and abs(self.rot) > 0:
            u = self.rot / abs(self.rot)
            same = (a * (prev[1] * u).conjugate()).real / abs(prev[1])
            v = same if prev[2] >= 0.0 else -same
        else:                                   # no previous bit to refer to: start a new chain
            v = abs(a + b)
        self.prev_bit = (self.cur_bit, b, v)
        return v

    def _feed(self, bits, first):
        if not bits:
            return
        for ev in self.decoder.feed(np.asarray(bits), first):
            if isinstance(ev, SubframeEvent):
                cp_ref = self.bit_offset + self.bit_ms * ev.bit_index
                if self.time_assisted and abs(ev.tow_s - cp_ref * 1e-3 - self.tx_offset) > 1e-4:
                    self.time_mismatches += 1          # the assisted guess was wrong: frame sync wins
                self.cp_ref = cp_ref
                self.tow_ref = ev.tow_s
                self.polarity = ev.polarity
                self.time_assisted = False

    @property
    def has_time(self) -> bool:
        return self.tow_ref is not None

    @property
    def tx_offset(self) -> float:
        """GPS TOW of code period 0 (transmit time = tx_offset + relative transmit time)."""
        return self.tow_ref - self.cp_ref * 1e-3

    def settled(self, s: float, settle_s: float) -> bool:
        """True once the loops have tracked for settle_s after the pull-in (DLL transient over); a resumed
        track uses its own (shorter) settle time."""
        start, own = self.track_start_s, self.settle_s
        if self.prev_track is not None and s <= self.prev_track[2]:
            start, own, _ = self.prev_track          # an epoch of the previous track (before its loss)
        if own is not None:
            settle_s = own
        return start is not None and s / self.fs - start >= settle_s

    def _columns(self, recs):
        """The columns measure/locked_at read, as Python lists (cached for the records added by :meth:`add`:
        a binary search and list reads instead of numpy calls on scalars, ~10x cheaper per epoch)."""
        hit = self._cols.get(id(recs))
        if hit is not None and hit[0] is recs:
            return hit
        return _columns(recs)

    def measure(self, s: float):
        """(relative transmit time s, NCO Doppler Hz, carrier phase cycles) at fractional sample s.

        The relative transmit time counts from the start of code period 0 of this channel; it needs no
        frame sync, so pseudoranges can be carrier-smoothed from the start of tracking."""
        m = self.measure_track(s)
        return None if m is None else m[:3]

    def measure_track(self, s: float):
        """measure(s) and the number of the track the records belong to: the carrier phase is continuous
        within one track only (a re-acquired channel starts a new one)."""
        for recs, track in zip(reversed(self.recent), reversed(self.recent_track)):
            c = self._columns(recs)
            si = c[1]
            if len(si) == 0 or si[0] > s:
                continue
            k = bisect_right(si, s) - 1
            if k >= len(si) - 1 and s - si[-1] > 0.03 * self.fs:
                return None
            dt = (s - float(si[k])) / self.fs
            txrel = (c[2][k] * 1e-3 + c[3][k] / self.chip_rate + dt * c[4][k] / self.chip_rate)
            dop = c[5][k]
            phase = c[6][k] + dt * (dop + self.if_hz) - self.if_hz * s / self.fs
            if self.polarity < 0:
                phase += 0.5
            return txrel, dop, phase, track
        return None

    def locked_at(self, s: float, guard_s: float = LOCK_GUARD_S, presence_cn0: float | None = None) -> bool:
        """The channel's lock detectors (PLL lock and C/N0) were good at sample s and guard_s later (or at its
        latest epoch, if earlier): the detectors lag a vanished signal, so the epochs just before a loss are
        noise-tracking too.  A channel tracking noise during a blockage never enters a fix.  presence_cn0: a
        channel at least this strong at s is judged by the signal-presence test, whose lag is shorter: the
        guard is then LOCK_GUARD_PRESENT_S."""
        for t in (s, s + guard_s * self.fs):
            found = None
            for recs in reversed(self.recent):
                c = self._columns(recs)
                si = c[1]
                if len(si) == 0 or si[0] > t:
                    continue
                found = (c, max(bisect_right(si, t) - 1, 0))
                break
            if found is None:
                if t == s:
                    return False
                continue
            c, k = found
            if not c[7][k]:
                return False
            # (the C/N0 column is float32: compared in float32, as numpy compares a float32 with a float)
            if t == s and presence_cn0 is not None and c[8][k] >= float(np.float32(presence_cn0)) and \
                    guard_s > LOCK_GUARD_PRESENT_S:
                return self.locked_at(s, LOCK_GUARD_PRESENT_S)
        return True

    def smooth_update(self, s: float, txrel: float, phase: float, window_epochs: int, track: int = 0):
        """Carrier smoothing, step 1: add this epoch's code-minus-carrier to the channel's fit.

        The code-minus-carrier z = c (s/fs - txrel) + lambda * phase is constant for an ideal front end
        but drifts linearly when code and carrier see different clock rates (an oscillator error applied
        to the carrier only, as in the third-party reference recording) and, slowly, with ionospheric
        divergence.  The sums of a straight-line fit of z over time are kept with exponential forgetting
        (memory ``window_epochs``).  A jump of the code against the fit (cycle slip) restarts it.
        """
        if window_epochs <= 1:
            self.hatch = None
            return
        t = s / self.fs
        z = C_LIGHT * (t - txrel) + self.wavelength * phase
        h = self.hatch
        # (a suspended channel's remaining epochs are before its loss: its lock there is checked per epoch)
        if h is None or (self.active and not self.locked) or h["track"] != track:   # new track: new phase
            h = self.hatch = {"z0": z, "t0": t, "S": [0.0] * 5, "n": 0, "track": track}   # (Python floats)
        zr, tr = z - h["z0"], t - h["t0"]
        S = h["S"]
        if h["n"] >= 20:
            a, b = self._fit(S)
            res = zr - (a + b * tr)
            # slip: restart.  The threshold is 20 m, or 6 x the RMS of the code against the fit when that is
            # larger (weak channels: a 0.5-Hz DLL at 27 dB-Hz wanders +/- 10 m; restarting on such an
            # excursion would put the raw code back into the smoothed range)
            if abs(res) > max(20.0, 6.0 * math.sqrt(h.get("r2", 0.0))):
                self.hatch = None
                self.smooth_update(s, txrel, phase, window_epochs, track)
                return
            h["r2"] = h.get("r2", res * res) + (res * res - h.get("r2", res * res)) / min(h["n"], window_epochs)
        f = 1.0 - 1.0 / window_epochs             # (each sum scaled, then the new term added: as numpy did)
        S[0], S[1], S[2], S[3], S[4] = S[0] * f + 1.0, S[1] * f + tr, S[2] * f + tr * tr, S[3] * f + zr, \
            S[4] * f + tr * zr
        h["n"] += 1

    def slope_info(self):
        """(slope m/s, weight) of this channel's code-minus-carrier fit, or None."""
        h = self.hatch
        if h is None or h["n"] < 3:
            return None
        s0, s1, s2, sz, stz = h["S"]
        det = s0 * s2 - s1 * s1
        if det <= 1e-9 * max(s0 * s2, 1e-30):
            return None
        return (s0 * stz - s1 * sz) / det, det / s0

    def smooth_value(self, s: float, txrel: float, phase: float, slope: float | None) -> float:
        """Carrier smoothing, step 2: the smoothed relative transmit time.  With a common drift
        ``slope`` (m/s, estimated over all channels) only the channel's offset is fitted, which halves
        the noise of a per-channel straight-line fit; without it the channel's own line is used."""
        h = self.hatch
        if h is None or h["n"] < 3:
            return txrel
        t = s / self.fs
        tr = t - h["t0"]
        S = h["S"]
        if slope is None:
            a, b = self._fit(S)
        else:
            b = slope
            a = (S[3] - b * S[1]) / S[0]
        ys = h["z0"] + a + b * tr - self.wavelength * phase
        return t - ys / C_LIGHT

    @staticmethod
    def _fit(S):
        s0, s1, s2, sz, stz = S
        det = s0 * s2 - s1 * s1
        if det <= 1e-12 * max(s0 * s2, 1e-30):
            return sz / s0, 0.0
        b = (s0 * stz - s1 * sz) / det
        return (sz - b * s1) / s0, b


class NavigationEngine:
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
        self.epoch = 0
        self.x0 = None
        self.aid_cfg = getattr(nav_cfg, "aiding", None)
        if self.aid_cfg is not None and not self.aid_cfg.enabled:
            self.aid_cfg = None
        self.aid_hist = deque()     # (t_s, clock bias m, drift m/s, height m, up speed m/s, TDOP, VDOP) of unaided fixes
        self.n_aided = 0
        self.first_eph_checks = []  # (prn, receiver time s, range error m) of first ephemerides checked
        # assisted mode: approximate GPS TOW of file sample 0 (input.start_gps_tow_s) lets transmit times
        # be resolved from bit synchronisation alone, before any subframe has been decoded
        self.approx_tow0 = approx_tow0

    def channel(self, prn: int) -> ChannelNav:
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

    def add_records(self, prn: int, recs, bit_offset: int):
        self.channel(prn).add(recs, bit_offset)

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

    # ------------------------------------------------------------------------------------------
    # Navigation interface for the trackers (vector loop, channel manager): week(), ephemeris(prn, t),
    # ephemerides(t), iono(), iono_params(), last_fix, set_noncoherent(prn, sample), decoded_ephemerides(),
    # satellite_los(prn, sample).
    def ephemerides(self, t):
        """prn -> Ephemeris valid at GPS time t: the RINEX file's (assisted mode) or the decoded ones, for
        every satellite met during the run (tracked now or not)."""
        from ..gnss.ephemeris import select
        out = {}
        if self.assisted:
            for prn, lst in self.rinex_ephs.items():
                e = select(lst, t)
                if e is not None:
                    out[prn] = e
            return out
        for prn, ch in self.channels.items():
            if ch.decoder.ephemeris is not None:
                out[prn] = ch.decoder.ephemeris
        return out

    def ephemeris(self, prn: int, t):
        """ephemerides(t).get(prn), selecting for prn only."""
        if self.assisted:
            from ..gnss.ephemeris import select
            return select(self.rinex_ephs.get(prn), t)
        ch = self.channels.get(prn)
        return ch.decoder.ephemeris if ch is not None else None

    def _ephemerides(self, t):
        """The ephemerides of the satellites with navigation memory (the fixes' candidates)."""
        from ..gnss.ephemeris import select
        out = {}
        for prn, ch in self.channels.items():
            if self.assisted and prn in self.rinex_ephs:
                e = select(self.rinex_ephs[prn], t)
                if e is not None:
                    out[prn] = e
            elif ch.decoder.ephemeris is not None:
                out[prn] = ch.decoder.ephemeris
        return out

    def decoded_ephemerides(self) -> dict:
        """prn -> the latest ephemeris decoded from the signal during the run (every satellite)."""
        return {p: ch.decoder.ephemeris for p, ch in sorted(self.channels.items())
                if ch.decoder.ephemeris is not None}

    def broadcast_iono(self):
        """The broadcast Klobuchar / GPS-UTC set: the RINEX header's (assisted mode; not when the header has
        GPS-UTC terms but no ION ALPHA / BETA: the reader leaves alpha and beta zero), else the first decoded
        by any channel; None while none is known."""
        if self.iono_utc is not None and (any(self.iono_utc.alpha) or any(self.iono_utc.beta)):
            return self.iono_utc
        # (several signals: GPS keys first, so the GPS set wins over BeiDou's once both are decoded)
        for ch in (self.channels.values() if not self.signals else
                   (c for _, c in sorted(self.channels.items()))):
            if ch.decoder.iono_utc is not None:
                return ch.decoder.iono_utc
        return None

    def iono(self):
        """The Klobuchar set the fixes use now: the broadcast one, else the fallback set
        (navigation.klobuchar_fallback), else None (no ionospheric correction)."""
        io = self.broadcast_iono()
        return io if io is not None else self.iono_fallback

    def iono_params(self) -> int:
        """FIX_DTYPE iono_params of a fix computed now: IONO_BROADCAST, IONO_FALLBACK or IONO_NONE (no
        parameters, or navigation.ionosphere none)."""
        if self.solver.ionosphere != "klobuchar":
            return IONO_NONE
        if self.broadcast_iono() is not None:
            return IONO_BROADCAST
        return IONO_FALLBACK if self.iono_fallback is not None else IONO_NONE

    def week(self):
        """GPS week (decoded, else input.start_gps_week), or None."""
        for ch in self.channels.values():
            if ch.decoder.week is not None:
                return ch.decoder.week
        return self.week_hint

    _week = week

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
        fixes, obs = [], []
        active = [ch for ch in self.channels.values() if ch.active and ch.last_sample >= 0]
        if not active:
            return np.zeros(0, FIX_DTYPE), np.zeros(0, OBS_DTYPE)
        horizon = min(up_to_sample, min(ch.last_sample for ch in active))
        while self.next_s <= horizon:
            s = self.next_s
            f, o = self._epoch(s)
            if f is not None:
                fixes.append(f)
            obs.extend(o)
            self._advance()
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
        of 60..95 ms at the approximate receiver time and keeping the assignment whose least-squares fix
        has the smallest residuals and a clock bias within 10 ms.  Later channels: the ambiguity is taken
        from the current fix.  Frame sync, when it comes, replaces (and checks) the assisted value."""
        from ..gnss.ephemeris import select
        pending = [ch for ch in self.channels.values()
                   if not ch.has_time and ch.bit_offset >= 0 and ch.locked
                   and ch.settled(s, self.cfg.settle_s)]
        if not pending:
            return
        if self.last_fix is not None:
            self._resolve_from_fix(s, pending)
            return
        if len(pending) < 5:
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
        grid = [(c, c) for c in np.arange(0.060, 0.0955, 0.001)]
        if deep:
            grid = [(c, c2) for c in np.arange(0.060, 0.0955, 0.001) for c2 in np.arange(0.115, 0.1405, 0.001)]
        for c, c2 in grid:
            offs, obs = {}, []
            for ch, _, txrel in cand:
                off = ch.offset_nearest(T - (c2 if ch.prn in deep else c), txrel)
                offs[ch.prn] = off
                obs.append(Observation(prn=ch.prn, tx_tow=off + txrel, cn0_dbhz=ch.cn0, system=ch.signal.system))
            key = tuple(offs.items())
            if len(obs) < 5 or key in tried:
                continue
            tried.add(key)
            ephs = {o.prn: select(self.rinex_ephs[o.prn], T) for o in obs}
            fix = self.solver.fix(week, T, obs, ephs, self.iono())
            # a common 20 ms shift of every transmit time fits almost as well (only the satellites'
            # along-track motion differs) but needs a 20 ms clock bias: input.start_gps_tow_s must be
            # within +/-10 ms for the search to pick the right assignment
            if fix is None or fix.rejected_prns or fix.n_sats < 5 or \
                    abs(fix.clock_bias_m) > 0.01 * C_LIGHT:
                continue
            if deep and fix.n_sats < len(obs):
                continue       # (a fix without the deep group cannot judge its travel time: e.g. all masked)
            rms = float(np.sqrt(np.mean(np.square(fix.residuals_m))))
            if best is None or rms < best[0]:
                best = (rms, offs)
        if best is not None and best[0] < 100.0:
            for prn, off in best[1].items():
                self.channels[prn].set_assisted_offset(off)

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
        if fix.aiding or (self.aid_hist and t_s <= self.aid_hist[-1][0]) or not (np.isfinite(fix.clock_drift_mps) and np.all(np.isfinite(fix.velocity_ecef))):
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
        if self.last_fix is None or (fix is not None and n > self.aid_cfg.max_sats):
            return fix
        if fix is not None and fix.n_sats >= AID_REF_SATS:
            self._remember(t_s, fix)        # over-determined on its own: a reference for the prediction
        aid = self._aiding(t_s)
        if aid is None:
            return fix
        aided = self.solver.fix(week, rx_tow, observations, ephs, self.iono(), x0=self.x0, aid=aid)
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
            if not ch.settled(s, self.cfg.settle_s) or not ch.locked_at(s, presence_cn0=self.presence_cn0):
                ch.hatch = None
                continue
            m = ch.measure_track(s)
            if m is None:
                ch.hatch = None
                continue
            ch.smooth_update(s, m[0], m[2], window, m[3])
            if not ch.has_time:
                continue
            prev = ch.measure_track(s - dt * self.fs)
            dop = (m[2] - prev[2]) / dt if prev is not None and prev[3] == m[3] else m[1]
            meas[prn] = (m, dop, ch)
        # common code-minus-carrier drift (clock-rate mismatch between code and carrier), weighted
        slope = common_slope([i for i in (ch.slope_info() for ch in self.channels.values()) if i is not None])
        unsmoothed = {}             # unsmoothed minus smoothed pseudorange (m), for navigation.filter ekf/ckf
        for prn, (m, dop, ch) in list(meas.items()):
            txrel = ch.smooth_value(s, m[0], m[2], slope)
            meas[prn] = ((ch.tx_offset + txrel, dop, m[2]), ch)
            unsmoothed[prn] = C_LIGHT * (txrel - m[0])
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
        lat, lon, h = ecef2lla(out.ecef)
        row = (out.gps_week, out.gps_tow, t_s, out.ecef, out.velocity_ecef, out.clock_bias_m,
               out.clock_drift_mps, fix.n_sats, fix.pdop, fix.hdop, fix.vdop, fix.gdop,
               MODE_AIDED if fix.aiding else 0,
               float(lat), float(lon), float(h), self.iono_params())
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
        return row, obs_rows
