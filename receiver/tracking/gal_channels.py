"""Galileo E1 channels in the receiver pipeline: :class:`GalTrack` (a :class:`receiver.tracking.gal.GalChannel`
that consumes the chunk loop's sample blocks and writes channel-epoch records) and :class:`GalChannelManager`
(their lifecycle: the first acquisition, loss of lock, cold re-acquisition of the missing PRNs).

Records (:data:`receiver.runfile.record.EPOCH_DTYPE`), one per 4-ms E1 code period:

* ``code_period`` counts 4-ms periods (the first epoch is period 1 of the acquisition block), so the
  relative transmit time is ``code_period x 4 ms + code_phase_chips / 1.023 MHz`` (ChannelNav.period_s);
* ``prompt_i`` / ``prompt_q``: the E1-C (pilot) prompt with CS25 wiped off -- what the PLL and DLL track --,
  ``early`` / ``late``: the pilot's |E| and |L|; ``prompt1_i`` / ``prompt1_q``: the E1-B (data) prompt, one
  I/NAV symbol (the carrier locked on the pilot, transmitted as -e_C: a logic-0 symbol reads negative; the
  I/NAV decoder takes either polarity from the page sync); ``prompt2_*`` zero; ``integration_ms`` 4;
* ``state``: STATE_PULL_IN for the first PULL_IN_EPOCHS, then STATE_BIT_SYNC (every period is a symbol:
  no bit synchronisation to wait for), STATE_LOST on the epoch the channel gives up;
* ``pll_lock``: the low-passed phase-lock indicator cos(2 phi) of the pilot above LOCK_PLI and the C/N0
  above tracking.lock_cn0_min_dbhz; ``lost`` after tracking.lost_ms without lock.

Vector tracking (receiver.tracking.vector): the channel's NCO and loop state live in a kernel-style state row
``st`` (receiver.tracking.kernel S_* slots, the Galileo-only quantities in G_* slots of the bit-sync ring, which a
Galileo channel does not use), with ``cfg`` and ``code_ext`` (the E1-C and E1-B replicas and CS25, one row), so
that the vector tracker can hand its NCOs to the vector loop, which runs its epochs compiled
(receiver.tracking.vector.galileo) on the same row, and give them back (``set_external``).

The lifecycle is simpler than the scalar channels' (receiver.tracking.channels): a lost Galileo satellite
goes back to the cold round-robin search (no hot re-acquisition around the prediction), and there are no
carrier false-lock restarts (the pilot's four-quadrant PLL has no data to slip on).
"""
from __future__ import annotations

import math

import numpy as np

from ..gnss.satid import sat_label
from ..gnss.signals_gal import GAL_E1
from ..runfile import record
from . import kernel as K
from .gal import GalChannel, _correlate_block

PULL_IN_EPOCHS = 50          # 200 ms: the PLL settles from the refined Doppler
LOCK_PLI = 0.5               # low-passed cos(2 phi) of the pilot prompt above this: phase lock
PLI_KEEP = 0.9               # its low-pass factor per 4-ms epoch
PLL_BW_HZ = 15.0             # pilot PLL noise bandwidth (4-ms epochs: B T = 0.06)
DLL_BW_HZ = 8.0              # carrier-aided DLL noise bandwidth (scripts/bench/accuracy_galileo.py --dll-bw); 2 Hz
                             # gave no better carrier-smoothed fixes on short runs (docs/galileo.md, Limits)
DLL_SPACING = 0.2            # early-late spacing (chips)
REFINE_PERIODS = 50          # 200 ms of pilot periods refine the Doppler and find the CS25 phase
REACQ_PER_ATTEMPT = 4        # cold searches per attempt

# ---- Galileo slots of the state row (kernel slots S_RING.. are the 1-ms bit-sync ring, unused here)
G_CARR_PHASE01 = K.S_RING        # carrier NCO phase at S_NEXT_SAMPLE modulo 1 (cycles; S_CARR_PHASE accumulates)
G_FREQ_INT = K.S_RING + 1        # PLL integrator (Hz, IF included)
G_CS25 = K.S_RING + 2            # CS25 phase: the pilot's secondary chip of code period k is (k + this) % 25
G_PLI = K.S_RING + 3             # low-passed cos(2 phi) of the pilot prompt
N_REPLICA = 8184                 # BOC(1,1) half-chips of one replica (code_ext: E1-C, E1-B, then CS25)


