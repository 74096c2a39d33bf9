"""The compiled vector-tracking epoch loop: one call runs every vector epoch that fits in a block.

Epoch grid.  The filter runs on a grid of receiver time, epoch k ending at sample S_k = S_0 + k T fs.
In epoch k every vector channel runs the correlation epochs that START before S_k (normally exactly one;
occasionally none or two, since a channel's code periods last (1 - Doppler/f_L1) ms of receiver time;
two are averaged).  A channel measurement is taken at the middle of its correlation epoch,
tau_mid = tau_k + Delta with |Delta| <= T/2; the prediction is propagated by Delta with the estimated
velocity and drift (the tiny Delta terms of H are neglected).

Per channel and epoch:
  replica transmit time   tx_nco = A_j + code_period * T_code + code_phase / f_code   (at tau_mid)
  measured pseudorange    rho = c (tau_mid - tx_nco) + Z_code
  measured rate           rate = -lambda (NCO Doppler + df),   df from the cross/dot of the halves
  predicted               rho_hat = |p_sat(tau) - r| + I + T + b (+ isb_s) - c dt_sv(tau)
                          rate_hat = e . (v_sat - v) + d - c ddt_sv
(all times relative to the handover reference, see tracker.py; A_j is the relative transmit time of the
channel's code period 0, a whole number of code periods in absolute GPS time).  The signal constants are the
channel's (SIG columns, from its SignalDef: chip rate f_code, carrier wavelength lambda, code period T_code, the
IF and the input block of its signal, the kind of its correlation epoch), so channels of several signals
(GPS/QZSS L1 C/A, BeiDou B1I, Galileo E1) share one filter; a channel of a system other than the reference
clock's adds its system's inter-system bias state isb_s (column SIG_ISB: its index in x, -1 for the reference
system). The frequency discriminator compares the two halves of ONE correlation epoch, and the kernel's epochs
never span a data symbol or overlay-code chip (B1I: 1 ms before NH sync, then NH wiped off and epochs aligned to
the D1 bits; D2: epochs of at most the 2-ms symbol; Galileo E1: one 4-ms E1-C pilot period with its CS25 chip
wiped, the E1-B symbols read against the pilot's phase, galileo.py), so the symbol signs never enter it. A
Galileo channel's epoch lasts 4 ms whatever the filter's T: with T < 4 ms it gives a measurement every 4 / T
filter epochs (the others predict it only), with T > 4 ms its one or two epochs in the filter epoch are averaged.
Since the NCOs are commanded from the prediction, the innovation rho - rho_hat is the discriminator output of the
error-state formulation of the papers (E_code = t_b + (X - X_hat)^T a_j); the explicit form above stays exact
when an NCO could not follow the prediction (clamped code steps, the first epoch after handover).

NCO commands for the next correlation epoch of channel j (starting at sample s_next):
  code phase  shifted so that the replica transmit time at s_next equals tau_next - rho_hat(tau_next)/c
              (at most MAX_SHIFT chips per epoch)
  code rate   f_code (1 - rate_hat_code / c), rate_hat_code with the code drift d + delta
  carrier     Doppler -rate_hat / lambda at the middle of the next epoch
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import kernel as K
from ..correlator import workspace
from ...gnss.signals import C_LIGHT
from .discriminators import code_disc_boc_m, code_disc_m, freq_disc_hz
from .galileo import gal_epoch
from .kalman import adapt_r, kf_predict, kf_update_isb

MAX_SHIFT = 3.0          # chips per epoch (the correlator's code array has 4 chips of wrap margin)
GROSS_CODE_M = 3000.0    # innovations beyond these are not measurements of this channel's signal (the
GROSS_RATE_MPS = 1000.0  # discriminators alone span +/- 220 m and +/- 190 m/s): never used in an update

# ---- parameter vector indices
P_FS = 0
P_IF = 1
P_GRID = 2               # samples per filter epoch
P_SREF = 3               # sample index of tau = 0
P_MARGIN = 4             # samples a correlation epoch may extend past its grid point
P_CHI2 = 5
P_CN0_MASK = 6
P_LOCK_CN0 = 7
P_FORM = 8
P_FLOOR_C = 9
P_FLOOR_F = 10
P_MIN_FILL = 11
P_GATE = 12
P_COAST_MASK = 13      # 1: while fewer than 4 channels carry signal, channels without signal only predict
P_SLOW_CN0 = 14        # > 0: the slow lock detector's threshold (dB-Hz), see _slow_lock
P_SLOW_BITS = 15       # data bits per slow lock window
N_PRM = 16

# ---- per-channel signal columns (SIG)
SIG_CHIP = 0             # chip rate (chips/s)
SIG_LAMBDA = 1           # carrier wavelength (m)
SIG_PERIOD = 2           # primary-code period (s)
SIG_IF = 3               # IF of the channel's input stream (Hz)
SIG_BLOCK = 4            # row of `blocks` holding the channel's signal
SIG_ISB = 5              # state index of the channel's inter-system bias, -1: the reference clock
SIG_KIND = 6             # the channel's correlation epoch: KIND_KERNEL or KIND_GAL_E1
SIG_SLOW = 7             # 1: the slow lock detector applies (1-ms prompts carry 20-ms data bits and no overlay)
N_SIG = 8

KIND_KERNEL = 0          # the 1-ms tracking kernel (BPSK: GPS/QZSS L1 C/A, BeiDou B1I)
KIND_GAL_E1 = 1          # Galileo E1: 4-ms E1-C pilot epochs, BOC(1,1) discriminator (galileo.py)

# ---- per-channel slow lock detector state (WK), see _slow_lock
WK_I = 0                 # prompt sum of the current data bit
WK_Q = 1
WK_MS = 2                # ms summed in the current bit (-1: waiting for the next bit edge)
WK_M2 = 3                # moments of the bit sums' power over the current window
WK_M4 = 4
WK_N = 5
WK_CN0 = 6               # the last window's C/N0 (dB-Hz; 0: none)
N_WK = 7

# ---- per-epoch log columns (besides the state)
L_TAU = 0
L_TAGP = 1
L_TAGV = 2
L_FIRED = 3
L_NVALID = 4
L_NLOCK = 5
N_LOG = 6


@njit(cache=True)
def _sat(POLY, TAU_A, j, tau, sp, sv):
    dt = tau - TAU_A[j]
    for a in range(4):
        sp[a] = POLY[j, 0, a] + (POLY[j, 1, a] + POLY[j, 2, a] * dt) * dt
        sv[a] = POLY[j, 1, a] + 2.0 * POLY[j, 2, a] * dt


@njit(cache=True)
def _predict_channel(x, lay, POLY, TAU_A, ATM, j, tau, tau_k, sp, sv, e, ig):
    """Predicted pseudorange, carrier rate and code rate of channel j at tau (state x at tau_k); fills e.
    ig >= 0: the state index of the channel's inter-system bias."""
    ip, iv, ib, idd, idl = lay[0], lay[1], lay[2], lay[3], lay[4]
    dlt = x[idl] if idl >= 0 else 0.0
    dt = tau - tau_k
    _sat(POLY, TAU_A, j, tau, sp, sv)
    rng2 = 0.0
    for a in range(3):                       # e holds the line of sight, then its unit vector
        e[a] = sp[a] - (x[ip + a] + x[iv + a] * dt)
        rng2 += e[a] * e[a]
    rng = math.sqrt(rng2)
    rr = 0.0
    for a in range(3):
        e[a] = e[a] / rng
        rr += e[a] * (sv[a] - x[iv + a])
    b = x[ib] + (x[idd] + dlt) * dt
    if ig >= 0:
        b += x[ig]
    rho = rng + ATM[j] + b - sp[3]
    rate_carr = rr + x[idd] - sv[3]
    return rho, rate_carr, rate_carr + dlt


