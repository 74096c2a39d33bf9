"""Channels of a second-frequency signal (GPS L5, Galileo E5a) aided by the L1 / E1 channels of the same
satellites (:class:`AidedBand`).

The second signal is recorded in a file of its own on the same clock (``input.signal_files``): sample ``n``
of the L1 stream and sample ``n * fs_band / fs_L1`` of the band's stream are the same instant.  For every
satellite an L1 channel tracks in phase lock, the band searches the satellite's signal around the code phase
and Doppler the L1 channel predicts (receiver.acquisition.aided) and, once found, tracks it with a scalar
channel (receiver.tracking.scalar: the Q5 pilot, NH20 wiped once synchronised; E5a: the E5a-Q pilot, CS100
wiped once synchronised, the same sign-change histogram over 100 code periods).  The aiding channels are the
scalar L1 C/A ones or the Galileo E1 ones (receiver.tracking.gal_channels.GalTrack: 4-ms code periods).  Without aiding
(``aiding=False``) it searches every code phase over the full Doppler range instead.  A failed search is
retried ``retry_s`` later; a lost channel is searched for again.  Only the last ``keep_s`` of each channel's
records are kept (for the observables): memory does not grow with the run.

:meth:`AidedBand.measure_at` also gives the carrier of the band (RINEX L5Q / E5a-Q): the channel's Costas loop
is blind to half a cycle, which the pilot resolves once its secondary code is wiped (records in bit_sync): the
prompt's sign over the current lock run is then the carrier's polarity.  The lock time counts from the first
record of the channel's current run of phase-locked records (a new channel, or ``pll_lock`` 0, starts a run).
"""
from __future__ import annotations

import numpy as np

from ..acquisition.aided import predict_from_l1, search
from ..gnss.signals import GPS_L1CA
from ..runfile import record
from . import kernel as K
from .scalar import Channel

#: one row per search (run file /acquisition_l5)
SEARCH_DTYPE = np.dtype([("time_s", "f8"), ("prn", "i4"), ("aided", "u1"), ("detected", "u1"),
                         ("metric", "f4"), ("threshold", "f4"), ("code_phase_chips", "f8"),
                         ("doppler_hz", "f8"), ("cells", "i4")])


def aiding_state(ch) -> tuple:
    """(still pulling in, code phase in chips at ``ch.next_sample``) of an aiding channel: a Galileo E1
    GalTrack (``pulling_in``, ``code_phase``) or a scalar Channel (kernel state)."""
    if hasattr(ch, "pulling_in"):
        return bool(ch.pulling_in), float(ch.code_phase)
    return int(ch.st[K.S_MODE]) == K.MODE_PULL_IN, float(ch.st[K.S_CODE_PHASE])