class GalTrack(GalChannel):
    """One Galileo E1 channel of the pipeline: ``process(block, block_start)`` runs every 4-ms epoch that fits
    in the complex sample block (first sample = file index ``block_start``) and returns EPOCH_DTYPE records
    (module docstring).  The loops run per epoch in Python; the correlations (the per-sample work) are one
    compiled call per epoch."""

    def __init__(self, prn, fs, if_hz, sample, code_phase_chips, doppler_hz, cs25_offset, trk_cfg,
                 channel_id: int = 0, signal=GAL_E1):
        self.st = np.zeros(K.N_STATE)           # (before the base class sets the NCO state through the properties)
        self.cfg = np.zeros(K.N_CONFIG)
        self.hist = np.zeros(20, np.int64)
        super().__init__(prn, fs, if_hz, sample, code_phase_chips, doppler_hz, cs25_offset, pll_bw_hz=PLL_BW_HZ,
                         dll_bw_hz=DLL_BW_HZ, dll_spacing=DLL_SPACING)
        self.signal = signal
        self.id = channel_id
        c = self.cfg
        c[K.C_FS], c[K.C_IF], c[K.C_CHIP_RATE], c[K.C_CARRIER_HZ] = self.fs, self.if_hz, signal.chip_rate, \
            signal.carrier_hz
        c[K.C_CODE_LEN], c[K.C_EL_SPACING], c[K.C_BIT_MS] = signal.code_len, self.d, 1.0
        c[K.C_MAX_INT_MS], c[K.C_CN0_WIN_MS] = 1.0, float(getattr(trk_cfg, "cn0_window_ms", 200))
        c[K.C_LOCK_CN0_MIN], c[K.C_LOST_MS] = float(trk_cfg.lock_cn0_min_dbhz), float(trk_cfg.lost_ms)
        self.st[K.S_INT_MS] = 1.0
        self.lock_cn0 = float(trk_cfg.lock_cn0_min_dbhz)
        self.lost_epochs = max(1, int(math.ceil(trk_cfg.lost_ms / 4.0)))
        self.lost = False
        self.vector_carrier = self.vector_code = False
        self._epochs = 0
        self._unlocked = 0
        self._cn0 = float("nan")

    # ---------------------------------------------------------------- state (in the state row)
    @property
    def next_sample(self) -> int:
        """File sample index of the next epoch's first sample."""
        return int(self.st[K.S_NEXT_SAMPLE])

    @next_sample.setter
    def next_sample(self, v):
        self.st[K.S_NEXT_SAMPLE] = v

    @property
    def code_phase(self) -> float:
        """Replica code phase at next_sample (chips)."""
        return self.st[K.S_CODE_PHASE]

    @code_phase.setter
    def code_phase(self, v):
        self.st[K.S_CODE_PHASE] = v

    @property
    def carr_hz(self) -> float:
        """Carrier NCO frequency (Hz, IF included)."""
        return self.st[K.S_CARR_FREQ]

    @carr_hz.setter
    def carr_hz(self, v):
        self.st[K.S_CARR_FREQ] = v

    @property
    def carr_phase(self) -> float:
        """Carrier NCO phase at next_sample, modulo 1 (cycles)."""
        return self.st[G_CARR_PHASE01]

    @carr_phase.setter
    def carr_phase(self, v):
        self.st[G_CARR_PHASE01] = v

    @property
    def carr_cycles(self) -> float:
        """Accumulated carrier NCO phase at next_sample (cycles, IF included)."""
        return self.st[K.S_CARR_PHASE]

    @carr_cycles.setter
    def carr_cycles(self, v):
        self.st[K.S_CARR_PHASE] = v

    @property
    def period(self) -> int:
        """Code periods since the channel start (the first epoch is period 1 of the acquisition block)."""
        return int(self.st[K.S_CODE_PERIOD])

    @period.setter
    def period(self, v):
        self.st[K.S_CODE_PERIOD] = v

    @property
    def dll_rate(self) -> float:
        """DLL code-rate correction (chips/s) on top of the carrier-aided rate."""
        return self.st[K.S_DLL_RATE]

    @dll_rate.setter
    def dll_rate(self, v):
        self.st[K.S_DLL_RATE] = v

    @property
    def freq_int(self) -> float:
        """PLL integrator (Hz, IF included)."""
        return self.st[G_FREQ_INT]

    @freq_int.setter
    def freq_int(self, v):
        self.st[G_FREQ_INT] = v

    @property
    def cs25_offset(self) -> int:
        """CS25 phase: code period k carries the pilot's secondary chip (k + cs25_offset) % 25."""
        return int(self.st[G_CS25])

    @cs25_offset.setter
    def cs25_offset(self, v):
        self.st[G_CS25] = v

    @property
    def _pli(self) -> float:
        return self.st[G_PLI]

    @_pli.setter
    def _pli(self, v):
        self.st[G_PLI] = v

    @property
    def lost(self) -> bool:
        """The channel gave up (or the vector tracker closed it)."""
        return self.st[K.S_MODE] == K.MODE_LOST

    @lost.setter
    def lost(self, v):
        if v:
            self.st[K.S_MODE] = K.MODE_LOST

    @property
    def code_ext(self) -> np.ndarray:
        """The replicas of the vector loop's code row: E1-C and E1-B BOC(1,1) half-chips, then the CS25 signs."""
        return np.concatenate([self.rep_c, self.rep_b, self.cs25.astype(np.float32)])

    # ---------------------------------------------------------------- vector tracking
    def set_external(self, carrier: bool, code: bool):
        """Hand the NCOs to the vector loop (True, True) or take them back (False, False): on the way back the
        PLL integrator starts from the vector loop's last carrier command and the channel pulls in again (the
        pilot phase is not locked after frequency-locked vector tracking)."""
        back = (self.vector_carrier or self.vector_code) and not (carrier or code)
        self.vector_carrier, self.vector_code = carrier, code
        self.cfg[K.C_CARRIER_EXTERNAL] = 1.0 if carrier else 0.0
        self.cfg[K.C_CODE_EXTERNAL] = 1.0 if code else 0.0
        if carrier or code:
            # the state row as the vector loop's Galileo epoch reads it (receiver.tracking.vector.galileo)
            self.st[K.S_CODE_RATE] = self._epoch_length()[1] * self.fs
            self.st[K.S_PLL_FREQ] = self.carr_hz - self.if_hz
            self.st[K.S_INT_MS] = 1.0
            self.st[K.S_ABSENT_MS] = 0.0
            for i in (K.S_ACC_M2, K.S_ACC_M4, K.S_ACC_I2, K.S_ACC_Q2, K.S_ACC_N):
                self.st[i] = 0.0
        elif back:
            self.freq_int = self.carr_hz
            self.dll_rate = 0.0
            self._m = None
            self._epochs = 0
            self._unlocked = 0

    @property
    def bit_offset(self) -> int:
        """Code period of symbol 0: every 4-ms period carries one E1-B symbol, so 0 from the start."""
        return 0

    @property
    def pulling_in(self) -> bool:
        """Within the first PULL_IN_EPOCHS (the PLL settling from the refined Doppler)."""
        return self._epochs <= PULL_IN_EPOCHS

    @property
    def dll_hold_s(self) -> float:
        """The DLL tracks at its own bandwidth from the pull-in on (no weak-signal hold)."""
        return 0.0

    @property
    def doppler_hz(self) -> float:
        """Carrier NCO frequency minus IF (Hz)."""
        return self.carr_hz - self.if_hz

    @property
    def cn0_dbhz(self) -> float:
        """The latest C/N0 estimate of the whole E1 signal, E1-B + E1-C (dB-Hz)."""
        return self._cn0

    def process(self, block: np.ndarray, block_start: int) -> np.ndarray:
        """Track the epochs that fit in ``block``; EPOCH_DTYPE records (none once lost)."""
        if self.lost:
            return np.zeros(0, record.EPOCH_DTYPE)
        cap = int(len(block) / (self.fs * 4e-3)) + 2
        out = np.zeros(cap, record.EPOCH_DTYPE)
        i = 0
        end = block_start + len(block)
        while i < cap and not self.lost:
            n, step = self._epoch_length()
            k0 = self.next_sample - block_start
            if k0 < 0 or self.next_sample + n > end:
                break
            e, p, l, b = _correlate_block(block, k0, n, self.code_phase, step, self.carr_phase,
                                          self.carr_hz / self.fs, self.rep_c, self.rep_b, 0.5 * self.d)
            sample, cp, period, pb, pc, f_hz, cn0, cyc, ae, al, err, tau = self._update(e, p, l, b, n, step)
            self._fill(out[i], sample, cp, period, step, pb, pc, f_hz, cn0, cyc, ae, al, err, tau)
            i += 1
        return out[:i]

    def _fill(self, r, sample, cp, period, step, pb, pc, f_hz, cn0, cyc, ae, al, err, tau):
        """One record from an epoch's values; the lock and loss of lock judged."""
        pw = pc.real * pc.real + pc.imag * pc.imag
        cos2 = (pc.real * pc.real - pc.imag * pc.imag) / pw if pw > 0 else 0.0
        self._pli = PLI_KEEP * self._pli + (1.0 - PLI_KEEP) * cos2
        self._cn0 = cn0
        self._epochs += 1
        pulling = self._epochs <= PULL_IN_EPOCHS
        lock = (not pulling) and self._pli > LOCK_PLI and cn0 >= self.lock_cn0
        self._unlocked = 0 if (lock or pulling) else self._unlocked + 1
        if self._unlocked >= self.lost_epochs:
            self.lost = True
        st = self.st
        st[K.S_CN0] = cn0
        st[K.S_LOCK] = 1.0 if lock else 0.0
        if not self.lost:
            st[K.S_MODE] = K.MODE_PULL_IN if pulling else K.MODE_BIT_SYNC
        r["time_s"] = sample / self.fs
        r["sample_index"] = sample
        r["code_period"] = period
        r["code_phase_chips"] = cp
        r["code_rate_hz"] = step * self.fs
        r["doppler_hz"] = f_hz - self.if_hz
        r["carrier_phase_cycles"] = cyc
        r["prompt_i"], r["prompt_q"] = pc.real, pc.imag
        r["early"], r["late"] = ae, al
        r["cn0_dbhz"] = cn0
        r["pli"] = self._pli
        r["carrier_err_cycles"] = err
        r["code_err_chips"] = tau
        r["pll_lock"] = 1 if lock else 0
        r["state"] = record.STATE_LOST if self.lost else (record.STATE_PULL_IN if pulling else
                                                           record.STATE_BIT_SYNC)
        r["integration_ms"] = 4
        r["prompt1_i"], r["prompt1_q"] = pb.real, pb.imag


