"""Numba tracking kernel: runs a channel's epochs over a block of samples.

All per-channel state lives in a float64 array (indices S_*), the configuration in another (C_*),
so that the whole epoch loop - correlation, discriminators, built-in loop filters, C/N0, lock
detection and bit synchronisation - runs in compiled code.  Python sees the channel between calls: a
vector loop or a Python carrier loop steps the kernel one epoch at a time and rewrites the NCO state
(S_CARR_FREQ, S_CODE_RATE, S_CODE_PHASE) between epochs.  ``C_CARRIER_EXTERNAL`` / ``C_CODE_EXTERNAL``
stop the kernel from touching the carrier / code NCO itself.

Why this module is long: the compiled channel kernel is one function by design (numba compiles one epoch
loop), with its state and configuration slot tables beside it.
"""
import math

import numpy as np
from numba import njit

from .correlator import correlate_ws, workspace

# ---- state indices
S_NEXT_SAMPLE = 0      # first sample of the next epoch (file index)
S_CODE_PHASE = 1       # replica code phase at S_NEXT_SAMPLE (chips)
S_CODE_RATE = 2        # chips/s
S_CARR_FREQ = 3        # carrier NCO frequency (Hz, IF + Doppler)
S_CARR_PHASE = 4       # carrier NCO phase at S_NEXT_SAMPLE (cycles, accumulated)
S_PLL_RATE = 5         # loop filter integrator: Doppler rate (Hz/s)
S_PLL_FREQ = 6         # loop filter integrator: Doppler (Hz)
S_CODE_PERIOD = 7      # code periods since channel start
S_MODE = 8             # STATE_* of receiver.runfile.record
S_MODE_MS = 9          # ms spent in the mode
S_INT_MS = 10          # current integration (code periods)
S_BIT_OFFSET = 11      # code_period % 20 at a bit edge (-1 unknown)
S_PREV_I = 12
S_CN0 = 13
S_PLI_I2 = 14
S_PLI_Q2 = 15
S_LOCK = 16
S_BAD_MS = 17
S_ACC_ABSI = 18
S_ACC_Q2 = 19
S_ACC_M2 = 20
S_ACC_M4 = 21
S_ACC_N = 22
S_ACC_I2 = 23
S_TOTAL_MS = 24
S_BITSYNC_MS = 25
S_LAST_PI = 26
S_LAST_PQ = 27
S_LOCK_ABSI = 28       # low-pass |I| and |Q| for the lock detector
S_LOCK_ABSQ = 29
S_DLL_RATE = 30        # 2nd-order DLL integrator (chips/s): code/carrier rate mismatch
S_PRES_ACC = 32        # signal-presence test: prompt power (per ms^2) summed over the current window (x ms)
S_PRES_MS = 33         # ms in the current presence window
S_PRES_REF = 34        # reference: low-passed window power while the signal is present
S_ABSENT_MS = 35       # ms since the presence test found the signal absent (0: present)
S_WEAK = 31            # 1: weak channel (tracking.weak; latched until lost)
S_ESYNC = 36           # 20 slots: bit-sync energy per bit-edge hypothesis (sum of |20-ms prompt sum|^2)
S_RING = 56            # 20 slots: the last 20 one-ms prompt I values
S_ESYNC_Q2 = 76        # sum of the 1-ms prompt power while the energies accumulate
S_RINGQ = 77           # 20 slots: the last 20 one-ms prompt Q values
S_CN0_MAX = 97         # largest C/N0 estimate after the pull-in (weak classification)
S_WEAK_DONE = 98       # 1: the weak classification has been made
S_FL_RE = 99           # false-lock test: sum of P2 conj(P1) (second against first half of bit-aligned epochs)
S_FL_IM = 100
S_FL_MS = 101          # ms summed in the current false-lock window
S_FL_COUNT = 102       # false locks corrected so far
S_STRONG_WIN = 103     # consecutive C/N0 windows of a weak channel at or above C_WEAK_EXIT_CN0 (hand-over)
S_FADE = 104           # fade hand-down (C_WEAK_FADE): 1 while the first weak C/N0 window of a strong channel
                       # handed down to the weak loops is not complete (no loss declared meanwhile), 2 after
                       # it until the channel is handed back or lost, 0 otherwise
N_STATE = 105

#: false-lock test window (ms of bit-aligned epochs >= 10 ms): 0.5 s leaves ~2 Hz of noise at 27 dB-Hz
FL_WINDOW_MS = 500.0

