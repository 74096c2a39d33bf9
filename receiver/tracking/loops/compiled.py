"""Compiled epoch loop for the carrier-loop variants (cpll_atan, kf, adaptive_kf, ekf, pli_ekf).

The Python loop classes (cpll.py, kfpll.py, ekf.py) are the readable reference; each has here a compiled
twin of its ``start`` / ``step`` working on two float64 arrays: ``lp`` (parameters, fixed for the channel)
and ``ls`` (state), packed from the Python object by :func:`pack`.  :func:`builtin_start` /
:func:`builtin_update` are that twin through the carrier-loop interface's compiled path (the signatures of
receiver/tracking/loops/runner.py, whose epoch loop runs them as it runs a plugin's); the results agree
with the Python-stepped loops bit for bit (tests/unit/tracking/test_carrier_compiled.py).

Per variant: a ``KIND_*`` code, a packing branch in :func:`pack`, a start branch in :func:`loop_start` and an
update branch in :func:`loop_update`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...gnss.signals import C_LIGHT
from .ekf import ekf_step
from .kfpll import kf_prior_hph, kf_step
from .runner import START_SIG, UPDATE_SIG, CompiledFunction

TWO_PI = 2.0 * math.pi

KIND_CPLL, KIND_KF, KIND_AKF, KIND_EKF, KIND_PLIEKF = 1, 2, 3, 4, 5
KINDS = {"cpll_atan": KIND_CPLL, "kf": KIND_KF, "adaptive_kf": KIND_AKF, "ekf": KIND_EKF, "pli_ekf": KIND_PLIEKF}

# ---- parameters (lp)
P_KIND = 0
P_NW_CN0 = 1          # NWPR initial C/N0 (linear, as the Python NWPR computes it from dB-Hz)
P_NW_TAU = 2
P_CN0_DESIGN = 3      # design C/N0 (linear)
P_H0 = 4
P_H_2 = 5
P_A = 6               # cpll: bn; kf: jerk PSD; ekf: q
P_B = 7               # cpll: order; kf: window; ekf: amp_tau
P_C = 8               # ekf: pli_tau
P_D = 9               # ekf: pli_min
P_TWO = 10            # 2.0: the exponent of NWPR's |p| ** 2 (see _nwpr)
N_PARAM = 11

# ---- state (ls)
L_STARTED = 0
L_NCO_PHASE = 1
L_NCO_FREQ = 2
L_DOPPLER = 3
L_LAST_ERR = 4
L_T = 5
L_CARRIER_HZ = 6
L_NW_CN0 = 7
L_NW_MU = 8
L_NW_MU_SET = 9
L_CN0 = 10
L_V = 11              # variant state from here
# cpll
L_FREQ, L_RATE = L_V, L_V + 1
# kf / adaptive_kf
L_KS = L_V            # 3
L_KP = L_V + 3        # 9
L_PENDING = L_V + 12
L_LAM = L_V + 13
L_INN_N = L_V + 14
L_INN_HEAD = L_V + 15
L_INN = L_V + 16      # window entries
# ekf / pli_ekf
L_ES = L_V            # 4
L_EP = L_V + 4        # 16
L_POST = L_V + 20     # 4
L_PFAST = L_V + 24
L_PSLOW = L_V + 25
L_PPOW_SET = L_V + 26
L_PREV_SET = L_V + 27
L_PREV_X = L_V + 28   # 2
L_PREV_H = L_V + 30   # 2
L_PREV_POST = L_V + 32  # 4
L_PREV_NCO = L_V + 36
L_PLI = L_V + 37
L_PLI_I2 = L_V + 38
L_PLI_Q2 = L_V + 39
L_PLI_SET = L_V + 40
N_EKF_STATE = L_V + 41


def pack(loop):
    """(lp, ls) arrays of a Python loop object (its configuration; the state is set by loop_start)."""
    kind = KINDS[loop.name]
    lp = np.zeros(N_PARAM)
    lp[P_KIND] = kind
    lp[P_TWO] = 2.0
    if kind == KIND_CPLL:
        lp[P_A] = loop.bn
        lp[P_B] = loop.order
        ls = np.zeros(L_V + 2)
    else:
        # NWPR(10 log10(cn0_design), tau): the same initial value as the Python estimator computes
        lp[P_NW_CN0] = 10 ** ((10 * math.log10(loop.cn0_design)) / 10.0)
        lp[P_NW_TAU] = loop.cn0_tau
        lp[P_CN0_DESIGN] = loop.cn0_design
        lp[P_H0] = loop.h0
        lp[P_H_2] = loop.h_2
        if kind in (KIND_KF, KIND_AKF):
            lp[P_A] = loop.jerk_psd
            lp[P_B] = loop.window
            ls = np.zeros(L_INN + max(1, loop.window))
        else:
            lp[P_A] = loop.q
            lp[P_B] = loop.amp_tau
            lp[P_C] = loop.pli_tau
            lp[P_D] = loop.pli_min
            ls = np.zeros(N_EKF_STATE)
    return lp, ls


# ------------------------------------------------------------------ shared pieces
@njit(cache=True, nogil=True)
def _nwpr(lp, ls, p1i, p1q, p2i, p2q, T):
    """NWPR C/N0 (common.NWPR.update)."""
    # |p|^2 rounded as the Python NWPR's abs(p) ** 2: hypot, then libm pow(x, 2.0) (not always x * x: glibc's
    # pow is not correctly rounded).  The exponent comes from lp so that LLVM cannot rewrite pow(x, 2.0) as
    # x * x; a last-bit difference here would be amplified by chaotic runs
    # (tests/unit/tracking/test_corrsim_compiled.py).
    two = lp[P_TWO]
    wbp = math.hypot(p1i, p1q) ** two + math.hypot(p2i, p2q) ** two
    if wbp <= 0:
        return ls[L_NW_CN0]
    r = math.hypot(p1i + p2i, p1q + p2q) ** two / wbp
    ts = T / 2.0
    if ls[L_NW_MU_SET] == 0.0:
        c = ls[L_NW_CN0] * ts
        ls[L_NW_MU] = (1.0 + 2.0 * c) / (1.0 + c)
        ls[L_NW_MU_SET] = 1.0
    tau = lp[P_NW_TAU]
    a = min(1.0, T / tau) if tau > 0 else 1.0
    ls[L_NW_MU] += a * (r - ls[L_NW_MU])
    mu = min(max(ls[L_NW_MU], 1.0 + 1e-4), 2.0 - 1e-4)
    ls[L_NW_CN0] = max((mu - 1.0) / (ts * (2.0 - mu)), 1.0)
    return ls[L_NW_CN0]


@njit(cache=True, nogil=True)
def _atan_var(cn0, T):
    x = 2.0 * T * cn0
    return (1.0 / x) * (1.0 + 1.0 / x) / (4.0 * math.pi ** 2)


@njit(cache=True, nogil=True)
def _clock_q_add(Q, T, h0, h_2, fc, scale):
    sf = h0 / 2.0 * fc * fc
    sg = 2.0 * math.pi ** 2 * h_2 * fc * fc
    Q[0, 0] += (sf * T + sg * T ** 3 / 3.0) * scale
    Q[0, 1] += (sg * T ** 2 / 2.0) * scale
    Q[1, 0] += (sg * T ** 2 / 2.0) * scale
    Q[1, 1] += (sg * T) * scale


@njit(cache=True, nogil=True)
def _command(ls, T, start_phase, freq):
    end = ls[L_NCO_PHASE] + ls[L_NCO_FREQ] * T
    ls[L_NCO_PHASE] = start_phase
    ls[L_NCO_FREQ] = freq
    ls[L_DOPPLER] = freq
    return freq, start_phase - end


_FACT = np.array([1.0, 1.0, 2.0, 6.0, 24.0, 120.0, 720.0])


# ------------------------------------------------------------------ start / update
@njit(cache=True, nogil=True)
def loop_start(lp, ls, doppler_hz, T, rate_hz_s, carrier_hz):
    """PythonLoop.start + the variant's init."""
    kind = int(lp[P_KIND])
    ls[:] = 0.0
    ls[L_STARTED] = 1.0
    ls[L_DOPPLER] = doppler_hz
    ls[L_T] = T
    ls[L_CARRIER_HZ] = carrier_hz
    ls[L_NCO_PHASE] = 0.0
    ls[L_NCO_FREQ] = doppler_hz
    ls[L_NW_CN0] = lp[P_NW_CN0]
    ls[L_CN0] = lp[P_CN0_DESIGN]
    if kind == KIND_CPLL:
        ls[L_FREQ] = doppler_hz
        ls[L_RATE] = rate_hz_s if int(lp[P_B]) == 3 else 0.0
    elif kind == KIND_KF or kind == KIND_AKF:
        ls[L_KS] = ls[L_NCO_PHASE]
        ls[L_KS + 1] = doppler_hz
        ls[L_KS + 2] = rate_hz_s
        ls[L_KP] = 0.05 ** 2
        ls[L_KP + 4] = 3.0 ** 2
        ls[L_KP + 8] = 20.0 ** 2
        ls[L_PENDING] = 1.0
        ls[L_LAM] = 1.0
    else:
        ls[L_ES] = TWO_PI * doppler_hz * T / 2.0
        ls[L_ES + 1] = TWO_PI * doppler_hz
        ls[L_ES + 2] = TWO_PI * rate_hz_s
        ls[L_EP] = 0.3 ** 2
        ls[L_EP + 5] = (TWO_PI * 3.0) ** 2
        ls[L_EP + 10] = (TWO_PI * 20.0) ** 2
        ls[L_EP + 15] = (TWO_PI * 20.0) ** 2
        ls[L_PLI] = 1.0


