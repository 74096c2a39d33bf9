"""The correlator-level simulator (receiver.sim.corrsim) closed around a carrier loop's compiled twin: every
epoch of a run in one numba function.  The figure scripts (scripts/figures/figures_carrier.py, figures_check.py) use
it; corrsim.run (numpy per epoch, the Python loop's ``step``) stays the reference, and the two give the same
records (tests/unit/tracking/test_corrsim_compiled.py: the same noise draw, the same arithmetic in the same order,
numpy's
pairwise sums included).  It lives in this top layer because it needs both the simulator's correlator model
and the receiver's loops, and the simulator must not depend on the receiver stages."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..sim.corrsim import DT, OUT_KEYS, CorrScenario, prepare
from ..tracking.loops.compiled import (KIND_CPLL, KINDS, L_CN0, L_NCO_FREQ, L_NCO_PHASE, P_KIND, TWO_PI,
                                       loop_start, loop_update, pack)


def run(loop, sc: CorrScenario, truth=None) -> dict:
    """corrsim.run's records (OUT_KEYS) with `loop`'s compiled twin (receiver/tracking/loops/compiled.py,
    packed from `loop`, which is only read, not stepped).  ValueError for a loop without a compiled twin or
    t_coh_ms > 64 (the numpy-order sum covers at most 64 steps per half epoch)."""
    P = prepare(sc, truth)
    m, T, n_ep = P["m"], P["T"], P["n_ep"]
    if m > 64:
        raise ValueError("corrloop.run: t_coh_ms > 64 (the numpy-order sum covers <= 64 steps)")
    if getattr(loop, "name", None) not in KINDS:
        raise ValueError(f"corrloop.run: no compiled twin of the loop {getattr(loop, 'name', loop)!r}")
    lp, ls = pack(loop)
    loop_start(lp, ls, P["f_true0"] + sc.init_doppler_err_hz, T, 0.0, sc.carrier_hz)
    res = np.empty((len(OUT_KEYS), n_ep))
    _run_compiled(np.asarray(P["t"], float), np.asarray(P["theta"], float), P["th_mid"], P["fr"], P["a_mid"],
                  np.asarray(P["cn0"], float), P["noise"], P["tau"], m, T, float(P["offset"]), lp, ls,
                  int(lp[P_KIND]) != KIND_CPLL, res)
    return {k: res[i] for i, k in enumerate(OUT_KEYS)}


@njit(cache=True, nogil=True)
def _pairwise_sum(re, im, s, n):
    """Sum of the n complex values re[s:s+n] + j im[s:s+n] in numpy's order (its pairwise summation of a
    complex array's reduce, for n <= 64: sequential below 4 values, else four running partial sums combined
    as (r0 + r1) + (r2 + r3), then the remainder), so that the compiled path adds exactly as ``c.sum()``."""
    if n < 4:
        rr = -0.0
        ri = -0.0
        for i in range(n):
            rr += re[s + i]
            ri += im[s + i]
        return rr, ri
    r0, r1, r2, r3 = re[s], re[s + 1], re[s + 2], re[s + 3]
    q0, q1, q2, q3 = im[s], im[s + 1], im[s + 2], im[s + 3]
    i = 4
    lim = n - (n % 4)
    while i < lim:
        r0 += re[s + i]
        r1 += re[s + i + 1]
        r2 += re[s + i + 2]
        r3 += re[s + i + 3]
        q0 += im[s + i]
        q1 += im[s + i + 1]
        q2 += im[s + i + 2]
        q3 += im[s + i + 3]
        i += 4
    rr = (r0 + r1) + (r2 + r3)
    ri = (q0 + q1) + (q2 + q3)
    while i < n:
        rr += re[s + i]
        ri += im[s + i]
        i += 1
    return rr, ri


@njit(cache=True, nogil=True)
def _run_compiled(t, theta, th_mid, fr, a_mid, cn0, noise, tau, m, T, offset, lp, ls, has_cn0, out):
    """All epochs of :func:`run`: the correlator model of each epoch from the truth arrays,
    then the loop's compiled update (receiver.tracking.loops.compiled.loop_update) sets the next NCO.  The
    operations are those of the numpy path in the same order (exp(j y) as cos y + j sin y, np.sinc as
    sin(pi x) / (pi x) with x = 0 -> 1e-20); out rows in the order of OUT_KEYS."""
    steps = 2 * m
    n_ep = noise.shape[0]
    cre = np.empty(steps)
    cim = np.empty(steps)
    for k in range(n_ep):
        i0 = k * steps
        p = ls[L_NCO_PHASE]
        f = ls[L_NCO_FREQ]
        for j in range(steps):
            i = i0 + j
            y = TWO_PI * (th_mid[i] - offset - p - f * tau[j])
            x = (fr[i] - f) * DT
            if x == 0.0:
                x = 1.0e-20
            x = math.pi * x
            sc = math.sin(x) / x
            nz = noise[k, j]
            cre[j] = a_mid[i] * math.cos(y) * sc + nz.real
            cim[j] = a_mid[i] * math.sin(y) * sc + nz.imag
        p1i, p1q = _pairwise_sum(cre, cim, 0, m)
        p2i, p2q = _pairwise_sum(cre, cim, m, m)
        ip = p1i + p2i
        qp = p1q + p2q
        im = i0 + m
        out[0, k] = t[im]
        out[1, k] = ip
        out[2, k] = qp
        out[3, k] = theta[im] - offset - (p + f * T / 2.0)
        out[4, k] = cn0[im]
        out[6, k] = f
        out[7, k] = fr[im]
        loop_update(lp, ls, ip, qp, T, p1i, p1q, p2i, p2q)
        out[5, k] = 10 * math.log10(ls[L_CN0]) if has_cn0 else np.nan
