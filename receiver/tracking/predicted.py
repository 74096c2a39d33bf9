"""Ephemeris-aided search of satellites in view that no channel tracks (the channel manager's predicted
acquisition; ``acquisition.predicted``).

After a fix, with a satellite's ephemeris, its code phase and Doppler at a sample ``s`` follow from a
satellite that a channel tracks in lock (the reference ``q``) and the geometry of the two seen from the fix:
the satellites' clock readings at transmission differ by

    T_p - T_q = -(tau_p - tau_q) + (dt_p - dt_q)

(tau the signal travel time, dt the satellite clock offset), so the receiver clock cancels, and the
reference's code phase gives T_q modulo 1 ms: code phase of p = ((cp_q / chip rate + T_p - T_q) mod 1 ms) x
chip rate.  Its Doppler is the reference's plus -(rho_dot_p - rho_dot_q) / lambda + the satellite clock
drifts' difference (rho_dot = line of sight . (satellite velocity - receiver velocity)).  The errors are the
fix's (tens of metres: a tenth of a chip; a few tenths of m/s: a few Hz), so the search window is a few
chips by a few Doppler bins, and its threshold (set by the false-alarm probability over those cells only)
lets much longer integrations find much weaker signals than the full-grid search
(:func:`receiver.acquisition.high_sensitivity.search_predicted`): a satellite low in the sky at 22-25 dB-Hz
that the periodic cold search never sees.  The atmosphere's difference (metres) is left out.
"""
from __future__ import annotations

import math

import numpy as np

from ..gnss.ephemeris import earth_rotation, sat_state
from ..gnss.signals import C_LIGHT


def _travel(eph, t_rx: float, rx: np.ndarray):
    """(travel time s, satellite clock offset s, line-of-sight range rate m/s for a receiver at rest, unit
    vector) of the signal received at GPS time t_rx at rx."""
    tau = 0.075
    for _ in range(3):
        pos, vel, clk, drift = sat_state(eph, t_rx - tau)
        p = earth_rotation(np.asarray(pos, float), tau)
        d = p - rx
        rng = float(np.linalg.norm(d))
        tau = rng / C_LIGHT
    u = d / rng
    return tau, float(clk), float(u @ earth_rotation(np.asarray(vel, float), tau)), u, float(drift)


def predict(eph_p, eph_q, t_rx: float, rx_ecef, rx_vel, cp_q: float, dop_q: float, signal):
    """(code phase chips, Doppler Hz, T_p - T_q s) of satellite p at the receive time t_rx (GPS s of week) from
    the reference q's code phase ``cp_q`` (chips) and Doppler ``dop_q`` (Hz) at the same instant (module
    doc)."""
    rx = np.asarray(rx_ecef, float)
    v = np.asarray(rx_vel, float) if np.all(np.isfinite(rx_vel)) else np.zeros(3)
    tau_p, clk_p, rr_p, u_p, dr_p = _travel(eph_p, t_rx, rx)
    tau_q, clk_q, rr_q, u_q, dr_q = _travel(eph_q, t_rx, rx)
    dt = -(tau_p - tau_q) + (clk_p - clk_q)
    period = signal.code_len / signal.chip_rate
    frac = math.fmod(cp_q / signal.chip_rate + dt, period) % period
    lam = C_LIGHT / signal.carrier_hz
    rdot_p = rr_p - float(u_p @ v)
    rdot_q = rr_q - float(u_q @ v)
    dop = dop_q - (rdot_p - rdot_q) / lam + (dr_p - dr_q) * signal.carrier_hz
    return frac * signal.chip_rate, dop, dt