@njit(cache=True, nogil=True)
def loop_update(lp, ls, ip, qp, T, p1i, p1q, p2i, p2q):
    """One epoch: (Doppler for the next epoch, NCO phase step in cycles), as the Python loop's step."""
    kind = int(lp[P_KIND])
    if kind == KIND_CPLL:
        e = math.atan(qp / ip) / (2.0 * math.pi) if ip != 0.0 else 0.0
        ls[L_LAST_ERR] = e
        bn = lp[P_A]
        if int(lp[P_B]) == 3:
            w0 = bn / 0.7845
            ls[L_RATE] += T * w0 ** 3 * e
            ls[L_FREQ] += T * (ls[L_RATE] + 1.1 * w0 * w0 * e)
            f = ls[L_FREQ] + 2.4 * w0 * e
        else:
            w0 = bn / 0.53
            ls[L_FREQ] += T * w0 * w0 * e
            f = ls[L_FREQ] + 1.414 * w0 * e
        return _command(ls, T, ls[L_NCO_PHASE] + ls[L_NCO_FREQ] * T, f)
    fc = ls[L_CARRIER_HZ]
    if kind == KIND_KF or kind == KIND_AKF:
        phi = np.array([[1.0, T, T * T / 2.0], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
        H = np.array([1.0, T / 2.0, T * T / 6.0])
        q = lp[P_A] * (fc / C_LIGHT) ** 2
        Q = np.empty((3, 3))
        Q[0, 0], Q[0, 1], Q[0, 2] = q * T ** 5 / 20, q * T ** 4 / 8, q * T ** 3 / 6
        Q[1, 0], Q[1, 1], Q[1, 2] = q * T ** 4 / 8, q * T ** 3 / 3, q * T ** 2 / 2
        Q[2, 0], Q[2, 1], Q[2, 2] = q * T ** 3 / 6, q * T ** 2 / 2, q * T
        _clock_q_add(Q, T, lp[P_H0], lp[P_H_2], fc, 1.0)
        s = ls[L_KS:L_KS + 3]
        P = ls[L_KP:L_KP + 9].reshape((3, 3))
        e = math.atan(qp / ip) / (2.0 * math.pi) if ip != 0.0 else 0.0
        ls[L_LAST_ERR] = e
        z = e + ls[L_NCO_PHASE] + ls[L_NCO_FREQ] * T / 2.0
        d = z - (H[0] * s[0] + H[1] * s[1] + H[2] * s[2])
        adaptive = kind == KIND_AKF
        if adaptive:
            ls[L_CN0] = _nwpr(lp, ls, p1i, p1q, p2i, p2q, T)
            R = _atan_var(ls[L_CN0], T)
        else:
            R = _atan_var(lp[P_CN0_DESIGN], T)
        first = ls[L_PENDING] != 0.0
        ls[L_PENDING] = 0.0
        if adaptive and not first:
            w = int(lp[P_B])
            head = int(ls[L_INN_HEAD])
            ls[L_INN + head] = d * d
            ls[L_INN_HEAD] = (head + 1) % w
            if ls[L_INN_N] < w:
                ls[L_INN_N] += 1
            n = int(ls[L_INN_N])
            acc = 0.0                       # oldest first, as sum() over the deque
            start = (int(ls[L_INN_HEAD]) - n) % w
            for i in range(n):
                acc += ls[L_INN + (start + i) % w]
            c_hat = acc / n
            hph = kf_prior_hph(P, phi, Q, H)
            ls[L_LAM] = max(1.0, (c_hat - R) / hph) if hph > 0 else 1.0
        kf_step(s, P, phi, H, Q, d, R, ls[L_LAM], first)
        return _command(ls, T, s[0], s[1] + s[2] * T / 2.0)
    # ekf / pli_ekf
    phi = np.eye(4)
    for i in range(4):
        for j in range(i + 1, 4):
            phi[i, j] = T ** (j - i) / _FACT[j - i]
    Q = np.empty((4, 4))
    qq = lp[P_A]
    for i in range(4):
        for j in range(4):
            ex = 7 - i - j
            Q[i, j] = qq * T ** ex / (_FACT[3 - i] * _FACT[3 - j] * ex)
    _clock_q_add(Q, T, lp[P_H0], lp[P_H_2], fc, TWO_PI ** 2)
    s = ls[L_ES:L_ES + 4]
    P = ls[L_EP:L_EP + 16].reshape((4, 4))
    post = ls[L_POST:L_POST + 4]
    # amplitude and noise from the correlator power (EKF._amplitude)
    pw = ip * ip + qp * qp
    cn0 = _nwpr(lp, ls, p1i, p1q, p2i, p2q, T)
    ls[L_CN0] = cn0
    if ls[L_PPOW_SET] == 0.0:
        ls[L_PFAST] = pw
        ls[L_PSLOW] = pw
        ls[L_PPOW_SET] = 1.0
    amp_tau = lp[P_B]
    a = min(1.0, T / amp_tau) if amp_tau > 0 else 1.0
    b = min(1.0, T / lp[P_NW_TAU]) if lp[P_NW_TAU] > 0 else 1.0
    ls[L_PFAST] += a * (pw - ls[L_PFAST])
    ls[L_PSLOW] += b * (pw - ls[L_PSLOW])
    sig2 = ls[L_PSLOW] / (2.0 * (1.0 + cn0 * T))
    A = math.sqrt(max(ls[L_PFAST] - 2.0 * sig2, sig2 / 10.0))
    nco_mid = TWO_PI * (ls[L_NCO_PHASE] + ls[L_NCO_FREQ] * T / 2.0)
    pe = s[0] - nco_mid
    c, sn = math.cos(pe), math.sin(pe)
    hc, hs = A * c, A * sn
    h0, h1 = -A * sn, A * c
    xi, xq = ip, qp
    if ip * hc + qp * hs < 0.0:                       # decision-directed data wipe-off
        xi, xq = -xi, -xq
    use_pli = kind == KIND_PLIEKF
    if use_pli:
        if ls[L_PLI_SET] == 0.0:
            ls[L_PLI_I2], ls[L_PLI_Q2] = ip * ip, qp * qp
            ls[L_PLI_SET] = 1.0
        pli_tau = lp[P_C]
        w = min(1.0, T / pli_tau) if pli_tau > 0 else 1.0
        ls[L_PLI_I2] += w * (ip * ip - ls[L_PLI_I2])
        ls[L_PLI_Q2] += w * (qp * qp - ls[L_PLI_Q2])
        tot = ls[L_PLI_I2] + ls[L_PLI_Q2]
        pli = (ls[L_PLI_I2] - ls[L_PLI_Q2]) / tot if tot > 0 else 0.0
        pli = min(max(pli, lp[P_D]), 1.0)
        ls[L_PLI] = pli
        if ls[L_PREV_SET] != 0.0:
            ds0 = s[0] - ls[L_PREV_POST] - (nco_mid - ls[L_PREV_NCO])
            xi = pli * xi + (1.0 - pli) * (ls[L_PREV_X] + ls[L_PREV_H] * ds0)
            xq = pli * xq + (1.0 - pli) * (ls[L_PREV_X + 1] + ls[L_PREV_H + 1] * ds0)
        ls[L_PREV_H], ls[L_PREV_H + 1] = h0, h1
        ls[L_PREV_NCO] = nco_mid
    ekf_step(s, P, phi, Q, h0, h1, xi - hc, xq - hs, sig2, post)
    ls[L_LAST_ERR] = (post[0] - nco_mid) / TWO_PI
    if use_pli:
        ls[L_PREV_X], ls[L_PREV_X + 1] = xi, xq
        for i in range(4):
            ls[L_PREV_POST + i] = post[i]
        ls[L_PREV_SET] = 1.0
    f = s[1] / TWO_PI
    return _command(ls, T, s[0] / TWO_PI - f * T / 2.0, f)


# ------------------------------------------------------------------ the loop interface's compiled path
# (compiled for START_SIG / UPDATE_SIG at their first use, by runner.CompiledFunction, not at import: a run
# on the built-in PLL does not load them -- ~75 ms of numba's cache and set-up at every start)
@njit(cache=True, nogil=True)
def builtin_start(lp, ls, doppler_hz, T, rate_hz_s, carrier_hz):
    """The built-in variants' compiled ``start`` (receiver/tracking/loops/runner.py START_SIG)."""
    loop_start(lp, ls, doppler_hz, T, rate_hz_s, carrier_hz)


@njit(cache=True, nogil=True)
def builtin_update(lp, ls, ip, qp, T, p1i, p1q, p2i, p2q):
    """The built-in variants' compiled ``update`` (UPDATE_SIG)."""
    return loop_update(lp, ls, ip, qp, T, p1i, p1q, p2i, p2q)


_FUNCTIONS = []


class CompiledTwin:
    """Mixin of the built-in Python loops: their :meth:`compiled` path is this module's twin (as a plugin's
    is its own pair of functions; receiver/tracking/loops/plugin.py)."""

    def compiled(self):
        """``(start, update, lp, ls)`` of this module's compiled twin of the loop (the built-in functions and the
        loop's packed parameters / state)."""
        if not _FUNCTIONS:
            _FUNCTIONS.extend((CompiledFunction(builtin_start, START_SIG),
                               CompiledFunction(builtin_update, UPDATE_SIG)))
        lp, ls = pack(self)
        return _FUNCTIONS[0], _FUNCTIONS[1], lp, ls