class GalChannelManager:
    """The Galileo E1 channels of a run, with the interface the pipeline uses of
    :class:`receiver.tracking.channels.ChannelManager`: ``start``, ``channels`` (prn -> GalTrack), ``note``,
    ``after_chunk``, ``summary`` and ``events``."""

    def __init__(self, cfg, reader, nav, fs, if_hz, signal, acquire, writer=None, log=None, prns=None):
        self.cfg = cfg
        self.reader = reader
        self.nav = nav
        self.fs, self.if_hz = float(fs), float(if_hz)
        self.signal = signal
        self.acquire = acquire
        self.prns = list(prns) if prns is not None else list(cfg.acquisition.prns)
        self.writer = writer
        self.log = log or (lambda msg: None)
        self.channels: dict[int, GalTrack] = {}
        self.events: list = []
        self.max_ch = cfg.tracking.max_channels
        self._ids: dict[int, int] = {}
        self._state: dict[int, dict] = {}
        self._rr = 0
        self._next_cold = None

    def _event(self, s, prn, what, detail=""):
        self.events.append((s / self.fs, prn, what, detail))
        self.log(f"channels: {(s - self.reader.first) / self.fs:7.2f} s {sat_label(prn, 'E')} {what} {detail}")

    def _open(self, r) -> GalTrack | None:
        """A channel from a detection: the Doppler refined and the CS25 phase found over REFINE_PERIODS pilot
        periods from the detection's block (None when the input ends before them)."""
        from ..acquisition.galileo import refine_pilot
        n = int(round(self.fs * 4e-3)) * (REFINE_PERIODS + 1)
        block = self.reader.read(int(r.sample_index), n)
        if len(block) < n:
            return None
        dop, off = refine_pilot(block, self.fs, self.if_hz, r.prn, r.code_phase_chips, r.doppler_hz,
                                n_periods=REFINE_PERIODS)
        cid = self._ids.setdefault(r.prn, len(self._ids))
        ch = GalTrack(r.prn, self.fs, self.if_hz, int(r.sample_index), r.code_phase_chips, dop, off,
                      self.cfg.tracking, channel_id=cid, signal=self.signal)
        self.channels[r.prn] = ch
        st = self._state.setdefault(r.prn, {"state": "tracking", "reacquisitions": 0, "false_locks": 0})
        st["state"] = "tracking"
        return ch

    def start(self, acq_start: int, notes=None):
        """The first cold acquisition of every PRN; channels for the strongest detections."""
        notes = [] if notes is None else notes
        results = self.acquire(self.cfg, self.reader, acq_start, self.prns, widen=True, notes=notes)
        if self.writer is not None:
            self.writer.write_acquisition(results, {"fs": self.fs, "pfa": self.cfg.acquisition.pfa,
                                                    "notes": "\n".join(notes)})
        for r in sorted([r for r in results if r.detected], key=lambda r: -r.metric)[:self.max_ch]:
            self._open(r)
        self._next_cold = acq_start + int(self.cfg.tracking.reacquire_s * self.fs)
        return results

    def note(self, prn: int, recs: np.ndarray):
        """(The scalar manager keeps good states for hot re-acquisition here; Galileo channels re-acquire
        cold.)"""

    def after_chunk(self, start: int, next_start: int):
        """Lost channels removed (navigation memory suspended); every tracking.reacquire_s a cold search of
        up to REACQ_PER_ATTEMPT missing PRNs at ``next_start``."""
        for prn, ch in list(self.channels.items()):
            if ch.lost:
                del self.channels[prn]
                self._state[prn]["state"] = "searching"
                if self.nav is not None:
                    self.nav.suspend(prn)
                self._event(ch.next_sample, prn, "lost", "(cold search)")
        if next_start + 0.25 * self.fs >= self.reader.end or next_start < self._next_cold or \
                len(self.channels) >= self.max_ch:
            return
        self._next_cold = next_start + int(self.cfg.tracking.reacquire_s * self.fs)
        missing = [p for p in self.prns if p not in self.channels]
        if not missing:
            return
        pick = [missing[(self._rr + k) % len(missing)] for k in range(min(REACQ_PER_ATTEMPT, len(missing)))]
        self._rr += REACQ_PER_ATTEMPT
        res = self.acquire(self.cfg, self.reader, next_start, pick)
        if self.writer is not None:
            self.writer.write_acquisition(res, {"fs": self.fs})
        for r in res:
            if r.detected and len(self.channels) < self.max_ch and self._open(r) is not None:
                if self.nav is not None and r.prn in self.nav.channels:
                    self.nav.resume(r.prn, continuous=False)
                self._state[r.prn]["reacquisitions"] += 1
                self._event(r.sample_index, r.prn, "cold acquisition", f"Doppler {r.doppler_hz:.0f} Hz")

    def summary(self) -> dict:
        """Per PRN: its final state, number of re-acquisitions and of false locks (always 0)."""
        return {p: dict(s) for p, s in sorted(self._state.items())}