class AidedBand:
    """The second band's channels (``channels``: PRN -> Channel) and their recent records.

    trk_cfg: the receiver's ``tracking`` section; reader: the band's input stage (``fs``, ``if_hz``,
    ``first``, ``read``); fs_l1, first_l1: the L1 stream's rate and first sample; base: the aiding channels'
    signal (GPS L1 C/A, Galileo E1)."""

    def __init__(self, trk_cfg, reader, signal, fs_l1: float, first_l1: int, aiding: bool = True,
                 n_ms: int = 10, code_half_chips: float = 5.0, doppler_max_hz: float = 7000.0,
                 retry_s: float = 1.0, keep_s: float = 2.0, pfa: float = 1e-3, base=GPS_L1CA):
        self.trk_cfg, self.reader, self.signal, self.base = trk_cfg, reader, signal, base
        self.fs, self.if_hz = reader.fs, reader.if_hz
        self.fs_l1, self.first_l1 = fs_l1, first_l1
        self.aiding, self.n_ms, self.code_half = aiding, n_ms, code_half_chips
        self.doppler_max, self.retry_s, self.keep_s, self.pfa = doppler_max_hz, retry_s, keep_s, pfa
        self.channels: dict[int, Channel] = {}
        self.recs: dict[int, np.ndarray] = {}
        self.next_try: dict[int, float] = {}
        self.searches: list = []             # SEARCH_DTYPE rows not yet written
        self.lock_runs: dict[int, list] = {}  # PRN -> start times of its channel's runs of phase-locked records

    def to_band(self, n_l1: int) -> int:
        """The band's sample index at the instant of L1 sample ``n_l1``."""
        return self.reader.first + int(round((n_l1 - self.first_l1) * self.fs / self.fs_l1))

    def process(self, start_l1: int, n_l1: int, overlap_l1: int = 0) -> dict:
        """Track every channel over the band's samples of L1 samples ``start_l1`` .. ``+ n_l1`` (and the
        ``overlap_l1`` after them, where an epoch that starts before the chunk end may end: the next chunk
        starts at the band's ``start_l1 + n_l1``); returns {prn: EPOCH_DTYPE records} of the chunk."""
        b0 = self.to_band(start_l1)
        block = self.reader.read(b0, self.to_band(start_l1 + n_l1 + overlap_l1) - b0)
        out = {}
        for prn, ch in list(self.channels.items()):
            if ch.next_sample < b0:
                continue
            r = ch.process(block, b0)
            out[prn] = r
            if len(r):
                old = self.recs.get(prn, np.zeros(0, record.EPOCH_DTYPE))
                both = np.concatenate([old, r])
                self.recs[prn] = both[both["time_s"] >= both["time_s"][-1] - self.keep_s]
                self._note_lock_runs(prn, r, len(old) > 0 and bool(old["pll_lock"][-1]))
            if ch.lost:
                del self.channels[prn]
                self.recs.pop(prn, None)
                self.lock_runs.pop(prn, None)
        return out

    def _note_lock_runs(self, prn: int, r: np.ndarray, locked_before: bool):
        """Record the start times of the runs of phase-locked records in the new records ``r`` (``locked_before``:
        the previous record was locked); only the starts a record still kept can belong to are kept."""
        lock = r["pll_lock"] > 0
        prev = np.concatenate([[locked_before], lock[:-1]])
        runs = self.lock_runs.setdefault(prn, [])
        runs.extend(r["time_s"][lock & ~prev].tolist())
        t_old = float(self.recs[prn]["time_s"][0])
        while len(runs) > 1 and runs[1] <= t_old:
            runs.pop(0)

    def start(self, l1_channels: dict, end_l1: int):
        """Search for the band's signal of every satellite tracked in phase lock on L1 (``l1_channels``:
        PRN -> L1 Channel) that has no band channel, at the L1 channels' next epoch (after ``end_l1``)."""
        t = (end_l1 - self.first_l1) / self.fs_l1
        for prn, ch in l1_channels.items():
            if prn in self.channels or prn not in self.signal.prns or self.next_try.get(prn, -1.0) > t:
                continue
            pulling, code_l1 = aiding_state(ch)
            if ch.lost or pulling:
                continue
            n1 = ch.next_sample
            n5 = self.to_band(n1)
            n_need = int(round(self.fs * 1e-3)) * (self.n_ms + 1)
            if n5 + n_need > self.reader.end:
                continue
            block = self.reader.read(n5, n_need)
            code5, dop5 = predict_from_l1(code_l1, ch.doppler_hz, self.signal, self.base.chip_rate,
                                          self.base.carrier_hz, self.base.code_len)
            if self.aiding:
                res = search(block, self.fs, self.if_hz, self.signal, prn, dop5, 0.0, code5, self.code_half,
                             self.n_ms, pfa=self.pfa)
                dop = dop5                        # the L1 Doppler is better than a 1-ms search bin
            else:
                res = search(block, self.fs, self.if_hz, self.signal, prn, 0.0, self.doppler_max, None,
                             n_ms=self.n_ms, pfa=self.pfa)
                dop = res.doppler_hz
            self.searches.append((n5 / self.fs, prn, self.aiding, res.detected, res.metric, res.threshold,
                                  res.code_phase_chips, res.doppler_hz, res.cells))
            if not res.detected:
                self.next_try[prn] = t + self.retry_s
                continue
            self.channels[prn] = Channel(prn, dop, res.code_phase_chips, n5, self.trk_cfg, self.fs, self.if_hz,
                                         channel_id=prn, signal=self.signal)

    def take_searches(self) -> np.ndarray:
        """The searches since the last call (SEARCH_DTYPE)."""
        rows = np.array(self.searches, SEARCH_DTYPE)
        self.searches = []
        return rows

    def code_phase_at(self, prn: int, t_s: float):
        """(code phase in chips within the code period, C/N0, carrier Doppler phase in cycles) of ``prn``'s
        channel at receiver time ``t_s``
        (s since the first sample), from the epoch record that contains it; None when not tracked in phase
        lock there."""
        r = self.recs.get(prn)
        if r is None or not len(r):
            return None
        i = int(np.searchsorted(r["time_s"], t_s, side="right")) - 1
        if i < 0 or t_s - r["time_s"][i] > 2e-3 * max(int(r["integration_ms"][i]), 1) or not r["pll_lock"][i]:
            return None
        dt = t_s - r["time_s"][i]
        chips = r["code_phase_chips"][i] + dt * r["code_rate_hz"][i]
        # the carrier NCO's Doppler phase (cycles; the IF's share taken out): the range changes by -lambda x it
        cyc = r["carrier_phase_cycles"][i] + dt * (r["doppler_hz"][i] + self.if_hz) - self.if_hz * t_s
        return float(chips % self.signal.code_len), float(r["cn0_dbhz"][i]), float(cyc)

    def measure_at(self, prn: int, t_s: float) -> dict | None:
        """The band's measurements of ``prn`` at receiver time ``t_s`` (None when :meth:`code_phase_at` is):
        {"chips", "cn0_dbhz", "nco_cycles" (the NCO's Doppler phase, :meth:`code_phase_at`), "carrier_cycles"
        (that plus half a cycle when the pilot reads negative), "doppler_hz" (the carrier NCO's), "lock_time_s",
        "half_cycle_resolved"}."""
        m = self.code_phase_at(prn, t_s)
        if m is None:
            return None
        r = self.recs[prn]
        i = int(np.searchsorted(r["time_s"], t_s, side="right")) - 1
        runs = [t for t in self.lock_runs.get(prn, ()) if t <= r["time_s"][i]]
        t0 = runs[-1] if runs else float(r["time_s"][0])
        sel = (r["time_s"] >= t0) & (r["time_s"] <= r["time_s"][i]) & (r["state"] == record.STATE_BIT_SYNC)
        resolved = bool(r["state"][i] == record.STATE_BIT_SYNC)
        polarity = float(np.sum(r["prompt_i"][sel].astype(float))) if resolved else 0.0
        return {"chips": m[0], "cn0_dbhz": m[1], "nco_cycles": m[2],
                "carrier_cycles": m[2] + (0.5 if polarity < 0 else 0.0),
                "doppler_hz": float(r["doppler_hz"][i]), "lock_time_s": float(t_s - t0),
                "half_cycle_resolved": resolved}
