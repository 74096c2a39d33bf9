"""Compiled Kalman-filter core shared by every vector-loop variant.

The variants differ only in their state layout, transition matrix F, process noise Q, manoeuvre noise QB and
options (adaptive R form, chi-square manoeuvre detection); the measurement model is the same for all:

    code channel j:     z_code,j = rho_meas,j - rho_hat,j = -e_j^T (r - r_hat) + (b - b_hat) + eta_j
    carrier channel j:  z_carr,j = rate_meas,j - rate_hat,j = -e_j^T (v - v_hat) + (d - d_hat) + w_j

with e_j the unit line of sight receiver -> satellite (the papers' a_j = -e_j), r, v the receiver position
and velocity, b the (code) clock bias and d the carrier clock drift (both in metres, m/s).  The state
layout array ``lay`` = [ip, iv, ib, id, idel] gives the indices of x, y, z (ip..ip+2), vx, vy, vz
(iv..iv+2), b, d and of the code-minus-carrier drift (idel, -1 when absent).  Channels of a system other
than the clock's reference system (a run over several signals) see b + isb_s: their code rows have a 1 in
the column of that system's inter-system bias state too (``G`` (m,): the state index, -1 for the reference
system; :func:`kf_update_isb`).

Updates are sequential scalar updates (R diagonal), which is exactly the batch update.  Everything here
is numba-compiled; :mod:`receiver.tracking.vector.loop` calls it once per epoch.
"""
from __future__ import annotations


import numpy as np
from numba import njit

FORM_NONE = 0
FORM_PAPER = 1          # R = C_v + H P+ H^T   (innovations, posterior covariance: as printed)
FORM_INNOVATION = 2     # R = C_v - H P- H^T   (textbook innovation-based)
FORM_RESIDUAL = 3       # R = C_r + H P+ H^T   (textbook residual-based)
FORMS = {"none": FORM_NONE, "paper": FORM_PAPER, "innovation": FORM_INNOVATION, "residual": FORM_RESIDUAL}



@njit(cache=True)
def kf_predict(x, P, F, Q):
    """x <- F x, P <- F P F^T + Q (in place), in plain loops (BLAS calls for these small matrices cost more
    than the arithmetic; the sums' order differs from numpy's at the float-rounding level).

    Transitions are sparse (two or three entries per row: 18 x 18 for the polynomial filter), so the sums
    run over each row's non-zero entries only, in the same order as the dense sums: skipped terms are exact
    zeros, so the result is the dense product's to the bit (for finite P)."""
    n = x.shape[0]
    nz = np.empty((n, n), np.int64)
    cnt = np.zeros(n, np.int64)
    for i in range(n):
        c = 0
        for k in range(n):
            if F[i, k] != 0.0:
                nz[i, c] = k
                c += 1
        cnt[i] = c
    xn = np.empty(n)
    for i in range(n):
        acc = 0.0
        for t in range(cnt[i]):
            k = nz[i, t]
            acc += F[i, k] * x[k]
        xn[i] = acc
    x[:] = xn
    FP = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for t in range(cnt[i]):
                k = nz[i, t]
                acc += F[i, k] * P[k, j]
            FP[i, j] = acc
    for i in range(n):
        for j in range(n):
            acc = Q[i, j]
            for t in range(cnt[j]):
                k = nz[j, t]
                acc += FP[i, k] * F[j, k]
            P[i, j] = acc


@njit(cache=True)
def _ph(P, lay, e, kind, out, ig=-1):
    """out = P h for the code (kind 0) or carrier (kind 1) row of LOS e (ig >= 0: the code row's inter-system
    bias column); returns h P h^T."""
    n = P.shape[0]
    i0 = lay[0] if kind == 0 else lay[1]
    ic = lay[2] if kind == 0 else lay[3]
    for r in range(n):
        out[r] = P[r, ic] - e[0] * P[r, i0] - e[1] * P[r, i0 + 1] - e[2] * P[r, i0 + 2]
    if kind == 0 and ig >= 0:
        for r in range(n):
            out[r] += P[r, ig]
        return out[ic] - e[0] * out[i0] - e[1] * out[i0 + 1] - e[2] * out[i0 + 2] + out[ig]
    return out[ic] - e[0] * out[i0] - e[1] * out[i0 + 1] - e[2] * out[i0 + 2]


