"""One Galileo E1 correlation epoch of a vector channel (compiled; called by the vector loop, loop.py).

A Galileo channel under the vector loop (receiver.tracking.gal_channels.GalTrack handed over) runs one epoch per
4-ms code period on its state row (kernel S_* slots, the Galileo ones G_*), with the NCOs the vector loop
commands (code phase, code rate, carrier frequency); there is no PLL or DLL here.  Per epoch:

* early / prompt / late of the E1-C pilot (BOC(1,1) replica, E-L spacing C_EL_SPACING chips) and the E1-B
  prompt, each over the two halves of the epoch (the frequency discriminator's halves, receiver.tracking.vector
  .discriminators), the CS25 chip of the period wiped off the pilot's correlations: the pilot is then a pure
  carrier over the whole 4 ms and from one epoch to the next;
* the record (kernel O_* columns, EPOCH_DTYPE as the scalar Galileo channel writes it): prompt_i/q the pilot
  prompt, early / late its |E| and |L|, prompt1_i/q the E1-B prompt referred to the pilot's phase,
  B conj(P) / |P| -- the I/NAV symbol without a phase lock (the pilot shares E1-B's carrier; with the scalar
  channel's PLL locked on the pilot, P is real and positive and this is B itself) --, integration_ms 4,
  state bit_sync (every period is a symbol);
* C/N0 of the whole E1 signal (E1-B + E1-C, as the scalar channel and the simulator give it) by the moments
  estimator (M2M4) per component over a window of C_CN0_WIN_MS: S = sqrt(2 M2^2 - M4), C/N0 = (S_C + S_B) /
  (N T) with N the mean of the two noise powers M2 - S;
* the pilot's low-passed phase-lock indicator cos(2 phi) (a record column only: the vector loop does not
  phase-lock).

The pilot halves go to ``halves`` (I1, Q1, I2, Q2, CS25 wiped) for the loop's frequency discriminator.
"""
from __future__ import annotations

import math

from numba import njit

from .. import kernel as K
from ..gal import _correlate_block
from ..gal_channels import G_CARR_PHASE01, G_CS25, G_PLI, N_REPLICA, PLI_KEEP
from ...gnss.gal_codes import E1_CODE_LEN
from ...runfile.record import STATE_BIT_SYNC