# ---- config indices
C_FS = 0
C_IF = 1
C_CHIP_RATE = 2
C_CARRIER_HZ = 3
C_CODE_LEN = 4
C_EL_SPACING = 5
C_PLL_BW = 6
C_PLL_ORDER = 7
C_FLL_BW = 8
C_DLL_BW = 9
C_DLL_BW_PULL = 10
C_PULL_IN_MS = 11
C_MAX_INT_MS = 12
C_CN0_WIN_MS = 13
C_LOCK_CN0_MIN = 14
C_LOCK_RATIO = 15      # lock when LPF|I| > ratio * LPF|Q|
C_CARRIER_EXTERNAL = 16
C_CODE_EXTERNAL = 17
C_CN0_EST = 18         # 0 = snv (locked prompt moments), 1 = m2m4
C_LOST_MS = 19
C_BIT_MS = 20          # code periods per data bit (20 for GPS LNAV)
C_DLL_ORDER = 21
C_NH_BASE = 22         # > 0: index in code_ext of the overlay-modulated code section (B1I D1 NH code)
C_NO_DATA = 23         # 1: the signal carries no data symbols (skip bit sync: integrate from pull-in end)
C_LOST_GRACE_MS = 24   # a channel younger than this is declared lost only after this long below the thresholds
C_PRES_MS = 25         # signal-presence window (ms; 0 = no presence test)
C_PRES_FRAC = 26       # absent: window power below this fraction of the reference
C_PRES_CN0 = 27        # the test declares absence only for a channel whose C/N0 is at least this (dB-Hz)
C_PRES_LOST_MS = 28    # absent this long: the channel is lost
C_WEAK_CN0 = 29        # > 0: a channel whose C/N0 estimates stay below this becomes weak (tracking.weak)
C_WEAK_INT_MS = 30     # coherent integration of a weak channel after bit sync (code periods)
C_WEAK_PLL_BW = 31     # PLL noise bandwidth of a weak channel (built-in loop)
C_WEAK_LOCK_RATIO = 32  # lock ratio of a weak channel (|I| over |Q|, low-passed over C_WEAK_LOCK_MS)
C_WEAK_LOCK_CN0 = 33   # C/N0 below which a weak channel's lock is lost
C_WEAK_LOCK_MS = 34    # low-pass time constant of a weak channel's lock detector (ms)
C_ESYNC_MIN_MS = 35    # > 0: bit sync by the energy of 20-ms sums once this many ms accumulated (weak signals)
C_WEAK_DLL_BW = 36     # DLL noise bandwidth of a weak channel after pull-in
C_WEAK_FLL_BW = 37     # FLL noise bandwidth of a weak channel's pull-in (0: none, the PLL alone)
C_WEAK_GRACE_MS = 38   # lost-grace time of a weak channel (it needs longer to reach phase lock)
C_EL_SPACING_WIDE = 39  # > 0: E-L spacing (chips) during pull-in and on weak channels (whole samples)
C_WEAK_DLL_HOLD_MS = 40  # a weak channel's DLL keeps C_DLL_BW this long after its pull-in, then C_WEAK_DLL_BW
C_WEAK_EXIT_CN0 = 41   # > 0: a weak channel whose C/N0 reaches this for WEAK_EXIT_WINDOWS windows is handed
                       # over to the normal loops (tracking.weak.exit_cn0_dbhz)
C_WEAK_FADE = 42       # 1: a strong channel about to be declared lost is handed down to the weak loops instead
                       # (tracking.weak.fade)
C_WEAK_NARROW_EL = 43  # 1: a weak channel's E-L spacing is C_EL_SPACING once its DLL hold is over
                       # (tracking.weak.narrow_el_after_hold), else C_EL_SPACING_WIDE while weak
C_WEAK_REPULL_FLL_BW = 44  # > 0: FLL noise bandwidth on the two halves of a bit-aligned epoch while a weak
                           # channel with bit sync is out of lock (tracking.weak.repull_fll_bw_hz)
N_CONFIG = 45

# ---- output columns (same order as receiver.runfile.record.EPOCH_DTYPE)
O_TIME, O_SAMPLE, O_PERIOD, O_CODE_PHASE, O_CODE_RATE, O_DOPPLER, O_CARR_PHASE, O_PI, O_PQ, \
    O_E, O_L, O_CN0, O_PLI, O_CARR_ERR, O_CODE_ERR, O_LOCK, O_STATE, O_INT_MS, \
    O_P1I, O_P1Q, O_P2I, O_P2Q = range(22)  # same order as EPOCH_DTYPE
N_OUT = 22

#: a channel is classed weak (tracking.weak) from its C/N0 estimates over this long after its pull-in
WEAK_DECIDE_MS = 1000.0
#: consecutive C/N0 windows at or above C_WEAK_EXIT_CN0 before a weak channel is handed over to the normal loops
WEAK_EXIT_WINDOWS = 3

MODE_PULL_IN = 0
MODE_TRACK = 1
MODE_BIT_SYNC = 2
MODE_LOST = 3