@njit(cache=True)
def _slow_lock(wk, st, o, nbits):
    """The slow lock detector of a channel (weak signals under the vector loop): M2M4 over `nbits` bit-aligned
    20-ms sums of the 1-ms prompts.  Over the 200-ms window of 1-ms epochs that decides vector lock, M2M4 on
    noise alone reads 20-30 dB-Hz, so signals below ~32 dB-Hz cannot be told from noise there; 50 sums of 20 ms
    (1 s) read noise below ~23 dB-Hz (99.99 %) and a 27 dB-Hz signal above ~25 (99 %).  Reset while the
    presence test finds the signal absent or the bit edges are unknown."""
    off = st[K.S_BIT_OFFSET]
    if off < 0 or st[K.S_ABSENT_MS] > 0:
        for a in range(N_WK):
            wk[a] = 0.0
        wk[WK_MS] = -1.0
        return
    pos = (int(o[K.O_PERIOD]) - int(off)) % 20
    if pos == 0:
        wk[WK_I] = 0.0
        wk[WK_Q] = 0.0
        wk[WK_MS] = 0.0
    elif wk[WK_MS] != pos:                   # joined inside a bit, or an epoch was skipped
        wk[WK_MS] = -1.0
    if wk[WK_MS] < 0:
        return
    wk[WK_I] += o[K.O_PI]
    wk[WK_Q] += o[K.O_PQ]
    wk[WK_MS] += o[K.O_INT_MS]
    if wk[WK_MS] < 20.0:
        return
    pw = wk[WK_I] * wk[WK_I] + wk[WK_Q] * wk[WK_Q]
    wk[WK_M2] += pw
    wk[WK_M4] += pw * pw
    wk[WK_N] += 1.0
    wk[WK_MS] = -1.0
    if wk[WK_N] < nbits:
        return
    m2 = wk[WK_M2] / wk[WK_N]
    m4 = wk[WK_M4] / wk[WK_N]
    d = 2.0 * m2 * m2 - m4
    pd = math.sqrt(d) if d > 0 else 0.0
    pn = m2 - pd
    cn0 = pd / (pn * 0.02) if pn > 0 and pd > 0 else 0.0
    wk[WK_CN0] = 10.0 * math.log10(cn0) if cn0 > 1.0 else 0.0
    wk[WK_M2] = 0.0
    wk[WK_M4] = 0.0
    wk[WK_N] = 0.0