@njit(cache=True)
def _hdot(lay, e, kind, v, ig=-1):
    """h v for the code (0) or carrier (1) row (ig: as in _ph)."""
    i0 = lay[0] if kind == 0 else lay[1]
    ic = lay[2] if kind == 0 else lay[3]
    if kind == 0 and ig >= 0:
        return v[ic] - e[0] * v[i0] - e[1] * v[i0 + 1] - e[2] * v[i0 + 2] + v[ig]
    return v[ic] - e[0] * v[i0] - e[1] * v[i0 + 1] - e[2] * v[i0 + 2]


@njit(cache=True)
def chi2_tag(P, lay, E, z, R, valid, kind):
    """z^T (H P H^T + R)^-1 z over the valid channels of one measurement type (the manoeuvre tag)."""
    return chi2_tag_isb(P, lay, E, np.full(E.shape[0], -1, np.int64), z, R, valid, kind)


@njit(cache=True)
def chi2_tag_isb(P, lay, E, G, z, R, valid, kind):
    """:func:`chi2_tag` with the channels' inter-system bias columns G (m,) (-1: none)."""
    m = E.shape[0]
    n = P.shape[0]
    idx = np.zeros(m, np.int64)
    mv = 0
    for j in range(m):
        if valid[j]:
            idx[mv] = j
            mv += 1
    if mv == 0:
        return 0.0
    PH = np.zeros((n, mv))
    col = np.zeros(n)
    for a in range(mv):
        _ph(P, lay, E[idx[a]], kind, col, G[idx[a]])
        PH[:, a] = col
    S = np.zeros((mv, mv))
    zz = np.zeros(mv)
    for a in range(mv):
        ja = idx[a]
        for b in range(mv):
            S[a, b] = _hdot(lay, E[ja], kind, PH[:, b], G[ja])
        S[a, a] += R[ja]
        zz[a] = z[ja]
    S = 0.5 * (S + S.T)
    # z^T S^-1 z = |L^-1 z|^2 with S = L L^T (Cholesky in place, forward substitution): no LAPACK call per
    # epoch; a non-positive pivot (S not positive definite in floating point) falls back to the solve
    S0 = S.copy()
    w = zz.copy()
    tag = 0.0
    for a in range(mv):
        d = S[a, a]
        for k in range(a):
            d -= S[a, k] * S[a, k]
        if not d > 0.0:
            y = np.linalg.solve(S0, zz)
            return float(np.dot(zz, y))
        la = np.sqrt(d)
        S[a, a] = la
        for b in range(a + 1, mv):
            v = S[b, a]
            for k in range(a):
                v -= S[b, k] * S[a, k]
            S[b, a] = v / la
        v = w[a]
        for k in range(a):
            v -= S[a, k] * w[k]
        w[a] = v / la
        tag += w[a] * w[a]
    return tag


@njit(cache=True)
def kf_update(x, P, lay, E, zc, zf, valid, Rc, Rf, QB, chi2_thr, diag, gate=0.0):
    """:func:`kf_update_isb` of channels of the reference clock only."""
    return kf_update_isb(x, P, lay, E, np.full(E.shape[0], -1, np.int64), zc, zf, valid, Rc, Rf, QB, chi2_thr,
                         diag, gate)