@njit(cache=True)
def gal_epoch(samples, block_start, st, cfg, code, o, halves):
    """One 4-ms epoch of a Galileo vector channel from its state row ``st`` (config ``cfg``, code row ``code``:
    E1-C replica, E1-B replica, CS25) on the block ``samples`` (first sample = file index block_start); the
    record goes to ``o`` (kernel O_* columns), the pilot's half-epoch prompts to ``halves``.  Returns 1, or 0
    when the epoch does not fit in the block (nothing changed)."""
    fs = cfg[K.C_FS]
    step = st[K.S_CODE_RATE] / fs
    cp = st[K.S_CODE_PHASE]
    n = int(math.ceil((E1_CODE_LEN - cp) / step - 1e-9))
    off = int(st[K.S_NEXT_SAMPLE]) - block_start
    if off < 0 or n < 2 or off + n > samples.shape[0]:
        return 0
    carr_step = st[K.S_CARR_FREQ] / fs
    ph = st[G_CARR_PHASE01]
    half_d = 0.5 * cfg[K.C_EL_SPACING]
    rep_c = code[:N_REPLICA]
    rep_b = code[N_REPLICA:2 * N_REPLICA]
    s = float(code[2 * N_REPLICA + (int(st[K.S_CODE_PERIOD]) + int(st[G_CS25])) % 25])
    n1 = n // 2
    e1, p1, l1, b1 = _correlate_block(samples, off, n1, cp, step, ph, carr_step, rep_c, rep_b, half_d)
    e2, p2, l2, b2 = _correlate_block(samples, off + n1, n - n1, cp + n1 * step, step, ph + n1 * carr_step,
                                      carr_step, rep_c, rep_b, half_d)
    p1 = p1 * s
    p2 = p2 * s
    p = p1 + p2
    ae = abs(e1 + e2)
    al = abs(l1 + l2)
    b = b1 + b2
    halves[0] = p1.real
    halves[1] = p1.imag
    halves[2] = p2.real
    halves[3] = p2.imag
    ap = abs(p)
    sym = b * p.conjugate() / ap if ap > 0.0 else 0j
    T = n / fs
    # ---- record (NCO state at the epoch start)
    o[K.O_TIME] = st[K.S_NEXT_SAMPLE] / fs
    o[K.O_SAMPLE] = st[K.S_NEXT_SAMPLE]
    o[K.O_PERIOD] = st[K.S_CODE_PERIOD]
    o[K.O_CODE_PHASE] = cp
    o[K.O_CODE_RATE] = st[K.S_CODE_RATE]
    o[K.O_DOPPLER] = st[K.S_CARR_FREQ] - cfg[K.C_IF]
    o[K.O_CARR_PHASE] = st[K.S_CARR_PHASE]
    o[K.O_PI] = p.real
    o[K.O_PQ] = p.imag
    o[K.O_E] = ae
    o[K.O_L] = al
    o[K.O_INT_MS] = 4.0
    o[K.O_P1I] = sym.real
    o[K.O_P1Q] = sym.imag
    o[K.O_P2I] = 0.0
    o[K.O_P2Q] = 0.0
    o[K.O_CARR_ERR] = math.atan2(p.imag, p.real) / (2.0 * math.pi)
    o[K.O_CODE_ERR] = (ae - al) / (ae + al) * (2.0 - 6.0 * half_d) / 6.0 if ae + al > 0.0 else 0.0
    o[K.O_STATE] = STATE_BIT_SYNC
    # ---- NCOs to the end of the epoch
    st[K.S_NEXT_SAMPLE] += n
    st[K.S_CODE_PHASE] = cp + n * step - E1_CODE_LEN
    st[G_CARR_PHASE01] = (ph + n * carr_step) % 1.0
    st[K.S_CARR_PHASE] += n * carr_step
    st[K.S_CODE_PERIOD] += 1.0
    st[K.S_TOTAL_MS] += 4.0
    st[K.S_MODE_MS] += 4.0
    # ---- C/N0 (whole E1: pilot + data, M2M4 per component over the window)
    pc = p.real * p.real + p.imag * p.imag
    pb = b.real * b.real + b.imag * b.imag
    st[K.S_ACC_M2] += pc
    st[K.S_ACC_M4] += pc * pc
    st[K.S_ACC_I2] += pb
    st[K.S_ACC_Q2] += pb * pb
    st[K.S_ACC_N] += 1.0
    if st[K.S_ACC_N] * 4.0 >= cfg[K.C_CN0_WIN_MS]:
        k = st[K.S_ACC_N]
        m2c = st[K.S_ACC_M2] / k
        m4c = st[K.S_ACC_M4] / k
        m2b = st[K.S_ACC_I2] / k
        m4b = st[K.S_ACC_Q2] / k
        s_c = math.sqrt(max(2.0 * m2c * m2c - m4c, 0.0))
        s_b = math.sqrt(max(2.0 * m2b * m2b - m4b, 0.0))
        noise = 0.5 * ((m2c - s_c) + (m2b - s_b))
        cn0 = (s_c + s_b) / (noise * T) if noise > 0.0 else 0.0
        st[K.S_CN0] = 10.0 * math.log10(cn0) if cn0 > 1.0 else 0.0
        for i in (K.S_ACC_M2, K.S_ACC_M4, K.S_ACC_I2, K.S_ACC_Q2, K.S_ACC_N):
            st[i] = 0.0
    o[K.O_CN0] = st[K.S_CN0]
    cos2 = (p.real * p.real - p.imag * p.imag) / pc if pc > 0.0 else 0.0
    st[G_PLI] = PLI_KEEP * st[G_PLI] + (1.0 - PLI_KEEP) * cos2
    o[K.O_PLI] = st[G_PLI]
    st[K.S_LOCK] = 1.0 if st[K.S_CN0] >= cfg[K.C_LOCK_CN0_MIN] else 0.0
    o[K.O_LOCK] = st[K.S_LOCK]
    return 1