@njit(cache=True)
def vector_locked(st, wk, sig, prm) -> bool:
    """A vector channel carries signal: its C/N0 (M2M4, vector.cn0_window_ms) at or above vector.lock_cn0_dbhz,
    or, for a weak GPS/QZSS channel the signal-presence test finds present, its slow detector's C/N0 at or
    above vector.weak_lock_cn0_dbhz."""
    if st[K.S_CN0] >= prm[P_LOCK_CN0]:
        return True
    return prm[P_SLOW_CN0] > 0 and sig[SIG_SLOW] > 0 and st[K.S_ABSENT_MS] == 0 and \
        wk[WK_CN0] >= prm[P_SLOW_CN0]


@njit(cache=True)
def run_chunk(blocks, block_start, prm, grid_next, max_epochs, chans, geometry, filt, out):
    """Run vector epochs while every channel's next correlation epoch fits in the block.

    blocks (n_signals, n): the chunk's samples of each signal's input stream (the same sample span).
    The arrays come in four tuples (numba unpacks them without copying):

    * chans = (ST, CF, CODE, HIST, CA, ACTIVE, SIG, WK): the channels' tracking state, configuration, codes,
      histories, code-aiding state, ACTIVE (m,) (0 freezes a channel: not stepped, not commanded), SIG
      (m, N_SIG) the channel's signal constants (see the module docstring) and WK (m, N_WK) the slow lock
      detectors (_slow_lock);
    * geometry = (POLY, TAU_A, ATM): the satellite polynomials over the block, their time origin, the
      atmospheric delays;
    * filt = (x, P, F, Q, QB, lay, Rc, Rf, W, WI, WN, WS): the filter's state, covariance, transition,
      process noise, layout, measurement noise and adaptive windows;
    * out = (REC, NREC, LOG, LX, LPD, LR): REC (m, cap, N_OUT) / NREC receive the channels' correlation
      records; LOG / LX / LPD / LR (per epoch: log columns, state, covariance diagonal, channel R) the
      filter history.

    Returns (epochs run, next grid point).
    """
    ST, CF, CODE, HIST, CA, ACTIVE, SIG, WK = chans
    POLY, TAU_A, ATM = geometry
    x, P, F, Q, QB, lay, Rc, Rf, W, WI, WN, WS = filt
    REC, NREC, LOG, LX, LPD, LR = out
    fs = prm[P_FS]
    nblk = blocks.shape[1]
    m = ST.shape[0]
    n = x.shape[0]
    step = prm[P_GRID]
    s_ref = prm[P_SREF]
    G = np.zeros(m, np.int64)
    for j in range(m):
        G[j] = int(SIG[j, SIG_ISB])
    E = np.zeros((m, 3))
    zc = np.zeros(m)
    zf = np.zeros(m)
    cnt = np.zeros(m, np.int64)
    valid = np.zeros(m, np.bool_)
    diag = np.zeros((m, 8))
    sp = np.zeros(4)
    sv = np.zeros(4)
    e = np.zeros(3)
    halves = np.zeros(4)              # a Galileo epoch's pilot prompt halves (I1, Q1, I2, Q2)
    cap = REC.shape[1]
    ws = workspace()                  # the correlator's scratch, once per chunk (one epoch per call below)
    k = 0
    while k < max_epochs:
        s_end = grid_next
        if s_end + prm[P_MARGIN] > block_start + nblk:
            break
        full = False
        for j in range(m):
            if ACTIVE[j] and NREC[j] + 2 >= cap:
                full = True
        if full:
            break
        tau_k = (s_end - s_ref) / fs
        kf_predict(x, P, F, Q)
        nlock = 0
        for j in range(m):
            zc[j] = 0.0
            zf[j] = 0.0
            cnt[j] = 0
            valid[j] = False
            if not ACTIVE[j]:
                continue
            if vector_locked(ST[j], WK[j], SIG[j], prm):
                nlock += 1
            chip = SIG[j, SIG_CHIP]
            block = blocks[int(SIG[j, SIG_BLOCK])]
            gal = SIG[j, SIG_KIND] == KIND_GAL_E1
            while ST[j, K.S_NEXT_SAMPLE] < s_end and NREC[j] < cap:
                r0 = NREC[j]
                if gal:
                    got = gal_epoch(block, block_start, ST[j], CF[j], CODE[j], REC[j, r0], halves)
                else:
                    got = K.track_block_ws(block, block_start, ST[j], CF[j], CODE[j], HIST[j],
                                           REC[j, r0:r0 + 1], 1, ws)
                if got == 0:
                    break
                NREC[j] = r0 + 1
                o = REC[j, r0]
                if SIG[j, SIG_SLOW] > 0:
                    _slow_lock(WK[j], ST[j], o, prm[P_SLOW_BITS])
                o[K.O_LOCK] = 1.0 if vector_locked(ST[j], WK[j], SIG[j], prm) else 0.0
                ns = ST[j, K.S_NEXT_SAMPLE] - o[K.O_SAMPLE]
                t_int = ns / fs
                tau_mid = (o[K.O_SAMPLE] + 0.5 * ns - s_ref) / fs
                txrel = CA[j] + o[K.O_PERIOD] * SIG[j, SIG_PERIOD] + \
                    (o[K.O_CODE_PHASE] + 0.5 * ns * o[K.O_CODE_RATE] / fs) / chip
                if gal:
                    rho_meas = C_LIGHT * (tau_mid - txrel) + \
                        code_disc_boc_m(o[K.O_E], o[K.O_L], CF[j, K.C_EL_SPACING], chip)
                    dop = o[K.O_DOPPLER] + freq_disc_hz(halves[0], halves[1], halves[2], halves[3], t_int)
                else:
                    rho_meas = C_LIGHT * (tau_mid - txrel) + \
                        code_disc_m(o[K.O_E], o[K.O_L], K.el_spacing(ST[j], CF[j]), chip)
                    dop = o[K.O_DOPPLER] + freq_disc_hz(o[K.O_P1I], o[K.O_P1Q], o[K.O_P2I], o[K.O_P2Q], t_int)
                rate_meas = -SIG[j, SIG_LAMBDA] * dop
                rho_hat, rate_hat, _ = _predict_channel(x, lay, POLY, TAU_A, ATM, j, tau_mid, tau_k,
                                                        sp, sv, e, G[j])
                zc[j] += rho_meas - rho_hat
                zf[j] += rate_meas - rate_hat
                cnt[j] += 1
                E[j, 0] = e[0]
                E[j, 1] = e[1]
                E[j, 2] = e[2]
            if cnt[j] > 0:
                zc[j] /= cnt[j]
                zf[j] /= cnt[j]
                valid[j] = ST[j, K.S_CN0] >= prm[P_CN0_MASK] and ST[j, K.S_ABSENT_MS] == 0 and \
                    abs(zc[j]) < GROSS_CODE_M and \
                    abs(zf[j]) < GROSS_RATE_MPS
        if prm[P_COAST_MASK] > 0 and nlock < 4:
            # coasting: a channel without signal measures noise; the filter is propagated, not pulled
            for j in range(m):
                if not vector_locked(ST[j], WK[j], SIG[j], prm):
                    valid[j] = False
        nvalid = 0
        for j in range(m):
            if valid[j]:
                nvalid += 1
        tp, tv, fired = kf_update_isb(x, P, lay, E, G, zc, zf, valid, Rc, Rf, QB, prm[P_CHI2], diag,
                                      prm[P_GATE])
        adapt_r(int(prm[P_FORM]), valid, diag, W, WI, WN, WS, Rc, Rf, int(prm[P_MIN_FILL]),
                prm[P_FLOOR_C], prm[P_FLOOR_F])
        # ---- NCO commands for each channel's next correlation epoch
        for j in range(m):
            if not ACTIVE[j]:
                continue
            chip = SIG[j, SIG_CHIP]
            s_next = ST[j, K.S_NEXT_SAMPLE]
            tau_n = (s_next - s_ref) / fs
            rho_n, _, _ = _predict_channel(x, lay, POLY, TAU_A, ATM, j, tau_n, tau_k, sp, sv, e, G[j])
            tx_pred = tau_n - rho_n / C_LIGHT
            tx_nco = CA[j] + ST[j, K.S_CODE_PERIOD] * SIG[j, SIG_PERIOD] + ST[j, K.S_CODE_PHASE] / chip
            shift = (tx_pred - tx_nco) * chip
            if shift > MAX_SHIFT:
                shift = MAX_SHIFT
            elif shift < -MAX_SHIFT:
                shift = -MAX_SHIFT
            ST[j, K.S_CODE_PHASE] += shift
            tau_m = tau_n + 0.5 * SIG[j, SIG_PERIOD] * ST[j, K.S_INT_MS]
            _, rate_c, rate_code = _predict_channel(x, lay, POLY, TAU_A, ATM, j, tau_m, tau_k, sp, sv, e,
                                                    G[j])
            ST[j, K.S_CODE_RATE] = chip * (1.0 - rate_code / C_LIGHT)
            dop = -rate_c / SIG[j, SIG_LAMBDA]
            ST[j, K.S_CARR_FREQ] = SIG[j, SIG_IF] + dop
            ST[j, K.S_PLL_FREQ] = dop
        # ---- log
        LOG[k, L_TAU] = tau_k
        LOG[k, L_TAGP] = tp
        LOG[k, L_TAGV] = tv
        LOG[k, L_FIRED] = fired
        LOG[k, L_NVALID] = nvalid
        LOG[k, L_NLOCK] = nlock
        for a in range(n):
            LX[k, a] = x[a]
            LPD[k, a] = P[a, a]
        for j in range(m):
            LR[k, j, 0] = Rc[j]
            LR[k, j, 1] = Rf[j]
        grid_next += step
        k += 1
    return k, grid_next
