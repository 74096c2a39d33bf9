"""Numba tracking kernel: runs a channel's epochs over a block of samples.

All per-channel state lives in a float64 array (indices S_*), the configuration in another (C_*),
so that the whole epoch loop - correlation, discriminators, built-in loop filters, C/N0, lock
detection and bit synchronisation - runs in compiled code.  Python sees the channel between calls: a
vector loop or a Python carrier loop steps the kernel one epoch at a time and rewrites the NCO state
(S_CARR_FREQ, S_CODE_RATE, S_CODE_PHASE) between epochs.  ``C_CARRIER_EXTERNAL`` / ``C_CODE_EXTERNAL``
stop the kernel from touching the carrier / code NCO itself.
"""
import math

import numpy as np
from numba import njit

from .correlator import correlate

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
N_STATE = 36

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
N_CONFIG = 29

# ---- output columns (same order as receiver.runfile.record.EPOCH_DTYPE)
O_TIME, O_SAMPLE, O_PERIOD, O_CODE_PHASE, O_CODE_RATE, O_DOPPLER, O_CARR_PHASE, O_PI, O_PQ, \
    O_E, O_L, O_CN0, O_PLI, O_CARR_ERR, O_CODE_ERR, O_LOCK, O_STATE, O_INT_MS, \
    O_P1I, O_P1Q, O_P2I, O_P2Q = range(22)  # same order as EPOCH_DTYPE
N_OUT = 22

MODE_PULL_IN = 0
MODE_TRACK = 1
MODE_BIT_SYNC = 2
MODE_LOST = 3


#: state entries of the C/N0 estimator and the lock / PLI filters (reset if they become non-finite)
_ESTIMATOR_STATE = (S_CN0, S_PLI_I2, S_PLI_Q2, S_ACC_ABSI, S_ACC_Q2, S_ACC_M2, S_ACC_M4, S_ACC_N, S_ACC_I2,
                    S_LOCK_ABSI, S_LOCK_ABSQ, S_LAST_PI, S_LAST_PQ, S_PREV_I, S_PRES_ACC, S_PRES_MS,
                    S_PRES_REF, S_ABSENT_MS)


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
def _samples_needed(st, cfg, periods):
    step = st[S_CODE_RATE] / cfg[C_FS]
    chips = periods * cfg[C_CODE_LEN] - st[S_CODE_PHASE]
    return int(math.ceil(chips / step))


