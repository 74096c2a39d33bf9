"""Channel lifecycle: one owner for the tracking channels of a run.

Per satellite (:class:`SatTrack`)::

    searching --(cold acquisition)--> pull-in --> tracking --(signal lost)--> re-acquiring
        ^                                ^                                       |
        |                                +----(narrow search around prediction)--+
        +----(prediction impossible: outage longer than max_age_s, set below the mask)

* Loss of signal: the kernel's lock detectors (low-passed |I| / |Q| and C/N0) declare a channel lost after
  ``tracking.lost_ms`` of bad epochs (default 200 ms, i.e. ~250-400 ms after the signal vanished).
* While tracking, the manager keeps the satellite's last *good* state (epochs in lock, C/N0 above the lock
  threshold): sample, relative transmit time (code period count + code phase), Doppler and Doppler rate.
* Re-acquiring: every chunk the satellite is searched in the first samples of the next chunk, in a narrow
  window (receiver.acquisition.reacquisition) around the Doppler and code phase predicted at that sample.  The
  Doppler is extrapolated from the last good state; with an ephemeris and a fix, the change of the
  satellite's line-of-sight velocity seen from the last fix is added (the receiver's own velocity is
  assumed constant).  The window starts at ``reacquisition.doppler_hz`` / ``code_chips`` and widens with
  the outage length t by the dynamics bound (accel t / lambda, accel t^2 / 2, capped by the speed bound);
  beyond ``max_age_s`` (or a window wider than the acquisition grid) the satellite goes back to the cold
  round-robin search.  A satellite predicted below the navigation elevation mask is not searched.
* Hot start: the new channel continues the old channel's code-period count (the predicted transmit time
  fixes the integer milliseconds: its error is far below 0.5 ms for any outage below minutes), so the
  bit alignment and the navigation engine's transmit-time reference stay valid (ChannelNav.resume); the
  bit-sync histogram is seeded with the known bit offset and the pull-in is ``reacquisition.pull_in_ms``;
  its DLL runs 1st order for the first chunk (no rate wind-up on the initial code error), then as configured
  with the old channel's rate integrator.  When the dynamics bound puts the predicted code phase within
  0.05 chip and the search finds the signal within 0.5 chip of it, the channel starts on the prediction and
  its measurements are used ``reacquisition.settle_predicted_s`` after the pull-in (else ``settle_s``).

* Carrier false lock: in a true lock the code and the carrier move together (carrier-aided DLL: its rate
  integrator, the code-minus-carrier rate, stays within a few m/s).  A channel whose carrier loop was captured
  by something else -- the images of strong signals at another Doppler leaking through its code (B1I: the
  GEO cluster, several 45 dB-Hz signals within a few Hz of each other), or a sidelobe at 1/(2 T) -- keeps
  its code on its own satellite (the DLL still sees it) while the carrier runs at the wrong frequency: the
  code-minus-carrier rate is that frequency error times lambda.  When it differs from the median over the
  signal's channels (the common part: a front-end LO offset) by more than ``CC_FALSE_LOCK_MPS`` over
  ``CC_WINDOW_S`` of in-lock epochs (every chunk of the window beyond half of it, same sign) the channel is
  restarted at its current code phase with the Doppler its code rate measured (event "carrier false
  lock"; its navigation memory is reset as for a new track).

The pipeline calls ``start`` once, then per chunk ``note(prn, recs)`` for every channel's records and
``after_chunk(start, next_start)``.  ``channels`` (prn -> Channel) is the dict the vector tracker shares.

Why this module is long: the channel lifecycle's states and transitions stay in one module, so the whole
state machine reads in one place.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ..gnss.satid import sat_label
from ..gnss.signals import C_LIGHT
from . import kernel as K
from ..acquisition import AcqResult, cross_correlation_image
from ..acquisition.reacquisition import narrow_search
from .scalar import Channel

REACQ_PER_ATTEMPT = 4           # cold searches per attempt
GOOD_KEEP_S = 1.5               # good-state history used for the Doppler rate
HOT_DLL_FIRST_ORDER_S = 0.4     # a hot-started channel's DLL is 1st order this long (then per the config)
CATCH_UP_OVERLAP_S = 0.03       # as the pipeline's chunk overlap: a channel's epochs may end inside it
MAX_LOS_RATE_MPS = 1000.0       # bound of a GPS/BeiDou MEO satellite's range rate seen from the ground (~930 m/s)
COLD_MARGIN_HZ = 500.0          # cold search after a fix: margin of the Doppler window (drift error, rate)
GOOD_MARGIN_S = 0.1             # lock detectors lag: the prediction starts this long before the last good epoch
XCORR_RATIO_DB = 15.0           # a cold detection this much weaker than a tracked signal at its Doppler is an image
XCORR_IMAGE_FRACTION = 0.25     # ... or at k x 1 kHz when the predicted image explains this share of its power
CHUNK_YOUNG_S = 1.0             # a channel opened this recently is judged by its search's C/N0 until in lock
CC_FALSE_LOCK_MPS = 15.0        # code-minus-carrier rate of a carrier false lock (true locks: < ~8 m/s per s)
CC_WINDOW_S = 2.0               # ... sustained over this much of consecutive in-lock chunks
CC_MIN_EPOCHS = 50              # a chunk counts when it has this many in-lock epochs
DYN_HISTORY_S = 3.0             # fixes kept for the receiver's measured speed and acceleration
DYN_MARGIN = 1.5                # the measured acceleration / speed bound the windows with this margin
COLD_FALLBACK_S = 3.0           # a satellite re-acquired in vain this long is also in the cold round-robin
STARVED_COLD_S = 1.0            # cold-search interval while fewer than 4 satellites are tracked


@dataclass
class SatTrack:
    """Per-satellite state of the channel manager: searching | tracking | reacquiring, the recent good
    epochs and the reference the re-acquisition prediction starts from (samples are file sample indices)."""
    prn: int
    channel_id: int
    state: str = "searching"            # searching | tracking | reacquiring
    good: deque = field(default_factory=deque)   # (sample, txrel s, doppler Hz) of recent good epochs
    lost_at: float | None = None        # sample of the last good state (outage start)
    ref: tuple | None = None            # (sample, txrel, doppler, rate, bit_offset) the prediction starts from
    bit_offset: int = -1
    dll_rate: float = 0.0               # the DLL rate integrator of the last good state (code/carrier mismatch)
    restore_at: float | None = None     # sample from which a hot channel's DLL is 2nd order again
    reacquisitions: int = 0
    searches: int = 0
    # per chunk (last sample, code-minus-carrier rate m/s, code-derived Doppler Hz, seconds) of in-lock epochs
    cc: deque = field(default_factory=deque)
    false_locks: int = 0


class ChannelManager:
    """Owner of the tracking channels of a run (see the module docstring): cold searches, channel opening,
    loss of signal, re-acquisition around the prediction, false-lock restarts and the channel events."""
    def __init__(self, cfg, reader, nav, fs, if_hz, signal, acquire, writer=None, log=None, prns=None):
        self.cfg = cfg
        self.rc = cfg.tracking.reacquisition
        self.reader = reader
        self.nav = nav
        self.fs = float(fs)
        self.if_hz = float(if_hz)
        self.signal = signal
        self.acquire = acquire          # acquire(cfg, reader, start, prns) -> [AcqResult] (cold search)
        self.prns = list(prns) if prns is not None else list(cfg.acquisition.prns)     # the PRNs searched
        self.writer = writer
        self.log = log or (lambda msg: None)
        self.channels: dict[int, Channel] = {}
        self._open_cn0: dict[int, tuple] = {}   # prn -> (sample, C/N0 estimate of the search) of its channel
        self.sats: dict[int, SatTrack] = {}
        self.events: list = []          # (time_s, prn, event, detail)
        self._rr = 0
        self._pred_due: dict = {}       # prn -> (next sample of its predicted search, interval s)
        self._next_cold = None
        self._ids = 0
        self.max_ch = cfg.tracking.max_channels
        self.lambda_m = C_LIGHT / signal.carrier_hz
        self.chip_m = C_LIGHT / signal.chip_rate
        self._fixes: deque = deque()    # (sample, velocity ECEF) of the recent fixes: measured dynamics

    # ------------------------------------------------------------------ helpers
    def _sat(self, prn) -> SatTrack:
        if prn not in self.sats:
            self.sats[prn] = SatTrack(prn, self._ids)
            self._ids += 1
        return self.sats[prn]

    def _event(self, s, prn, what, detail=""):
        self.events.append((s / self.fs, prn, what, detail))
        name = sat_label(prn, self.signal.system)
        self.log(f"channels: {s / self.fs - self.reader.first / self.fs:7.2f} s {name} {what} {detail}")

    def _open(self, prn, doppler, code_phase, sample, cn0_est=None):
        sat = self._sat(prn)
        weak = cn0_est is not None and cn0_est < self.cfg.tracking.weak.cn0_dbhz     # docs: tracking, weak signals
        ch = Channel(prn, doppler, code_phase, sample, self.cfg.tracking, self.fs, self.if_hz,
                     channel_id=sat.channel_id, signal=self.signal, weak=weak)
        self.channels[prn] = ch
        self._open_cn0[prn] = (int(sample), cn0_est)
        sat.state = "tracking"
        sat.good.clear()
        return ch

    # ------------------------------------------------------------------ start / cold search
    def start(self, acq_start: int, notes=None):
        """The initial cold acquisition (widened when fewer than 4 satellites are found); lines for the user
        go to notes."""
        notes = [] if notes is None else notes
        results = self.acquire(self.cfg, self.reader, acq_start, self.prns, widen=True,
                               notes=notes)
        if self.writer is not None:
            self.writer.write_acquisition(results, {"fs": self.fs, "pfa": self.cfg.acquisition.pfa,
                                                    "notes": "\n".join(notes)})
        detected = sorted([r for r in results if r.detected], key=lambda r: -r.metric)
        for r in detected[:self.max_ch]:
            self._open(r.prn, r.doppler_hz, r.code_phase_chips, r.sample_index, r.cn0_dbhz_est)
        self._next_cold = acq_start + int(self.cfg.tracking.reacquire_s * self.fs)
        return results

    def _cold(self, start, next_start):
        if start < self._next_cold or len(self.channels) >= self.max_ch:
            return
        # fewer than 4 satellites tracked (no fix): no satellite above the mask waits reacquire_s for a search
        interval = self.cfg.tracking.reacquire_s
        if sum(1 for ch in self.channels.values() if not ch.lost) < 4:
            interval = min(interval, STARVED_COLD_S)
        self._next_cold = start + int(interval * self.fs)
        # a satellite whose narrow searches have failed for COLD_FALLBACK_S is searched cold as well (the
        # prediction may be wrong: dynamics beyond the bounds); its narrow searches go on meanwhile
        missing = [p for p in self.prns if p not in self.channels
                   and (self._sat(p).state != "reacquiring" or self._sat(p).lost_at is None
                        or next_start - self._sat(p).lost_at > COLD_FALLBACK_S * self.fs)]
        missing = [p for p in missing if not self._below_mask(p, next_start)]
        if not missing:
            return
        pick = [missing[(self._rr + k) % len(missing)] for k in range(min(REACQ_PER_ATTEMPT, len(missing)))]
        self._rr += REACQ_PER_ATTEMPT
        hs = self.cfg.acquisition.high_sensitivity
        weak = hs.enabled and hs.cold and len(self.channels) < hs.min_found
        window = self._cold_doppler_window()
        res = self.acquire(self.cfg, self.reader, next_start, pick, sensitive=weak,
                           known_hz=[ch.doppler_hz for ch in self.channels.values()] if weak else (),
                           **({"doppler_window": window} if window is not None else {}))
        self._reject_tracked_images(res)
        if self.writer is not None:
            self.writer.write_acquisition(res, {"fs": self.fs})
        for r in res:
            if r.detected and len(self.channels) < self.max_ch:
                sat = self._sat(r.prn)
                known = self.nav is not None and r.prn in self.nav.channels
                self._open(r.prn, r.doppler_hz, r.code_phase_chips, r.sample_index, r.cn0_dbhz_est)
                if known:
                    self.nav.resume(r.prn, continuous=False)
                self._event(r.sample_index, r.prn, "cold acquisition", f"Doppler {r.doppler_hz:.0f} Hz")
                sat.reacquisitions += 1

    def _reject_tracked_images(self, res):
        """Un-detect cold-search detections that are cross-correlation images of a signal a channel tracks.

        The search's own test (receiver.acquisition.reject_cross_correlations) compares only the PRNs it
        searched; a satellite already in a channel is not among them, so a 45 dB-Hz signal's Gold-code
        sidelobes (-21..-24 dB) passed as a ~23 dB-Hz 'satellite' that is not in the sky (urban canyon:
        G09 / G10 at 22-28 dB-Hz, at the Doppler of G26 / G29 or 1 kHz from G11's).  The same rules are
        applied against every channel: same Doppler within half a bin and >= 15 dB weaker, or a k x 1 kHz
        offset whose image predicted from the two codes at the tracked code phase explains >= 1/4 of the
        detection's power.  A channel's strength is its C/N0 while in lock, else (a channel opened by this
        chunk's re-acquisition, still in its pull-in) the C/N0 its search estimated."""
        det = [r for r in res if r.detected]
        if not det:
            return
        a = self.cfg.acquisition
        half_bin = 1.0 / (2.0 * a.coherent_ms * 1e-3)
        lock_min = self.cfg.tracking.lock_cn0_min_dbhz
        code_len = self.signal.code_len
        for r in det:
            for prn, ch in self.channels.items():
                if ch.lost or prn == r.prn:
                    continue
                if ch.st[K.S_LOCK] > 0 and ch.cn0_dbhz >= lock_min:
                    cn0 = float(ch.cn0_dbhz)
                elif self._open_cn0.get(prn) is not None and \
                        ch.next_sample - self._open_cn0[prn][0] < CHUNK_YOUNG_S * self.fs:
                    cn0 = self._open_cn0[prn][1]
                else:
                    continue
                ratio_db = cn0 - r.cn0_dbhz_est
                if ratio_db <= 0:
                    continue
                dd = ch.doppler_hz - r.doppler_hz
                if abs(dd) <= half_bin and ratio_db > XCORR_RATIO_DB:
                    r.detected, r.reason = False, "xcorr"
                    break
                k = round(dd / 1000.0)
                if k == 0 or abs(k) > 60 or abs(dd - 1000.0 * k) > half_bin:
                    continue
                cp = (ch.st[K.S_CODE_PHASE] - (ch.next_sample - r.sample_index) / self.fs
                      * ch.st[K.S_CODE_RATE]) % code_len
                strong = AcqResult(prn, True, ch.doppler_hz, float(cp), r.sample_index, 1.0, 1.0, cn0)
                img = cross_correlation_image(strong, r, self.fs, a.coherent_ms, self.signal)
                if img * 10 ** (ratio_db / 10) >= XCORR_IMAGE_FRACTION:
                    r.detected, r.reason = False, "xcorr"
                    break
            if not r.detected:
                self._event(r.sample_index, r.prn, "cold detection rejected",
                            f"(cross-correlation image of a tracked signal, Doppler {r.doppler_hz:.0f} Hz, "
                            f"{r.cn0_dbhz_est:.1f} dB-Hz)")

    # ------------------------------------------------------------------ per chunk
    def note(self, prn: int, recs: np.ndarray):
        """Keep the satellite's recent good states (epochs in lock with C/N0 above the lock threshold)."""
        if not len(recs):
            return
        sat = self._sat(prn)
        ok = (recs["pll_lock"] > 0) & (recs["cn0_dbhz"] >= self.cfg.tracking.lock_cn0_min_dbhz) & \
            (recs["state"] != K.MODE_PULL_IN)
        self._note_code_carrier(sat, recs, ok)
        if not ok.any():
            return
        r = recs[ok][::10]
        chip = self.signal.chip_rate
        # (sample, relative transmit time, Doppler) per kept epoch, computed column-wise
        txrel = r["code_period"].astype(np.int64) * 1e-3 + r["code_phase_chips"].astype(np.float64) / chip
        sat.good.extend(zip(r["sample_index"].astype(np.float64).tolist(), txrel.tolist(),
                            r["doppler_hz"].astype(np.float64).tolist()))
        keep = GOOD_KEEP_S * self.fs
        while sat.good and sat.good[-1][0] - sat.good[0][0] > keep:
            sat.good.popleft()
        ch = self.channels.get(prn)
        if ch is not None and ch.bit_offset >= 0:
            sat.bit_offset = ch.bit_offset
        if ch is not None and sat.restore_at is None and ch.st[K.S_LOCK] > 0:
            sat.dll_rate = float(ch.st[K.S_DLL_RATE])

    def _note_code_carrier(self, sat: SatTrack, recs: np.ndarray, ok: np.ndarray):
        """Keep the chunk's mean code-minus-carrier rate (m/s) and code-derived Doppler of the in-lock
        epochs; a chunk without enough of them ends the run of consecutive chunks."""
        if ok.sum() < CC_MIN_EPOCHS:
            sat.cc.clear()
            return
        r = recs[ok]
        sig = self.signal
        code_dop = (r["code_rate_hz"].astype(np.float64) / sig.chip_rate - 1.0) * sig.carrier_hz
        w = r["integration_ms"].astype(np.float64)
        dop_code = float(np.sum(code_dop * w) / np.sum(w))
        dop_carr = float(np.sum(r["doppler_hz"].astype(np.float64) * w) / np.sum(w))
        sat.cc.append((int(r["sample_index"][-1]), (dop_code - dop_carr) * self.lambda_m, dop_code,
                       float(np.sum(w)) * 1e-3))
        while len(sat.cc) > 1 and sum(x[3] for x in list(sat.cc)[1:]) >= CC_WINDOW_S:
            sat.cc.popleft()

    @staticmethod
    def _cc_window(sat: SatTrack):
        """(mean code-minus-carrier rate m/s, per-chunk rates, mean code-derived Doppler Hz) over the window,
        or None when the satellite has less than CC_WINDOW_S of consecutive in-lock chunks."""
        cc = list(sat.cc)
        secs = np.array([x[3] for x in cc])
        if secs.sum() < CC_WINDOW_S * 0.999:
            return None
        rates = np.array([x[1] for x in cc])
        return (float(np.sum(rates * secs) / secs.sum()), rates,
                float(np.sum(np.array([x[2] for x in cc]) * secs) / secs.sum()))

    def _restart_false_locks(self):
        """Restart channels in a carrier false lock at their code phase with the code-derived Doppler.

        The code-minus-carrier rate has a part common to every channel of the signal (a front-end LO offset
        moves every carrier Doppler, not the code rates: the GPS reference recording reads +150 m/s on every
        satellite); a channel is judged by its difference to the median over the channels with a full
        window, so at least 3 of them are needed."""
        # scalar channels only: under the vector loop both NCOs follow the navigation solution
        win = {prn: self._cc_window(self._sat(prn)) for prn, ch in self.channels.items()
               if not ch.lost and not (ch.vector_carrier or ch.vector_code)}
        win = {p: w for p, w in win.items() if w is not None}
        if len(win) < 3:
            return
        common = float(np.median([w[0] for w in win.values()]))
        for prn, (mean, rates, dop_code) in win.items():
            dev = mean - common
            if abs(dev) < CC_FALSE_LOCK_MPS or np.any((rates - common) * np.sign(dev) < 0.5 * CC_FALSE_LOCK_MPS):
                continue
            ch = self.channels[prn]
            sat = self._sat(prn)
            s = ch.next_sample
            code_phase = float(ch.st[K.S_CODE_PHASE])
            old = ch.doppler_hz
            dop = dop_code - common / self.lambda_m
            sat.cc.clear()
            sat.false_locks += 1
            self._open(prn, dop, code_phase, s)
            if self.nav is not None and prn in self.nav.channels:
                self.nav.resume(prn, continuous=False)
            self._event(s, prn, "carrier false lock",
                        f"(carrier at {old:.0f} Hz, code-minus-carrier {dev:+.0f} m/s from the common "
                        f"{common:+.1f} m/s): restarted at the code's Doppler {dop:.0f} Hz")

    def after_chunk(self, start: int, next_start: int):
        """Lost channels -> re-acquiring; carrier false locks restarted; narrow searches at next_start; the
        periodic cold search."""
        self._restart_false_locks()
        self._note_fix()
        for prn, ch in list(self.channels.items()):
            if ch.lost:
                del self.channels[prn]
                self._lost(prn)
                continue
            sat = self._sat(prn)
            if sat.restore_at is not None and ch.next_sample >= sat.restore_at:
                # the hot channel's code error has converged (1st-order DLL): back to the configured order,
                # its rate integrator starting from the old channel's value
                ch.cfg[K.C_DLL_ORDER] = self.cfg.tracking.dll_order
                ch.st[K.S_DLL_RATE] = sat.dll_rate
                sat.restore_at = None
        if next_start + 0.05 * self.fs >= self.reader.end:
            return
        # narrow searches at several points of the chunk just tracked (earliest first), not only at its end:
        # a satellite that came back early in the chunk is found there and its new channel catches up to
        # the chunk end at once (the re-acquisition latency drops from ~1 chunk to ~1 search step)
        step = int(round(self.rc.search_step_s * self.fs))
        points = [next_start]
        if step > 0:
            points = list(range(next_start - step * ((next_start - start - 1) // step), next_start + 1, step))
            points = [p for p in points if p >= start] or [next_start]
        for prn, sat in list(self.sats.items()):
            if sat.state == "reacquiring" and prn not in self.channels and len(self.channels) < self.max_ch:
                for p in points:
                    if sat.lost_at is not None and p < sat.lost_at + self.rc.search_after_s * self.fs:
                        continue
                    if self._hot(sat, p) or sat.state != "reacquiring":
                        if p < next_start and prn in self.channels:
                            self._catch_up(prn, p, next_start)
                        break
        self._predicted_search()
        self._cold(start, next_start)

    def _start_on_prediction(self, ch, ref, s, dt, dop):
        """A channel opened on its prediction from the reference channel ``ref`` (T_p - T_q = dt at sample s):
        its code-period count continues the reference's, so the reference's bit alignment is its own (a
        weak channel integrates whole bits at once instead of finding the edges in 1-ms prompts), and its
        pull-in is the hot start's (the Doppler is known to a few Hz)."""
        st, chip = ch.st, self.signal.chip_rate
        tx = float(ref.st[K.S_CODE_PERIOD]) * 1e-3 + float(ref.st[K.S_CODE_PHASE]) / chip + dt
        tx_first = tx + (float(st[K.S_NEXT_SAMPLE]) - s) / self.fs * (1.0 + dop / self.signal.carrier_hz)
        st[K.S_CODE_PERIOD] = int(round((tx_first - st[K.S_CODE_PHASE] / chip) * 1e3))
        bit_off = ref.bit_offset
        if bit_off >= 0:
            st[K.S_BIT_OFFSET] = bit_off
            ch.hist[bit_off % self.signal.bit_ms(ch.prn)] = 12     # bit sync known: confirmed at once
        ch.cfg[K.C_PULL_IN_MS] = self.rc.pull_in_ms

    def _predicted_search(self):
        """Satellites in view that no channel tracks, searched around their prediction from a tracked one
        and the fix (receiver/tracking/predicted.py; ``acquisition.predicted``)."""
        pc = self.cfg.acquisition.predicted
        n1 = self.fs * 1e-3
        if not pc.enabled or self.nav is None or self.nav.last_fix is None or len(self.channels) >= self.max_ch \
                or self.signal.name != "gps_l1ca" or abs(n1 - round(n1)) > 1e-6:
            return
        fix = self.nav.last_fix[1]
        lock_min = self.cfg.tracking.lock_cn0_min_dbhz
        refs = [(p, ch) for p, ch in self.channels.items()
                if not ch.lost and ch.st[K.S_LOCK] > 0 and ch.cn0_dbhz >= lock_min]
        if not refs or not np.all(np.isfinite(fix.ecef)):
            return
        q, ref = max(refs, key=lambda x: x[1].cn0_dbhz)
        s = ref.next_sample
        n = int(round(n1)) * pc.coherent_ms * pc.noncoherent
        t = self.nav.gps_time(s)
        eph_q = self.nav.ephemeris(q, t) if t is not None else None
        if eph_q is None or s + n >= self.reader.end:
            return
        from ..acquisition.high_sensitivity import search_predicted
        from .predicted import predict
        block = None                    # the samples from s, read once for every satellite searched
        for p in self.prns:
            if p in self.channels or self._sat(p).state == "reacquiring" or len(self.channels) >= self.max_ch:
                continue
            due, every = self._pred_due.get(p, (0, pc.every_s))
            if s < due:
                continue
            eph_p = self.nav.ephemeris(p, t)
            if eph_p is None or self._below_mask(p, s):
                self._pred_due[p] = (s + int(pc.every_s * self.fs), every)     # (not looked up every chunk)
                continue
            cp, dop, dt = predict(eph_p, eph_q, t, fix.ecef, fix.velocity_ecef, ref.st[K.S_CODE_PHASE],
                                  ref.doppler_hz, self.signal)
            if block is None:
                block = self.reader.read(s, n)
            res = search_predicted(block, s, self.fs, self.if_hz, p, dop, pc.doppler_hz, cp,
                                   pc.window_chips, pc.coherent_ms, pc.noncoherent, pc.pfa, self.signal)
            self._reject_tracked_images([res])
            if self.writer is not None:
                self.writer.write_acquisition([res], {"fs": self.fs})
            self._pred_due[p] = (s + int(every * self.fs), pc.every_s if res.detected else min(2 * every,
                                                                                              4 * pc.every_s))
            if res.detected:
                # the prediction is finer than a weak search's estimate (a few Hz and a tenth of a chip from
                # the fix, against ~25 Hz and the sample grid): the channel starts on it when the search
                # confirms it (the detection within half a chip and a Doppler bin)
                dc = (res.code_phase_chips - cp + self.signal.code_len / 2) % self.signal.code_len \
                    - self.signal.code_len / 2
                on_pred = abs(dc) < 0.5 and abs(res.doppler_hz - dop) < 1e3 / (2 * pc.coherent_ms)
                ch = self._open(p, dop if on_pred else res.doppler_hz, cp if on_pred else res.code_phase_chips, s,
                                res.cn0_dbhz_est)
                if on_pred:
                    self._start_on_prediction(ch, ref, s, dt, dop)
                if p in self.nav.channels:
                    self.nav.resume(p, continuous=False)
                self._event(s, p, "predicted acquisition", f"Doppler {res.doppler_hz:.0f} Hz (predicted {dop:.0f}), "
                            f"code {res.code_phase_chips:.2f} chips (predicted {cp:.2f}), {res.cn0_dbhz_est:.1f} dB-Hz")
                self._sat(p).reacquisitions += 1

    def _note_fix(self):
        """Keep the recent fixes' velocities (the receiver's measured dynamics, see :meth:`_dynamics`)."""
        lf = self.nav.last_fix if self.nav is not None else None
        if lf is None:
            return
        s, fix = lf
        v = np.asarray(fix.velocity_ecef, float)
        if not np.all(np.isfinite(v)) or (self._fixes and self._fixes[-1][0] >= s):
            return
        self._fixes.append((float(s), v))
        while self._fixes and self._fixes[-1][0] - self._fixes[0][0] > DYN_HISTORY_S * self.fs:
            self._fixes.popleft()

    def _dynamics(self, before: float):
        """(acceleration bound m/s^2, speed bound m/s) of the windows: the configured bounds, raised to
        DYN_MARGIN x the receiver's largest acceleration / speed measured over the fixes of the last
        DYN_HISTORY_S before sample ``before`` (a turn at 50 m/s can hold 10-25 m/s^2 for seconds)."""
        rc = self.rc
        f = [x for x in self._fixes if x[0] <= before + 0.5 * self.fs]
        accel, speed = rc.accel_mps2, rc.speed_mps
        if f:
            speed = max(speed, DYN_MARGIN * max(float(np.linalg.norm(v)) for _, v in f))
        # accelerations over >= 0.5 s baselines (the fixes' velocity noise is ~0.1 m/s)
        base = 0.5 * self.fs
        acc = [float(np.linalg.norm(f[j][1] - f[i][1])) / ((f[j][0] - f[i][0]) / self.fs)
               for i in range(len(f)) for j in range(i + 1, len(f)) if f[j][0] - f[i][0] >= base
               and (j == i + 1 or f[j - 1][0] - f[i][0] < base)]
        if acc:
            accel = max(accel, DYN_MARGIN * max(acc))
        return accel, speed

    def _catch_up(self, prn, s, next_start):
        """Run a channel opened at sample s (inside the chunk just tracked) up to the pipeline's position."""
        ch = self.channels[prn]
        overlap = int(CATCH_UP_OVERLAP_S * self.fs)
        block = self.reader.read(int(s), int(next_start - s) + overlap)
        recs = ch.process(block, int(s))
        if self.writer is not None:
            self.writer.append_channel(prn, recs)
        self.note(prn, recs)
        if self.nav is not None:
            self.nav.add_records(prn, recs, ch.bit_offset, ch.dll_hold_s)
        if ch.lost:                         # lost again at once: the next chunk's after_chunk handles it
            pass

    def _lost(self, prn):
        sat = self._sat(prn)
        sat.restore_at = None
        if self.nav is not None:
            self.nav.suspend(prn)
        g = list(sat.good)
        if not g:
            if sat.ref is not None and sat.lost_at is not None:
                # lost again before a good state (re-acquired just before another blockage): the previous
                # prediction still holds, its window keeps widening with the age of that last good state
                sat.state = "reacquiring"
                sat.searches = 0
                self._event(sat.lost_at, prn, "lost", "(no new good state: previous prediction kept)")
                return
            sat.state, sat.ref = "searching", None
            self._event(self.reader.first, prn, "lost", "(no good state: cold search)")
            return
        last = g[-1][0]
        # the lock detectors lag: start the prediction a little before the last good epoch
        cut = [x for x in g if x[0] <= last - GOOD_MARGIN_S * self.fs] or g[:1]
        s0, tx0, d0 = cut[-1]
        rate = 0.0
        if len(g) >= 5 and g[-1][0] - g[0][0] > 0.3 * self.fs:
            t = np.array([x[0] for x in g]) / self.fs
            rate = float(np.polyfit(t - t[0], [x[2] for x in g], 1)[0])
        sat.ref = (s0, tx0, d0, rate, sat.bit_offset)
        sat.lost_at = s0
        sat.state = "reacquiring"
        sat.searches = 0
        self._event(s0, prn, "lost", f"Doppler {d0:.0f} Hz, rate {rate:.2f} Hz/s")

    def _cold_doppler_window(self):
        """(centre, half width) Hz of a cold search, or None (the configured grid) when not narrower.

        Any satellite's Doppler is -(range rate + receiver velocity . line of sight) / lambda + c, c the
        receiver clock's Doppler (-drift / lambda), |range rate| <= MAX_LOS_RATE_MPS; with R = (that +
        receiver speed) / lambda:  after a fix (drift and speed known) the window is c +/- R; before it,
        c itself is bounded by the channels in lock (c within R of each of their Dopplers), so any Doppler
        lies in [max(d_i) - 2R, min(d_i) + 2R].  Plus COLD_MARGIN_HZ either side."""
        grid = self.cfg.acquisition.doppler_max_hz
        fix = self.nav.last_fix[1] if self.nav is not None and self.nav.last_fix is not None else None
        if fix is not None and np.isfinite(fix.clock_drift_mps):
            v = np.asarray(fix.velocity_ecef, float)
            speed = float(np.linalg.norm(v)) if np.all(np.isfinite(v)) else self.rc.speed_mps
            half = (MAX_LOS_RATE_MPS + speed) / self.lambda_m + COLD_MARGIN_HZ
            return (-fix.clock_drift_mps / self.lambda_m, half) if half < grid else None
        lock_min = self.cfg.tracking.lock_cn0_min_dbhz
        dops = [ch.doppler_hz for ch in self.channels.values()
                if ch.st[K.S_LOCK] > 0 and ch.cn0_dbhz >= lock_min and not ch.lost]
        if not dops:
            return None
        r2 = 2.0 * (MAX_LOS_RATE_MPS + self.rc.speed_mps) / self.lambda_m
        lo = max(dops) - r2 - COLD_MARGIN_HZ
        hi = min(dops) + r2 + COLD_MARGIN_HZ
        half = 0.5 * (hi - lo)
        return (0.5 * (hi + lo), half) if half < grid else None

    def _below_mask(self, prn, s) -> bool:
        if self.nav is None:
            return False
        los = self.nav.satellite_los(prn, s)
        return los is not None and los[1] < self.cfg.navigation.elevation_mask_deg

    def predict(self, sat: SatTrack, s: float):
        """(Doppler Hz, relative transmit time s) predicted at sample s from the last good state."""
        s0, tx0, d0, rate, _ = sat.ref
        dt = (s - s0) / self.fs
        n = max(2, int(np.ceil(dt / 0.5)) + 1)
        ts = np.linspace(0.0, dt, n)
        # Doppler rate of the tracked state for the first seconds; with an ephemeris and a fix, the
        # change of the satellite's line-of-sight velocity (receiver velocity and clock drift held)
        eph = None
        if self.nav is not None:
            a = self.nav.satellite_los(sat.prn, s0)
            if a is not None:
                eph = [self.nav.satellite_los(sat.prn, s0 + t * self.fs) for t in ts]
                if any(e is None for e in eph):
                    eph = None
        if eph is not None:
            dop = d0 - (np.array([e[0] for e in eph]) - eph[0][0]) / self.lambda_m
        else:
            dop = d0 + rate * np.minimum(ts, 2.0)
        # transmit time advances at 1 + Doppler / carrier frequency (trapezoidal integral)
        integ = float(np.sum(0.5 * (dop[1:] + dop[:-1]) * np.diff(ts))) if n > 1 else 0.0
        tx = tx0 + dt + integ / self.signal.carrier_hz
        return float(dop[-1]), tx

    def _hot(self, sat: SatTrack, s_next: int):
        rc = self.rc
        prn = sat.prn
        s = float(s_next)
        age = (s - sat.lost_at) / self.fs
        if age > rc.max_age_s:
            sat.state = "searching"
            self._event(s, prn, "prediction too old", "(cold search)")
            return
        if self._below_mask(prn, s):
            return
        dop, tx = self.predict(sat, s)
        accel, speed = self._dynamics(sat.lost_at)
        dv = min(accel * age, 2.0 * speed)
        dr = min(0.5 * accel * age * age, 2.0 * speed * age)
        # every other search: the window that holds for any acceleration (the velocity can change by at
        # most twice the speed bound): it finds a satellite whose prediction the turn has carried beyond
        # the acceleration-bounded window
        dr_narrow = dr
        if sat.searches % 2 == 1 and (dv < 2.0 * speed or dr < 2.0 * speed * age):
            dv, dr = 2.0 * speed, 2.0 * speed * age
        dop_half = rc.doppler_hz + dv / self.lambda_m
        code_half = rc.code_chips + dr / self.chip_m
        if dop_half > self.cfg.acquisition.doppler_max_hz:
            sat.state = "searching"
            self._event(s, prn, "window beyond the acquisition grid", "(cold search)")
            return
        code_len = self.signal.code_len
        chip = self.signal.chip_rate
        cp_pred = (tx * 1e3 % 1.0) * code_len                   # code phase at sample s (chips)
        n = int(rc.coherent_ms * rc.noncoherent * 1e-3 * self.fs)
        block = self.reader.read(int(s), n)
        sat.searches += 1
        res = narrow_search(block, int(s), self.fs, self.if_hz, prn, dop, dop_half, cp_pred,
                            code_half, rc.coherent_ms, rc.noncoherent, rc.pfa, self.signal)
        if res is None:
            return False
        # code phase: the prediction while its uncertainty is below the search's resolution
        cp = res.code_phase_chips
        predicted = False
        # (judged by the acceleration-bounded uncertainty also when the speed-bounded window found it)
        if dr_narrow / self.chip_m < 0.05 and code_half < code_len / 4:
            diff = (cp - cp_pred + code_len / 2) % code_len - code_len / 2
            if abs(diff) < 0.5:
                cp = cp_pred
                predicted = True
        ch = self._open(prn, res.doppler_hz, cp, int(s))
        self._open_cn0[prn] = (int(s), res.cn0_dbhz_est)     # (its strength until in lock: image test)
        # continue the old channel's code-period count: the predicted transmit time fixes the integer ms
        st = ch.st
        s_first = float(st[K.S_NEXT_SAMPLE])
        tx_first = tx + (s_first - s) / self.fs * (1.0 + res.doppler_hz / self.signal.carrier_hz)
        period = int(round((tx_first - st[K.S_CODE_PHASE] / chip) * 1e3))
        st[K.S_CODE_PERIOD] = period
        bit_off = sat.ref[4]
        bit_ms = self.signal.bit_ms(prn)
        if bit_off >= 0 and self.signal.secondary(prn) is None:
            st[K.S_BIT_OFFSET] = bit_off
            ch.hist[bit_off % bit_ms] = 12        # bit sync known: the histogram confirms it at once
        ch.cfg[K.C_PULL_IN_MS] = rc.pull_in_ms
        # the code error left by the search (a fraction of a chip) converges within the short pull-in
        ch.cfg[K.C_DLL_BW_PULL] = rc.dll_bw_pull_in_hz
        # a 2nd-order DLL would wind its rate integrator up on the search's initial code error (metres, at
        # the pull-in bandwidth) and ring for seconds: 1st order until the error has converged
        ch.cfg[K.C_DLL_ORDER] = 1
        sat.restore_at = s + HOT_DLL_FIRST_ORDER_S * self.fs
        sat.reacquisitions += 1
        if self.nav is not None:
            # started on the predicted code phase: no DLL transient, the shorter settle
            self.nav.resume(prn, continuous=bit_off >= 0,
                            settle_s=rc.settle_predicted_s if predicted else rc.settle_s)
        self._event(s, prn, "re-acquired",
                    f"after {age:.2f} s, Doppler {res.doppler_hz:.1f} Hz (predicted {dop:.1f} +/- {dop_half:.0f}), "
                    f"code {res.code_phase_chips:.2f} chips (predicted {cp_pred:.2f} +/- {code_half:.2f})")
        return True

    # ------------------------------------------------------------------ summary
    def summary(self) -> dict:
        """Per PRN: its final state, number of re-acquisitions and of false locks."""
        return {p: {"state": s.state, "reacquisitions": s.reacquisitions, "false_locks": s.false_locks}
                for p, s in sorted(self.sats.items())}