@njit(cache=True)
def el_spacing(st, cfg):
    """E-L spacing (chips) of this epoch: the whole-sample one (C_EL_SPACING_WIDE, when set) while the
    channel pulls in and on weak channels until their DLL hold (C_WEAK_DLL_HOLD_MS) is over -- a narrow
    correlator's +/- d/2 linear range loses weak signals and codes not yet settled -- else the configured one
    (the code noise of a settled DLL goes as the spacing: at 2.6 MS/s 0.79 against 0.5 chip)."""
    if cfg[C_EL_SPACING_WIDE] > 0 and (st[S_MODE] == MODE_PULL_IN or (st[S_WEAK] > 0 and (
            cfg[C_WEAK_NARROW_EL] == 0 or st[S_MODE_MS] < cfg[C_WEAK_DLL_HOLD_MS]))):
        return cfg[C_EL_SPACING_WIDE]
    return cfg[C_EL_SPACING]


#: state entries of the C/N0 estimator and the lock / PLI filters (reset if they become non-finite)
_ESTIMATOR_STATE = (S_CN0, S_PLI_I2, S_PLI_Q2, S_ACC_ABSI, S_ACC_Q2, S_ACC_M2, S_ACC_M4, S_ACC_N, S_ACC_I2,
                    S_LOCK_ABSI, S_LOCK_ABSQ, S_LAST_PI, S_LAST_PQ, S_PREV_I, S_PRES_ACC, S_PRES_MS,
                    S_PRES_REF, S_ABSENT_MS, S_FL_RE, S_FL_IM, S_FL_MS)


def repair_state(st: np.ndarray) -> bool:
    """Called once per block outside the compiled loop (which runs with fastmath, where NaN checks do
    not hold): a non-finite C/N0 estimate or lock filter (corrupt input, overflow) is reset to zero so the
    estimator starts a new window; non-finite NCO or loop-filter state cannot be repaired and marks the
    channel lost (it is re-acquired).  Returns True if anything was non-finite."""
    bad = ~np.isfinite(st)
    if not bad.any():
        return False
    est = list(_ESTIMATOR_STATE)
    st[est] = np.where(np.isfinite(st[est]), st[est], 0.0)
    if not np.isfinite(st).all():
        st[~np.isfinite(st)] = 0.0
        st[S_MODE] = MODE_LOST
    return True


@njit(cache=True, nogil=True)
def _reset_cn0_window(st):
    """Start a new C/N0 estimator window (its moment sums to zero)."""
    st[S_ACC_ABSI] = 0.0
    st[S_ACC_Q2] = 0.0
    st[S_ACC_I2] = 0.0
    st[S_ACC_M2] = 0.0
    st[S_ACC_M4] = 0.0
    st[S_ACC_N] = 0.0


@njit(cache=True, nogil=True)
def _hand_down(st, cfg):
    """Fade hand-down (tracking.weak.fade): a strong, bit-synchronised channel on the built-in loops that its
    lock detectors or the presence test are about to declare lost goes on with the weak loops instead (20-ms
    integration, narrow PLL / DLL, C/N0-aware lock detectors).  A signal faded by 10-20 dB (foliage, a body, a
    building edge) reads as absent to the normal detectors -- the 1-ms window power falls to the noise floor
    either way -- but the weak loops hold it; a signal that is gone is declared lost by them after their
    first C/N0 window (~0.25 s later).  Meanwhile the channel reports no lock (C/N0 0), so nothing it measures
    enters a fix; the presence reference is re-learnt at the faded level.  Returns True if handed down."""
    if cfg[C_WEAK_FADE] <= 0 or cfg[C_WEAK_CN0] <= 0 or st[S_WEAK] > 0 or st[S_MODE] != MODE_BIT_SYNC or \
            cfg[C_CARRIER_EXTERNAL] != 0 or cfg[C_CODE_EXTERNAL] != 0 or cfg[C_WEAK_INT_MS] <= cfg[C_MAX_INT_MS]:
        return False
    st[S_WEAK] = 1.0
    st[S_WEAK_DONE] = 1.0
    st[S_STRONG_WIN] = 0.0
    st[S_FADE] = 1.0
    st[S_CN0] = 0.0
    st[S_BAD_MS] = 0.0
    st[S_ABSENT_MS] = 0.0
    st[S_PRES_REF] = 0.0
    st[S_PRES_ACC] = 0.0
    st[S_PRES_MS] = 0.0
    st[S_LOCK_ABSI] = 0.0
    st[S_LOCK_ABSQ] = 0.0
    _reset_cn0_window(st)
    return True


@njit(cache=True, nogil=True)
def _samples_needed(st, cfg, periods):
    step = st[S_CODE_RATE] / cfg[C_FS]
    chips = periods * cfg[C_CODE_LEN] - st[S_CODE_PHASE]
    return int(math.ceil(chips / step))


@njit(cache=True, nogil=True)
def track_block(samples, block_start, st, cfg, code_ext, hist, out, max_epochs):
    """Run epochs while they fit in `samples` (file indices block_start...). Returns epochs written."""
    return track_block_ws(samples, block_start, st, cfg, code_ext, hist, out, max_epochs, workspace())


