"""One satellite's navigation memory in the engine (:class:`ChannelNav`): the channel's records -> data-bit
sums and the message decoder (LNAV / D1 / D2), the transmit-time reference across losses of lock, the lock
and presence tests a measurement needs, and the carrier-smoothed code observables.

Time keeping of a record's transmit time: frame sync ties bit ``b`` of a channel to GPS TOW, so the code
period ``bit_offset + 20 b`` started at that TOW; a record then transmits
``tow_ref + (code_period - cp_ref) * 1 ms + code_phase_chips / 1.023 MHz`` (satellite clock).
Galileo E1 (4-ms code periods, one I/NAV symbol each): ``code_period`` counts 4-ms periods, the E1-B symbol
of a record is its ``prompt1_i`` (receiver.tracking.gal_channels), and ``cp_ref`` / ``tx_offset`` stay in
milliseconds (``bit_ms`` = 4: symbol ``b`` starts at millisecond ``4 b``); the decoder's page events give
the GST of a page start, converted to GPS time (receiver.gnss.gal_inav).

Why this module is long: the message decoding, the transmit-time reference, the lock tests and the carrier
smoothing are one satellite's memory over the same records and losses of lock; split, each would reach into
the others' state (the smoothing's track and lock gaps, the time reference's track of the records).
"""
from __future__ import annotations

import math
from bisect import bisect_right
from collections import deque

import numpy as np

from ..runfile.record import STATE_BIT_SYNC
from ..gnss.signals import C_LIGHT, GPS_L1CA
from ..gnss.lnav import LnavDecoder, SubframeEvent
from .bits_jit import bit_segments

BIT_MS = 20
LOCK_GUARD_S = 0.1           # a measurement needs lock this long after its epoch too (detector lag)
LOCK_GUARD_PRESENT_S = 0.04  # the same for a channel judged by the signal-presence test (lock gone <= 35 ms)
PRESENCE_MARGIN_DB = 3.0     # ... i.e. its C/N0 this far above tracking.presence.min_cn0_dbhz
SLOPE_OUTLIER_MPS = 2.0     # channels' code-minus-carrier drifts this far from the weighted median: not common
ROT_KEEP = 0.8              # decay per bit of the rotation estimate (about 5 bits, 100 ms)
SMOOTH_GAP_S = 1.0          # carrier smoothing goes on over lock gaps of one track up to this long
SMOOTH_FAST_EPOCHS = 10     # memory (epochs) of the recent code-against-fit RMS (slip test of a faded channel)
SMOOTH_FADE_DB = 6.0        # a code epoch this far below the fit's C/N0 level enters the smoothing fit with the
                            # weight C/N0 / level (the code variance goes as 1 / C/N0), else with weight 1 (the
                            # C/N0 estimates of a steady signal scatter by 1-2 dB: weights from them add noise)