@njit(cache=True)
def kf_update_isb(x, P, lay, E, G, zc, zf, valid, Rc, Rf, QB, chi2_thr, diag, gate=0.0):
    """One epoch's measurement update (in place).  G (m,): the state index of each channel's inter-system
    bias (-1: a channel of the reference clock).

    E (m, 3) lines of sight, zc / zf innovations (m, m/s), valid (m,) channels with a measurement,
    Rc / Rf (m,) their variances.  When chi2_thr > 0 the code and carrier tags are computed first and,
    when either exceeds the threshold, QB is added to the prior covariance (manoeuvre).  gate > 0: a scalar
    measurement whose innovation exceeds gate * sqrt(h P h^T + R) is not used (its innovation still feeds
    the adaptive-R window).
    diag (m, 8) receives per channel: [hP-h code, hP-h carr, hP+h code, hP+h carr, residual code,
    residual carr, innovation code, innovation carr].  Returns (tag_code, tag_carr, fired).
    """
    n = x.shape[0]
    m = E.shape[0]
    tag_p = 0.0
    tag_v = 0.0
    fired = 0
    if chi2_thr > 0.0:
        tag_p = chi2_tag_isb(P, lay, E, G, zc, Rc, valid, 0)
        tag_v = chi2_tag_isb(P, lay, E, G, zf, Rf, valid, 1)
        if tag_p > chi2_thr or tag_v > chi2_thr:
            P += QB
            fired = 1
    ph = np.zeros(n)
    for j in range(m):
        if valid[j]:
            diag[j, 0] = _ph(P, lay, E[j], 0, ph, G[j])
            diag[j, 1] = _ph(P, lay, E[j], 1, ph)
    dx = np.zeros(n)
    for kind in range(2):
        for j in range(m):
            if not valid[j]:
                continue
            e = E[j]
            s = _ph(P, lay, e, kind, ph, G[j])
            if kind == 0:
                r = Rc[j]
                innov = zc[j] - _hdot(lay, e, 0, dx, G[j])
            else:
                r = Rf[j]
                innov = zf[j] - _hdot(lay, e, 1, dx)
            s += r
            if not s > 0.0:
                continue
            if gate > 0.0 and innov * innov > gate * gate * s:
                continue
            for a in range(n):
                dx[a] += ph[a] * innov / s
            for a in range(n):
                pa = ph[a] / s
                for b in range(n):
                    P[a, b] -= pa * ph[b]
    for a in range(n):
        x[a] += dx[a]
    for a in range(n):
        for b in range(a + 1, n):
            v = 0.5 * (P[a, b] + P[b, a])
            P[a, b] = v
            P[b, a] = v
        if P[a, a] < 1e-12:
            P[a, a] = 1e-12
    for j in range(m):
        if valid[j]:
            diag[j, 2] = _ph(P, lay, E[j], 0, ph, G[j])
            diag[j, 3] = _ph(P, lay, E[j], 1, ph)
            diag[j, 4] = zc[j] - _hdot(lay, E[j], 0, dx, G[j])
            diag[j, 5] = zf[j] - _hdot(lay, E[j], 1, dx)
            diag[j, 6] = zc[j]
            diag[j, 7] = zf[j]
    return tag_p, tag_v, fired


@njit(cache=True)
def adapt_r(form, valid, diag, W, WI, WN, WS, Rc, Rf, min_fill, floor_c, floor_f):
    """Sliding-window re-estimate of each channel's diagonal R after an update (in place).

    W (m, 2, N) holds the last N squared innovations (paper / innovation forms) or post-fit residuals
    (residual form), WI / WN the ring index and fill count per channel, WS (m, 2) the running sums.
    The new Rc / Rf apply from the next epoch; until a window holds min_fill samples the initial R is
    kept.
    """
    if form == 0:
        return
    m = W.shape[0]
    N = W.shape[2]
    for j in range(m):
        if not valid[j]:
            continue
        k = WI[j]
        for t in range(2):
            if form == 3:
                v = diag[j, 4 + t]
            else:
                v = diag[j, 6 + t]
            v2 = v * v
            WS[j, t] += v2 - W[j, t, k]
            W[j, t, k] = v2
        WI[j] = (k + 1) % N
        if WN[j] < N:
            WN[j] += 1
        if WN[j] < min_fill:
            continue
        for t in range(2):
            c = WS[j, t] / WN[j]
            if c < 0.0:               # running-sum round-off
                c = 0.0
            if form == 1:
                r = c + diag[j, 2 + t]
            elif form == 2:
                r = c - diag[j, t]
            else:
                r = c + diag[j, 2 + t]
            if t == 0:
                Rc[j] = r if r > floor_c else floor_c
            else:
                Rf[j] = r if r > floor_f else floor_f


def reset_window(W, WI, WN, WS, j):
    """Forget channel j's window (new channel or a channel re-assigned to another satellite)."""
    W[j] = 0.0
    WI[j] = 0
    WN[j] = 0
    WS[j] = 0.0