@njit(cache=True, fastmath=True, nogil=True)
def track_block_ws(samples, block_start, st, cfg, code_ext, hist, out, max_epochs, ws):
    """:func:`track_block` with the correlator's workspace (``correlator.workspace()``) from the caller, for
    callers that run one epoch per call (the compiled carrier loops, the vector loop)."""
    fs = cfg[C_FS]
    nblk = samples.shape[0]
    n_out = 0
    two_pi = 2.0 * math.pi
    bit_ms = int(cfg[C_BIT_MS])
    while n_out < max_epochs and st[S_MODE] != MODE_LOST:
        periods = int(st[S_INT_MS])
        # after bit sync, grow the integration at a bit edge (a weak channel to C_WEAK_INT_MS)
        target = cfg[C_MAX_INT_MS]
        if st[S_WEAK] > 0 and cfg[C_WEAK_INT_MS] > target:
            target = cfg[C_WEAK_INT_MS]
        if st[S_MODE] == MODE_BIT_SYNC and periods < target:
            if (int(st[S_CODE_PERIOD]) - int(st[S_BIT_OFFSET])) % bit_ms == 0:
                periods = int(target)
                st[S_INT_MS] = periods
                if st[S_FADE] == 1:             # a handed-down channel's C/N0 window: weak epochs only
                    _reset_cn0_window(st)
        n = _samples_needed(st, cfg, periods)
        off = int(st[S_NEXT_SAMPLE]) - block_start
        if off < 0:
            raise ValueError("channel is behind the block start")
        if off + n > nblk:
            break
        T = periods * 1e-3
        code_step = st[S_CODE_RATE] / fs
        carr_step = st[S_CARR_FREQ] / fs
        half_el = 0.5 * el_spacing(st, cfg)
        cp = st[S_CODE_PHASE]
        if cfg[C_NH_BASE] > 0 and st[S_MODE] == MODE_BIT_SYNC:
            # overlay (NH) wipe-off: correlate against the NH-modulated code section
            k_nh = (int(st[S_CODE_PERIOD]) - int(st[S_BIT_OFFSET])) % bit_ms
            cp += cfg[C_NH_BASE] + k_nh * cfg[C_CODE_LEN]
        e, p, l, p1, p2 = correlate_ws(samples, off, n, code_ext, cp, code_step, half_el,
                                       st[S_CARR_PHASE], carr_step, ws)
        ip = p.real
        qp = p.imag
        ae = abs(e)
        al = abs(l)
        # ---- record the epoch (NCO state at its start)
        o = out[n_out]
        o[O_TIME] = st[S_NEXT_SAMPLE] / fs
        o[O_SAMPLE] = st[S_NEXT_SAMPLE]
        o[O_PERIOD] = st[S_CODE_PERIOD]
        o[O_CODE_PHASE] = st[S_CODE_PHASE]
        o[O_CODE_RATE] = st[S_CODE_RATE]
        o[O_DOPPLER] = st[S_CARR_FREQ] - cfg[C_IF]
        o[O_CARR_PHASE] = st[S_CARR_PHASE]
        o[O_PI] = ip
        o[O_PQ] = qp
        o[O_E] = ae
        o[O_L] = al
        o[O_INT_MS] = periods
        o[O_P1I] = p1.real
        o[O_P1Q] = p1.imag
        o[O_P2I] = p2.real
        o[O_P2Q] = p2.imag
        # ---- advance NCOs to the end of the epoch
        st[S_NEXT_SAMPLE] += n
        st[S_CODE_PHASE] = st[S_CODE_PHASE] + n * code_step - periods * cfg[C_CODE_LEN]
        st[S_CARR_PHASE] += n * carr_step
        st[S_CODE_PERIOD] += periods
        st[S_TOTAL_MS] += periods
        st[S_MODE_MS] += periods
        # ---- discriminators
        carr_err = math.atan(qp / ip) / two_pi if ip != 0.0 else 0.0          # cycles (Costas)
        # frequency: consecutive prompts, decision-directed (immune to data-bit flips), +/- 1/(4T)
        pi_prev = st[S_LAST_PI]
        pq_prev = st[S_LAST_PQ]
        cross = pi_prev * qp - ip * pq_prev
        dot = pi_prev * ip + pq_prev * qp
        freq_err = 0.0
        if dot != 0.0 and st[S_TOTAL_MS] > periods:
            freq_err = math.atan(cross / dot) / (two_pi * T)                    # Hz
        code_err = 0.0
        if ae + al > 0.0:
            code_err = (ae - al) / (ae + al) * (1.0 - half_el)                 # chips
        o[O_CARR_ERR] = carr_err
        o[O_CODE_ERR] = code_err
        # ---- C/N0 and lock indicators
        st[S_ACC_ABSI] += abs(ip)
        st[S_ACC_Q2] += qp * qp
        st[S_ACC_I2] += ip * ip
        pw = ip * ip + qp * qp
        st[S_ACC_M2] += pw
        st[S_ACC_M4] += pw * pw
        st[S_ACC_N] += 1.0
        if st[S_ACC_N] * periods >= cfg[C_CN0_WIN_MS]:
            nacc = st[S_ACC_N]
            cn0 = 0.0
            if cfg[C_CN0_EST] == 0 and st[S_LOCK] > 0:
                mi = st[S_ACC_ABSI] / nacc
                pd = mi * mi
                pn = (st[S_ACC_I2] / nacc - pd) + st[S_ACC_Q2] / nacc
                if st[S_WEAK] > 0 or pd > 10.0 * pn:
                    # the noise from |I| alone (both components alike): the tracking phase error puts
                    # signal into Q, which would read as noise -- a 20-ms weak channel's ~10 deg jitter
                    # costs 2-3 dB, a TCXO's phase noise through a 15-Hz loop at 5 ms (~0.1 rad) 3-5 dB;
                    # |I| loses only the second-order cos(phase) term.  Below 10 dB per integration |I|
                    # folds noise (reads high): there the jitter is the noise's and I + Q is the estimate
                    pn = 2.0 * (st[S_ACC_I2] / nacc - pd) * nacc / max(nacc - 1.0, 1.0)
                if pn > 0:
                    cn0 = pd / (pn * T)
            else:
                m2 = st[S_ACC_M2] / nacc
                m4 = st[S_ACC_M4] / nacc
                d = 2.0 * m2 * m2 - m4
                pd = math.sqrt(d) if d > 0 else 0.0
                pn = m2 - pd
                if pn > 0 and pd > 0:
                    cn0 = pd / (pn * T)
            st[S_CN0] = 10.0 * math.log10(cn0) if cn0 > 1.0 else 0.0
            if st[S_FADE] == 1 and periods == st[S_INT_MS] and periods > cfg[C_MAX_INT_MS]:
                st[S_FADE] = 2.0                # the weak loops' first estimate: the lock detectors judge again
            # hand-over: a weak channel whose signal the normal loops hold (C/N0 at or above C_WEAK_EXIT_CN0,
            # above the weak threshold by a hysteresis) leaves the weak mode: its 10-Hz PLL at 20 ms and its
            # 0.5-Hz DLL are never worse than the normal loops' for a signal they track.  The acquisition's
            # C/N0 reads low by up to ~3 dB (code straddle at 2 samples per chip, Doppler bin), so channels
            # are opened weak that need not be.  The next epoch starts at a bit edge (20-ms epochs are
            # bit-aligned), where the integration drops to the normal one.
            # (scalar channels only: a channel the vector loop steers keeps the integration it was given)
            if st[S_WEAK] > 0 and cfg[C_WEAK_EXIT_CN0] > 0 and st[S_MODE] != MODE_PULL_IN and \
                    st[S_LOCK] > 0 and cfg[C_CODE_EXTERNAL] == 0:
                if st[S_CN0] >= cfg[C_WEAK_EXIT_CN0]:
                    st[S_STRONG_WIN] += 1.0
                else:
                    st[S_STRONG_WIN] = 0.0
                if st[S_STRONG_WIN] >= WEAK_EXIT_WINDOWS:
                    st[S_WEAK] = 0.0
                    st[S_FADE] = 0.0
                    st[S_WEAK_DONE] = 1.0
                    st[S_STRONG_WIN] = 0.0
                    if st[S_INT_MS] > cfg[C_MAX_INT_MS]:
                        st[S_INT_MS] = cfg[C_MAX_INT_MS]
            # only a channel that starts weak becomes weak: one decision, WEAK_DECIDE_MS after the pull-in,
            # on the largest estimate since (a strong channel not yet in phase lock reads low for a while);
            # a strong one whose signal fades or vanishes later (an outage) keeps the strong lock
            # detectors, so its loss is declared as fast as before
            if st[S_MODE] != MODE_PULL_IN:
                if st[S_CN0] > st[S_CN0_MAX]:
                    st[S_CN0_MAX] = st[S_CN0]
                if st[S_WEAK_DONE] == 0 and st[S_TOTAL_MS] >= cfg[C_PULL_IN_MS] + WEAK_DECIDE_MS:
                    st[S_WEAK_DONE] = 1.0
                    if cfg[C_WEAK_CN0] > 0 and st[S_CN0_MAX] < cfg[C_WEAK_CN0]:
                        st[S_WEAK] = 1.0
            _reset_cn0_window(st)
        a = min(1.0, periods / 20.0)
        st[S_PLI_I2] += a * (ip * ip - st[S_PLI_I2])
        st[S_PLI_Q2] += a * (qp * qp - st[S_PLI_Q2])
        tot = st[S_PLI_I2] + st[S_PLI_Q2]
        pli = (st[S_PLI_I2] - st[S_PLI_Q2]) / tot if tot > 0 else 0.0
        weak = st[S_WEAK] > 0
        b = min(1.0, periods / (cfg[C_WEAK_LOCK_MS] if weak else 50.0))
        st[S_LOCK_ABSI] += b * (abs(ip) - st[S_LOCK_ABSI])
        st[S_LOCK_ABSQ] += b * (abs(qp) - st[S_LOCK_ABSQ])
        good = st[S_LOCK_ABSI] > (cfg[C_WEAK_LOCK_RATIO] if weak else cfg[C_LOCK_RATIO]) * st[S_LOCK_ABSQ] \
            and (st[S_CN0] >= (cfg[C_WEAK_LOCK_CN0] if weak else cfg[C_LOCK_CN0_MIN]) or st[S_TOTAL_MS] < 1000)
        # ---- signal presence: the prompt power over a short window against its level while present.  The
        # lock filters and the C/N0 window lag a vanished strong signal by 0.15-0.4 s; the window power
        # falls to the noise floor (-C/N0 T dB) at once.  Only channels whose C/N0 makes the test safe
        # (C_PRES_CN0) can be declared absent; absent -> no lock, C/N0 0, lost after C_PRES_LOST_MS.
        if cfg[C_PRES_MS] > 0 and st[S_MODE] != MODE_PULL_IN:
            st[S_PRES_ACC] += (ip * ip + qp * qp) / periods
            st[S_PRES_MS] += periods
            if st[S_PRES_MS] >= cfg[C_PRES_MS]:
                xw = st[S_PRES_ACC] / st[S_PRES_MS]
                ref = st[S_PRES_REF]
                if ref > 0.0 and xw < cfg[C_PRES_FRAC] * ref and \
                        (st[S_ABSENT_MS] > 0 or st[S_CN0] >= cfg[C_PRES_CN0]):
                    st[S_ABSENT_MS] += st[S_PRES_MS]
                else:
                    st[S_ABSENT_MS] = 0.0
                    st[S_PRES_REF] = xw if ref <= 0.0 else ref + 0.25 * (xw - ref)
                st[S_PRES_ACC] = 0.0
                st[S_PRES_MS] = 0.0
        if st[S_ABSENT_MS] > 0:
            good = False
            st[S_CN0] = 0.0
        if st[S_MODE] == MODE_PULL_IN:
            good = True
        st[S_LOCK] = 1.0 if (good and st[S_MODE] != MODE_PULL_IN) else 0.0
        if good:
            st[S_BAD_MS] = 0.0
        else:
            st[S_BAD_MS] += periods
            # a young channel (weak signal still pulling into phase lock) gets the longer grace time
            grace = cfg[C_LOST_GRACE_MS]
            if weak and cfg[C_WEAK_GRACE_MS] > grace and st[S_FADE] == 0:     # (not a handed-down one)
                grace = cfg[C_WEAK_GRACE_MS]
            # a handed-down channel is lost after two C/N0 windows in a row below the thresholds: the window
            # in which a faded signal comes back (a 20-dB step of |I| inside it) reads low
            lost_ms = cfg[C_LOST_MS]
            if st[S_FADE] == 2 and cfg[C_CN0_WIN_MS] + 1.0 > lost_ms:
                lost_ms = cfg[C_CN0_WIN_MS] + 1.0
            lost = st[S_BAD_MS] >= lost_ms and (st[S_TOTAL_MS] >= grace or st[S_BAD_MS] >= grace)
            if st[S_ABSENT_MS] >= cfg[C_PRES_LOST_MS] and cfg[C_PRES_MS] > 0:
                lost = True
            if lost and st[S_FADE] != 1 and not _hand_down(st, cfg):
                st[S_MODE] = MODE_LOST
        o[O_CN0] = st[S_CN0]
        o[O_PLI] = pli
        o[O_LOCK] = st[S_LOCK]
        # ---- bit synchronisation: histogram of prompt sign changes per ms position
        if st[S_MODE] == MODE_TRACK and periods == 1:
            if st[S_PREV_I] * ip < 0.0:
                hist[int(st[S_CODE_PERIOD] - 1) % bit_ms] += 1
            st[S_BITSYNC_MS] += 1
            best = 0
            second = 0
            ibest = 0
            if cfg[C_NH_BASE] > 0:
                # overlay code: sign changes are expected where the NH code changes (weight +1) and
                # not where it stays (weight -1); the data edge (NH position 0) is not scored
                b0 = int(cfg[C_NH_BASE]) + 4
                L = int(cfg[C_CODE_LEN])
                for r in range(bit_ms):
                    sc = 0
                    for j in range(1, bit_ms):
                        w = 1 if code_ext[b0 + j * L] != code_ext[b0 + (j - 1) * L] else -1
                        sc += w * hist[(r + j) % bit_ms]
                    if sc > best:
                        second = best
                        best = sc
                        ibest = r
                    elif sc > second:
                        second = sc
                # ~10 per NH period at the right offset, <= 3.5 at any other; mapped onto the
                # rule below: >= 48 raw score and twice the runner-up
                best = best // 4
                second = max(second, 0) // 6      # i.e. best > 2 x runner-up
            else:
                for j in range(bit_ms):
                    h = hist[j]
                    if h > best:
                        second = best
                        best = h
                        ibest = j
                    elif h > second:
                        second = h
            # weak signals: the energy of the complex 20-ms sums of the prompt per bit-edge hypothesis (the
            # sign changes of 1-ms prompts are too noisy below ~30 dB-Hz, and the PLL need not be in phase
            # lock: a few Hz of frequency error cost little over 20 ms); decided after C_ESYNC_MIN_MS
            esync = cfg[C_ESYNC_MIN_MS] > 0 and cfg[C_NH_BASE] == 0 and bit_ms == 20
            if esync:
                pcur = int(st[S_CODE_PERIOD] - 1)
                st[S_RING + pcur % 20] = ip
                st[S_RINGQ + pcur % 20] = qp
                st[S_ESYNC_Q2] += ip * ip + qp * qp
                if st[S_BITSYNC_MS] >= 20:
                    ssum = 0.0
                    qsum = 0.0
                    for j in range(20):
                        ssum += st[S_RING + j]
                        qsum += st[S_RINGQ + j]
                    st[S_ESYNC + (pcur + 1) % 20] += ssum * ssum + qsum * qsum
            if best >= 12 and best > 3 * second:
                st[S_BIT_OFFSET] = ibest
                st[S_MODE] = MODE_BIT_SYNC
            elif esync and st[S_BITSYNC_MS] >= cfg[C_ESYNC_MIN_MS]:
                eb = 0.0
                es = 0.0
                jb = 0
                for j in range(20):
                    e_ = st[S_ESYNC + j]
                    if e_ > eb:
                        es = eb
                        eb = e_
                        jb = j
                    elif e_ > es:
                        es = e_
                nwin = (st[S_BITSYNC_MS] - 19.0) / 20.0
                noise = 20.0 * st[S_ESYNC_Q2] / st[S_BITSYNC_MS]
                # the right hypothesis gathers ~10 % more energy than its neighbours at any C/N0 (one
                # ms of 20 lost at half the edges); the signal test rejects noise-only channels (noise
                # alone: ratio ~1; 24 dB-Hz: ~5, the 1-ms power counting signal too)
                if eb > 1.03 * es and eb > 3.0 * nwin * noise:
                    st[S_BIT_OFFSET] = jb
                    st[S_MODE] = MODE_BIT_SYNC
            if st[S_MODE] != MODE_BIT_SYNC and st[S_BITSYNC_MS] > 6000:
                for j in range(bit_ms):
                    hist[j] = 0
                for j in range(20):
                    st[S_ESYNC + j] = 0.0
                st[S_ESYNC_Q2] = 0.0
                st[S_BITSYNC_MS] = 0
        st[S_PREV_I] = ip
        st[S_LAST_PI] = ip
        st[S_LAST_PQ] = qp
        if st[S_MODE] == MODE_PULL_IN and st[S_MODE_MS] >= cfg[C_PULL_IN_MS]:
            st[S_MODE] = MODE_TRACK
            st[S_MODE_MS] = 0.0
            if cfg[C_NO_DATA] > 0 and cfg[C_NH_BASE] == 0:
                st[S_MODE] = MODE_BIT_SYNC           # no data, no overlay: any period is an edge
                st[S_BIT_OFFSET] = 0
        o[O_STATE] = st[S_MODE]
        # ---- false lock (built-in loop, bit-aligned epochs of >= 10 ms): a Costas loop integrating T is blind
        # to a residual of 1/(2T) (25 Hz at 20 ms: the phase turns by half a cycle per epoch, read as a data
        # flip), where it holds with the prompt 3.9 dB down and every other bit inverted (no preamble, no
        # frame).  The two halves of an epoch (one data bit) turn by a quarter cycle against each other
        # there, by nothing in true lock: their rotation, summed over FL_WINDOW_MS, measures the residual
        # unambiguously within +/-1/T; beyond +/-1/(4T) the loop's frequency is moved by it.
        if cfg[C_CARRIER_EXTERNAL] == 0 and st[S_MODE] == MODE_BIT_SYNC and periods >= 10 and \
                (int(o[O_PERIOD]) - int(st[S_BIT_OFFSET])) % bit_ms == 0:
            st[S_FL_RE] += p2.real * p1.real + p2.imag * p1.imag
            st[S_FL_IM] += p2.imag * p1.real - p2.real * p1.imag
            st[S_FL_MS] += periods
            if st[S_FL_MS] >= FL_WINDOW_MS:
                ang = math.atan2(st[S_FL_IM], st[S_FL_RE])
                if abs(ang) > 0.25 * math.pi:
                    st[S_PLL_FREQ] += ang / (two_pi * 0.5 * T)
                    st[S_FL_COUNT] += 1.0
                st[S_FL_RE] = 0.0
                st[S_FL_IM] = 0.0
                st[S_FL_MS] = 0.0
        # ---- loop filters (built in): FLL-assisted PLL, carrier-aided DLL
        if cfg[C_CARRIER_EXTERNAL] == 0:
            pull = st[S_MODE] == MODE_PULL_IN
            pll_bw = cfg[C_WEAK_PLL_BW] if (st[S_WEAK] > 0 and cfg[C_WEAK_PLL_BW] > 0) else cfg[C_PLL_BW]
            # re-pull: a channel that started weak and has been out of phase lock for a lock window after bit
            # sync (its 20-ms PLL entered unlocked, or slipped) is steered by the rotation between the two
            # halves of the epoch (one data bit: unambiguous within +/-1/T), which the 1-ms discriminator of
            # the pull-in cannot give at these C/N0; in lock, and on a strong channel handed down in a fade
            # (an outage: the halves would read noise), the PLL alone
            if not pull and st[S_WEAK] > 0 and st[S_FADE] == 0 and st[S_BAD_MS] >= cfg[C_WEAK_LOCK_MS] and \
                    cfg[C_WEAK_REPULL_FLL_BW] > 0 and \
                    st[S_MODE] == MODE_BIT_SYNC and periods >= 10 and \
                    (int(o[O_PERIOD]) - int(st[S_BIT_OFFSET])) % bit_ms == 0:
                h_re = p2.real * p1.real + p2.imag * p1.imag
                h_im = p2.imag * p1.real - p2.real * p1.imag
                if h_re != 0.0 or h_im != 0.0:
                    # (a 1st-order FLL: freq += 4 Bn_fll T e_f, before the PLL's own update)
                    st[S_PLL_FREQ] += T * 4.0 * cfg[C_WEAK_REPULL_FLL_BW] * math.atan2(h_im, h_re) / \
                        (two_pi * 0.5 * T)
            if pull or cfg[C_PLL_ORDER] == 2:
                # 2nd-order PLL; during pull-in aided by a 1st-order FLL (freq += 4 Bn_fll T e_f).  No
                # Doppler-rate integrator here: at low C/N0 noisy frequency discriminations would wind
                # it up and the 3rd-order loop would then ramp away after the pull-in.
                w0p = pll_bw / 0.53
                ef = freq_err if pull else 0.0
                fll_bw = cfg[C_WEAK_FLL_BW] if st[S_WEAK] > 0 else cfg[C_FLL_BW]
                st[S_PLL_FREQ] += T * (w0p * w0p * carr_err + 4.0 * fll_bw * ef)
                nco = st[S_PLL_FREQ] + 1.414 * w0p * carr_err
            else:
                w0p = pll_bw / 0.7845
                st[S_PLL_RATE] += T * w0p ** 3 * carr_err
                st[S_PLL_FREQ] += T * (st[S_PLL_RATE] + 1.1 * w0p * w0p * carr_err)
                nco = st[S_PLL_FREQ] + 2.4 * w0p * carr_err
            st[S_CARR_FREQ] = cfg[C_IF] + nco
        if cfg[C_CODE_EXTERNAL] == 0:
            bw = cfg[C_DLL_BW_PULL] if st[S_MODE] == MODE_PULL_IN else cfg[C_DLL_BW]
            # a weak channel's DLL narrows C_WEAK_DLL_HOLD_MS after the pull-in: the code error the pull-in
            # leaves (up to ~0.3 chip at low C/N0, whose 1-ms discriminator gain is low) converges at the
            # normal rate first -- at 0.5 Hz it took 3-5 s, measurements being used after 1 s
            if st[S_WEAK] > 0 and cfg[C_WEAK_DLL_BW] > 0 and st[S_MODE] != MODE_PULL_IN:
                bw = cfg[C_WEAK_DLL_BW] if st[S_MODE_MS] >= cfg[C_WEAK_DLL_HOLD_MS] else cfg[C_DLL_BW_PULL]
            doppler = st[S_CARR_FREQ] - cfg[C_IF]
            aid = cfg[C_CHIP_RATE] * (1.0 + doppler / cfg[C_CARRIER_HZ])
            if cfg[C_DLL_ORDER] == 2:
                # 2nd order: the integrator absorbs a code/carrier rate mismatch (oscillator error on
                # the carrier only, ionospheric divergence) that would bias a 1st-order loop
                w0 = bw / 0.53
                # a weak channel's rate integrator at its own (narrow) bandwidth from the start: at 1-ms
                # integration and low C/N0 the wide pull-in / hold loop's integrator random-walks to
                # ~0.2 chip/s, which the narrow loop then takes seconds to remove (code errors of 0.3 chip)
                w0i = cfg[C_WEAK_DLL_BW] / 0.53 if (st[S_WEAK] > 0 and 0 < cfg[C_WEAK_DLL_BW] < bw) else w0
                st[S_DLL_RATE] += T * w0i * w0i * code_err
                st[S_CODE_RATE] = aid + st[S_DLL_RATE] + 1.414 * w0 * code_err
            else:
                st[S_CODE_RATE] = aid + 4.0 * bw * code_err
        n_out += 1
    return n_out
