"""The time of a snapshot's first sample from data-bit transitions (coarse-time navigation, after the fix).

The code phases alone give the time of the first sample only to milliseconds: its partial derivatives are the
satellites' range rates (hundreds of m/s), against metres of pseudorange noise.  A data-bit transition leaves
a satellite when its clock reads a multiple of 20 ms; with the fix's position (tens of metres, i.e. 0.1 us)
each transition seen gives the first sample's time modulo 20 ms to a fraction of a microsecond.  The
transitions of all satellites are used jointly: their times modulo 20 ms must agree (a transition on the
wrong code epoch, or a false one, disagrees by a millisecond or more and is rejected), the agreeing ones
are averaged and the multiple of 20 ms is the one nearest the fix's own time.  That last step is right
while the code-phase time is within 10 ms of the truth: the physical limit of the method (see
docs/snapshot.md).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..gnss.signals import C_LIGHT
from .snapshot import coarse_time_fix
from .snapshot_model import (Ephemerides, SnapObs, SnapshotFix, SnapshotSettings, corrections, sat_geometry,
                             sigma_m)

BIT_S = 0.02          # GPS L1 C/A data bit


def edge_offsets(fix: SnapshotFix, edges: dict, ephs: Ephemerides, settings: SnapshotSettings) -> dict:
    """{prn: d}: for each transition (``edges`` {prn: its arrival, s after the first sample}) the correction d
    (s, in [-10, 10) ms) that puts the first sample's time where the transition leaves the satellite on the
    20-ms grid of its clock (the fix's position and time for the geometry)."""
    out = {}
    week, tow = fix.gps_week, fix.gps_tow_s
    for p, e in edges.items():
        if p not in fix.prns or not np.isfinite(e):
            continue
        t_rx = tow + e                                           # the transition's arrival (true time)
        pos, _, clk, _, _ = sat_geometry(ephs, [p], week, t_rx, fix.ecef)
        corr, _ = corrections(fix.ecef, pos, t_rx, ephs.iono, settings)
        t_sv = t_rx - (np.linalg.norm(pos[0] - fix.ecef) + corr[0]) / C_LIGHT + clk[0] / C_LIGHT
        d = np.round(t_sv / BIT_S) * BIT_S - t_sv
        out[p] = float((d + BIT_S / 2) % BIT_S - BIT_S / 2)
    return out


def refine_time(fix: SnapshotFix, edges: dict, ephs: Ephemerides, settings: SnapshotSettings | None = None,
                tol_s: float = 1e-4, min_agree: int = 1, min_ratio: float = 10.0, noise_scale: float = 1.0):
    """The time of the first sample from the data-bit transitions ``edges`` {prn: time of a transition after
    the first sample (s)}, used jointly: the corrections (:func:`edge_offsets`, modulo 20 ms) are clustered
    within ``tol_s`` on the circle; the largest cluster wins when it holds at least ``min_agree`` satellites
    and more than all the others together (a single transition is enough when no other contradicts it).
    The multiple of 20 ms is the one nearest the fix's time; it is validated like an integer ambiguity: the
    chi-square of the next-nearest multiple must exceed the nearest's by ``min_ratio``, with the fix's time
    sigma times ``noise_scale`` (> 1 when its residuals exceed their noise model): (d2^2 - d1^2) / sigma^2,
    d1 and d2 the distances of the two multiples from the fix's time.  Returns (tow, agreeing PRNs, rejected
    PRNs) or None."""
    s = settings or SnapshotSettings()
    if not fix.ok:
        return None
    d = edge_offsets(fix, edges, ephs, s)
    if not d:
        return None
    prns = list(d)
    v = np.array([d[p] for p in prns])
    # circular distance (period 20 ms) between every pair
    diff = np.abs((v[:, None] - v[None, :] + BIT_S / 2) % BIT_S - BIT_S / 2)
    support = (diff <= tol_s).sum(axis=1)
    k = int(np.argmax(support))
    agree = diff[k] <= tol_s
    n = int(agree.sum())
    if n < min_agree or n <= len(v) - n:
        return None
    # the agreeing corrections unwrapped around the cluster's centre, averaged
    c = v[k] + ((v[agree] - v[k] + BIT_S / 2) % BIT_S - BIT_S / 2)
    shift = float(np.mean(c))
    shift = (shift + BIT_S / 2) % BIT_S - BIT_S / 2              # the multiple of 20 ms nearest the fix's time
    sig_t = fix.time_sigma_s * max(1.0, noise_scale)
    d1, d2 = abs(shift), BIT_S - abs(shift)
    if not np.isfinite(sig_t) or (d2 ** 2 - d1 ** 2) / max(sig_t, 1e-9) ** 2 < min_ratio:
        return None                                               # the 20-ms multiple is not determined
    return (fix.gps_tow_s + shift, [p for p, a in zip(prns, agree) if a],
            [p for p, a in zip(prns, agree) if not a])


def _noise_scale(fix: SnapshotFix, obs: list[SnapObs]) -> float:
    """The fix's residual RMS over the RMS of the noise model (sigma_m) of its satellites (1: as modelled)."""
    by = {o.prn: o for o in obs}
    used = [by[p] for p in fix.prns if p in by]
    if not used or not fix.residuals_m:
        return 1.0
    sig = sigma_m([o.cn0_dbhz for o in used], [o.length_ms for o in used])
    return float(np.sqrt(np.mean(np.square(fix.residuals_m)) / np.mean(sig ** 2)))


def with_bit_edges(fix: SnapshotFix, obs: list[SnapObs], edges: dict, ephs: Ephemerides,
                   settings: SnapshotSettings | None = None) -> SnapshotFix:
    """The fix again with the time from data-bit transitions (:func:`refine_time`) as a tight constraint, when
    they give one and the new fix passes the same tests; else ``fix`` unchanged.  The result's
    ``time_source`` says which."""
    s = settings or SnapshotSettings()
    r = refine_time(fix, edges, ephs, s, noise_scale=_noise_scale(fix, obs))
    if r is None:
        return fix
    tow, agree, _ = r
    new = coarse_time_fix(obs, ephs, fix.gps_week, tow, fix.ecef, replace(s, time_sigma_s=1e-6))
    if not new.ok:
        return fix
    new.prior, new.prior_ecef = fix.prior, fix.prior_ecef
    new.time_source = f"bit transitions of {len(agree)} satellites"
    new.time_sigma_s = 1e-6
    return new