SMOOTH_LEVEL_EPOCHS = 50    # memory (epochs) of the fit's C/N0 level (the C/N0 of its full-weight epochs)


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
        self.bit_ms = sig.bit_ms(self.sig_prn)    # LNAV / BeiDou D1: 20 ms; BeiDou D2: 2 ms; Galileo E1-B 4 ms
        self.galileo = sig.system == "E"
        # duration of one code period (records' code_period unit): 1 ms, Galileo E1 4 ms
        self.period_s = 1e-3 * round(sig.code_period_s * 1e3)
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
        self.dll_hold_s = 0.0       # the current track's DLL keeps a wider bandwidth this long after its pull-in
        self.prev_track = None      # (track_start_s, settle_s, last sample, dll_hold_s) of the previous track
        self.resumed_with_time = 0  # re-acquisitions that kept the transmit-time reference

    def _new_decoder(self, week_hint):
        """LNAV for L1 C/A (GPS, QZSS); D1/D2 for BeiDou B1I (receiver.gnss.bds_nav); I/NAV for Galileo E1
        (receiver.gnss.gal_inav)."""
        if self.signal.system == "E":
            from ..gnss.gal_inav import InavDecoder
            return InavDecoder(self.sig_prn, week_hint=week_hint)
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
        self.prev_track = (self.track_start_s, self.settle_s, self.last_sample, self.dll_hold_s) \
            if keep and self.recent else None
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
        self.dll_hold_s = 0.0
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
            if self.galileo:
                self._carry_inav(old)
                return
            self.decoder.ephemeris, self.decoder.iono_utc, self.decoder.week = \
                old.ephemeris, old.iono_utc, old.week
            self.decoder.parity_failures = old.parity_failures
            self.decoder.first_check = getattr(old, "first_check", None)

    def _carry_inav(self, old):
        """A new I/NAV decoder (symbol indices restart) keeps what the old one decoded."""
        d = self.decoder
        d.ephemeris, d.nequick, d.utc, d.ggto, d.gst_week = old.ephemeris, old.nequick, old.utc, old.ggto, \
            old.gst_week
        d.crc_failures, d.pages_ok, d.first_check = old.crc_failures, old.pages_ok, old.first_check

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

    def add(self, recs: np.ndarray, bit_offset: int, dll_hold_s: float = 0.0):
        """Take a chunk of this channel's epoch records (EPOCH_DTYPE): lock, C/N0 and the recent records; with bit
        sync (``bit_offset`` >= 0: the code period where bit 0 starts) the prompt sums become data bits fed to the
        message decoder, whose subframes set the transmit-time reference."""
        if len(recs) == 0:
            return
        self.recent.append(recs)
        self.recent_track.append(self.tracks)
        while len(self.recent) > 3:
            self.recent.popleft()
            self.recent_track.popleft()
        self._cols = {id(r): self._cols.get(id(r)) or _columns(r) for r in self.recent}
        self.last_sample = int(recs["sample_index"][-1])
        self.dll_hold_s = dll_hold_s
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
        if self.galileo:
            self._add_symbols(recs)
            return
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

    def _add_symbols(self, recs):
        """Galileo E1: every record past the pull-in is one E1-B symbol (its prompt1_i); runs of consecutive
        code periods go to the I/NAV decoder (a gap restarts its page synchronisation)."""
        sel = recs["state"] == STATE_BIT_SYNC
        if not sel.any():
            return
        cp = recs["code_period"][sel]
        sym = recs["prompt1_i"][sel].astype(np.float64)
        cuts = np.flatnonzero(np.diff(cp) != 1) + 1
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(cp)]):
            self._feed(sym[a:b].tolist(), int(cp[a]))

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
                # (Galileo: the PLL tracks the pilot, whose phase has no half-cycle ambiguity)
                self.polarity = 1 if self.galileo else ev.polarity
                self.time_assisted = False

    @property
    def has_time(self) -> bool:
        """True when the channel's code periods are tied to GPS time (frame sync, or an assisted offset)."""
        return self.tow_ref is not None

    @property
    def tx_offset(self) -> float:
        """GPS TOW of code period 0 (transmit time = tx_offset + relative transmit time)."""
        return self.tow_ref - self.cp_ref * 1e-3

    def settled(self, s: float, settle_s: float) -> bool:
        """True once the loops have tracked for settle_s after the pull-in and the DLL's hold at a wider
        bandwidth (a weak channel's, dll_hold_s) -- the DLL transient is over; a resumed track uses its own
        (shorter) settle time."""
        start, own, hold = self.track_start_s, self.settle_s, self.dll_hold_s
        if self.prev_track is not None and s <= self.prev_track[2]:
            start, own, _, hold = self.prev_track     # an epoch of the previous track (before its loss)
        if own is not None:
            settle_s = own
        return start is not None and s / self.fs - start >= settle_s + hold

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
            txrel = (c[2][k] * self.period_s + c[3][k] / self.chip_rate + dt * c[4][k] / self.chip_rate)
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

    def cn0_at(self, s: float) -> float | None:
        """The C/N0 estimate (dB-Hz) of the channel's epoch at sample s (None: no record there)."""
        for recs in reversed(self.recent):
            c = self._columns(recs)
            si = c[1]
            if len(si) == 0 or si[0] > s:
                continue
            return float(c[8][max(bisect_right(si, s) - 1, 0)])
        return None

    def smooth_update(self, s: float, txrel: float, phase: float, window_epochs: int, track: int = 0,
                      cn0_dbhz: float | None = None):
        """Carrier smoothing, step 1: add this epoch's code-minus-carrier to the channel's fit.

        The code-minus-carrier z = c (s/fs - txrel) + lambda * phase is constant for an ideal front end
        but drifts linearly when code and carrier see different clock rates (an oscillator error applied
        to the carrier only, as in the third-party reference recording) and, slowly, with ionospheric
        divergence.  The sums of a straight-line fit of z over time are kept with exponential forgetting
        (memory ``window_epochs``).  A jump of the code against the fit (cycle slip) restarts it.  The fit
        goes on over a lock gap of the same track (the carrier NCO's phase is continuous: a fade handed to the
        weak loops, a weak channel's lock dropouts) up to SMOOTH_GAP_S; the slip test then judges the first
        epoch after it.  cn0_dbhz: the epoch's C/N0; more than SMOOTH_FADE_DB below the fit's level its code
        enters the fit with the weight C/N0 / level (the code variance of a DLL goes as 1 / C/N0), so a fade's
        weak code moves a fit made on the strong signal little, and the strong code after it takes the fit
        back at once.
        """
        if window_epochs <= 1:
            self.hatch = None
            return
        t = s / self.fs
        z = C_LIGHT * (t - txrel) + self.wavelength * phase
        h = self.hatch
        # (a suspended channel's remaining epochs are before its loss: its lock there is checked per epoch)
        if h is None or h["track"] != track or t - h.get("t_last", t) > SMOOTH_GAP_S:   # new track: new phase
            h = self.hatch = {"z0": z, "t0": t, "S": [0.0] * 5, "n": 0, "track": track}   # (Python floats)
        h["t_last"] = t
        zr, tr = z - h["z0"], t - h["t0"]
        S = h["S"]
        if h["n"] >= 20:
            a, b = self._fit(S)
            res = zr - (a + b * tr)
            # slip: restart.  The threshold is 20 m, or 6 x the RMS of the code against the fit when that is
            # larger -- over the fit's memory or over the last SMOOTH_FAST_EPOCHS (weak channels: a 0.5-Hz DLL
            # at 27 dB-Hz wanders +/- 10 m, at 24 dB-Hz +/- 30 m, smoothly; restarting on such an excursion
            # would put the raw code back into the smoothed range)
            if abs(res) > max(20.0, 6.0 * math.sqrt(max(h.get("r2", 0.0), h.get("f2", 0.0)))):
                self.hatch = None
                self.smooth_update(s, txrel, phase, window_epochs, track, cn0_dbhz)
                return
            h["r2"] = h.get("r2", res * res) + (res * res - h.get("r2", res * res)) / min(h["n"], window_epochs)
            h["f2"] = h.get("f2", res * res) + (res * res - h.get("f2", res * res)) / \
                min(h["n"], SMOOTH_FAST_EPOCHS, window_epochs)
        f = 1.0 - 1.0 / window_epochs             # (each sum scaled, then the new term added: as numpy did)
        level = h.get("cn0")
        if cn0_dbhz is not None and level is not None and cn0_dbhz < level - SMOOTH_FADE_DB:
            w = 10.0 ** ((max(cn0_dbhz, 0.0) - level) / 10.0)
            S[0], S[1], S[2], S[3], S[4] = S[0] * f + w, S[1] * f + w * tr, S[2] * f + w * tr * tr, \
                S[3] * f + w * zr, S[4] * f + w * tr * zr
        else:
            if cn0_dbhz is not None and cn0_dbhz > 0.0:
                h["cn0"] = cn0_dbhz if level is None else \
                    level + (cn0_dbhz - level) / min(h["n"] + 1, SMOOTH_LEVEL_EPOCHS)
            S[0], S[1], S[2], S[3], S[4] = S[0] * f + 1.0, S[1] * f + tr, S[2] * f + tr * tr, S[3] * f + zr, \
                S[4] * f + tr * zr
        h["n"] += 1

    def slope_info(self, h=None):
        """(slope m/s, weight) of this channel's code-minus-carrier fit (or of an earlier arc's, ``h``), or
        None."""
        if h is None:
            h = self.hatch
        if h is None or h["n"] < 3:
            return None
        s0, s1, s2, sz, stz = h["S"]
        det = s0 * s2 - s1 * s1
        if det <= 1e-9 * max(s0 * s2, 1e-30):
            return None
        return (s0 * stz - s1 * sz) / det, det / s0

    def smooth_value(self, s: float, txrel: float, phase: float, slope: float | None, h=None) -> float:
        """Carrier smoothing, step 2: the smoothed relative transmit time.  With a common drift
        ``slope`` (m/s, estimated over all channels) only the channel's offset is fitted, which halves
        the noise of a per-channel straight-line fit; without it the channel's own line is used.
        ``h``: the fit of an earlier carrier arc of this channel (navigation.lookahead_s) instead of the
        current one."""
        if h is None:
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