@njit(cache=True, fastmath=True, nogil=True)
def track_block(samples, block_start, st, cfg, code_ext, hist, out, max_epochs):
    """Run epochs while they fit in `samples` (file indices block_start...). Returns epochs written."""
    fs = cfg[C_FS]
    nblk = samples.shape[0]
    n_out = 0
    two_pi = 2.0 * math.pi
    bit_ms = int(cfg[C_BIT_MS])
    while n_out < max_epochs and st[S_MODE] != MODE_LOST:
        periods = int(st[S_INT_MS])
        # after bit sync, grow the integration at a bit edge
        if st[S_MODE] == MODE_BIT_SYNC and periods < cfg[C_MAX_INT_MS]:
            if (int(st[S_CODE_PERIOD]) - int(st[S_BIT_OFFSET])) % bit_ms == 0:
                periods = int(cfg[C_MAX_INT_MS])
                st[S_INT_MS] = periods
        n = _samples_needed(st, cfg, periods)
        off = int(st[S_NEXT_SAMPLE]) - block_start
        if off < 0:
            raise ValueError("channel is behind the block start")
        if off + n > nblk:
            break
        T = periods * 1e-3
        code_step = st[S_CODE_RATE] / fs
        carr_step = st[S_CARR_FREQ] / fs
        half_el = 0.5 * cfg[C_EL_SPACING]
        cp = st[S_CODE_PHASE]
        if cfg[C_NH_BASE] > 0 and st[S_MODE] == MODE_BIT_SYNC:
            # overlay (NH) wipe-off: correlate against the NH-modulated code section
            k_nh = (int(st[S_CODE_PERIOD]) - int(st[S_BIT_OFFSET])) % bit_ms
            cp += cfg[C_NH_BASE] + k_nh * cfg[C_CODE_LEN]
        e, p, l, p1, p2 = correlate(samples, off, n, code_ext, cp, code_step, half_el,
                                    st[S_CARR_PHASE], carr_step)
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
            st[S_ACC_ABSI] = 0.0
            st[S_ACC_Q2] = 0.0
            st[S_ACC_I2] = 0.0
            st[S_ACC_M2] = 0.0
            st[S_ACC_M4] = 0.0
            st[S_ACC_N] = 0.0
        a = min(1.0, periods / 20.0)
        st[S_PLI_I2] += a * (ip * ip - st[S_PLI_I2])
        st[S_PLI_Q2] += a * (qp * qp - st[S_PLI_Q2])
        tot = st[S_PLI_I2] + st[S_PLI_Q2]
        pli = (st[S_PLI_I2] - st[S_PLI_Q2]) / tot if tot > 0 else 0.0
        b = min(1.0, periods / 50.0)
        st[S_LOCK_ABSI] += b * (abs(ip) - st[S_LOCK_ABSI])
        st[S_LOCK_ABSQ] += b * (abs(qp) - st[S_LOCK_ABSQ])
        good = st[S_LOCK_ABSI] > cfg[C_LOCK_RATIO] * st[S_LOCK_ABSQ] and \
            (st[S_CN0] >= cfg[C_LOCK_CN0_MIN] or st[S_TOTAL_MS] < 1000)
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
            if st[S_BAD_MS] >= cfg[C_LOST_MS] and (st[S_TOTAL_MS] >= cfg[C_LOST_GRACE_MS]
                                                   or st[S_BAD_MS] >= cfg[C_LOST_GRACE_MS]):
                st[S_MODE] = MODE_LOST
            if st[S_ABSENT_MS] >= cfg[C_PRES_LOST_MS] and cfg[C_PRES_MS] > 0:
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
            if best >= 12 and best > 3 * second:
                st[S_BIT_OFFSET] = ibest
                st[S_MODE] = MODE_BIT_SYNC
            elif st[S_BITSYNC_MS] > 6000:
                for j in range(bit_ms):
                    hist[j] = 0
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
        # ---- loop filters (built in): FLL-assisted PLL, carrier-aided DLL
        if cfg[C_CARRIER_EXTERNAL] == 0:
            pull = st[S_MODE] == MODE_PULL_IN
            if pull or cfg[C_PLL_ORDER] == 2:
                # 2nd-order PLL; during pull-in aided by a 1st-order FLL (freq += 4 Bn_fll T e_f).  No
                # Doppler-rate integrator here: at low C/N0 noisy frequency discriminations would wind
                # it up and the 3rd-order loop would then ramp away after the pull-in.
                w0p = cfg[C_PLL_BW] / 0.53
                ef = freq_err if pull else 0.0
                st[S_PLL_FREQ] += T * (w0p * w0p * carr_err + 4.0 * cfg[C_FLL_BW] * ef)
                nco = st[S_PLL_FREQ] + 1.414 * w0p * carr_err
            else:
                w0p = cfg[C_PLL_BW] / 0.7845
                st[S_PLL_RATE] += T * w0p ** 3 * carr_err
                st[S_PLL_FREQ] += T * (st[S_PLL_RATE] + 1.1 * w0p * w0p * carr_err)
                nco = st[S_PLL_FREQ] + 2.4 * w0p * carr_err
            st[S_CARR_FREQ] = cfg[C_IF] + nco
        if cfg[C_CODE_EXTERNAL] == 0:
            bw = cfg[C_DLL_BW_PULL] if st[S_MODE] == MODE_PULL_IN else cfg[C_DLL_BW]
            doppler = st[S_CARR_FREQ] - cfg[C_IF]
            aid = cfg[C_CHIP_RATE] * (1.0 + doppler / cfg[C_CARRIER_HZ])
            if cfg[C_DLL_ORDER] == 2:
                # 2nd order: the integrator absorbs a code/carrier rate mismatch (oscillator error on
                # the carrier only, ionospheric divergence) that would bias a 1st-order loop
                w0 = bw / 0.53
                st[S_DLL_RATE] += T * w0 * w0 * code_err
                st[S_CODE_RATE] = aid + st[S_DLL_RATE] + 1.414 * w0 * code_err
            else:
                st[S_CODE_RATE] = aid + 4.0 * bw * code_err
        n_out += 1
    return n_out
