"""Vector-loop discriminators, in navigation units (metres, metres per second).

Both discriminators return "measured minus replica" pseudorange quantities, so that a measured pseudorange
(rate) is the replica's (the NCO's) plus the discriminator output.

Code (normalised early-minus-late envelope, E/L spacing d chips in total, E and L at +/- d/2):
    D = (|E| - |L|) / (|E| + |L|)
For a signal whose code phase leads the prompt replica by tau chips (|tau| < d/2, infinite bandwidth)
|E| = 1 - d/2 + tau and |L| = 1 - d/2 - tau, hence tau = (1 - d/2) D.  A leading code phase is a later
transmit time, i.e. a SHORTER pseudorange:
    Z_code = -(c / f_code) (1 - d/2) D        [m]          (measured - replica pseudorange)

BOC(1,1) (Galileo E1-C, the pilot's sine-phased 1.023-MHz sub-carrier): the autocorrelation's main peak is
R(tau) = 1 - 3 |tau| for |tau| <= 1/2 chip (then a negative side lobe down to -1/2 at |tau| = 1/2), three
times as steep as BPSK's.  With E and L at +/- d/2 (d < 2/3, so that both stay on the main peak's slopes)
|E| = 1 - 3 (d/2 - tau) and |L| = 1 - 3 (d/2 + tau), hence D = 6 tau / (2 - 3 d) and
    tau = (2 - 3 d) / 6 D,   Z_code = -(c / f_code) (2 - 3 d) / 6 D      [m]
linear while |tau| < d/2 (d = 0.2: gain 0.233 chip per unit of D against BPSK's 0.9).

Frequency (cross/dot of the two halves of one integration of length T):
    cross = I1 Q2 - I2 Q1,  dot = I1 I2 + Q1 Q2,  dphi = atan2(cross, dot)
The two half-integrations are centred T/2 apart, so a carrier frequency error df (signal minus NCO, Hz)
rotates the second half by dphi = 2 pi df T/2 = pi df T:  df = dphi / (pi T).  (The full-interval form
c/(2 pi f_L1 T) atan2 applies to consecutive integrations T apart; for halves the factor doubles.)
Unambiguous for |df| < 1/T.  A higher Doppler is a more negative pseudorange rate (rate = -lambda Doppler):
    Z_carr = -c / (pi f_L1 T) atan2(cross, dot)   [m/s]    (measured - replica pseudorange rate)
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...gnss.signals import C_LIGHT, CA_CHIP_RATE, L1_HZ

METRES_PER_CHIP = C_LIGHT / CA_CHIP_RATE


@njit(cache=True)
def code_disc_m(abs_e, abs_l, spacing_chips, chip_rate):
    """Z_code (m): measured minus replica pseudorange from |E|, |L| (E/L spacing in chips, total)."""
    s = abs_e + abs_l
    if s <= 0.0:
        return 0.0
    return -(C_LIGHT / chip_rate) * (1.0 - 0.5 * spacing_chips) * (abs_e - abs_l) / s


@njit(cache=True)
def code_disc_boc_m(abs_e, abs_l, spacing_chips, chip_rate):
    """Z_code (m) of a BOC(1,1) channel (Galileo E1-C) from |E|, |L| (E/L spacing in chips, total)."""
    s = abs_e + abs_l
    if s <= 0.0:
        return 0.0
    return -(C_LIGHT / chip_rate) * (2.0 - 3.0 * spacing_chips) / 6.0 * (abs_e - abs_l) / s


@njit(cache=True)
def freq_disc_hz(i1, q1, i2, q2, t_int):
    """Carrier frequency error (signal minus NCO, Hz) from the two halves of one integration of t_int s."""
    cross = i1 * q2 - i2 * q1
    dot = i1 * i2 + q1 * q2
    if cross == 0.0 and dot == 0.0:
        return 0.0
    return math.atan2(cross, dot) / (math.pi * t_int)


@njit(cache=True)
def freq_disc_mps(i1, q1, i2, q2, t_int, carrier_hz):
    """Z_carr (m/s): measured minus replica pseudorange rate."""
    return -(C_LIGHT / carrier_hz) * freq_disc_hz(i1, q1, i2, q2, t_int)


def _normalised_el(early, late):
    """(E - L) / (E + L) of envelope arrays, 0 where both are 0."""
    e = np.asarray(early, dtype=float)
    l = np.asarray(late, dtype=float)
    s = e + l
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(s > 0, (e - l) / np.where(s > 0, s, 1.0), 0.0)


def code_discriminator(early, late, spacing_chips=0.5, chip_rate=CA_CHIP_RATE):
    """numpy version of :func:`code_disc_m` (arrays allowed)."""
    return -(C_LIGHT / chip_rate) * (1.0 - 0.5 * spacing_chips) * _normalised_el(early, late)


def code_discriminator_boc(early, late, spacing_chips=0.2, chip_rate=CA_CHIP_RATE):
    """numpy version of :func:`code_disc_boc_m` (arrays allowed)."""
    return -(C_LIGHT / chip_rate) * (2.0 - 3.0 * spacing_chips) / 6.0 * _normalised_el(early, late)


def frequency_discriminator(i1, q1, i2, q2, t_int, carrier_hz=L1_HZ):
    """numpy version of :func:`freq_disc_mps` (arrays allowed)."""
    i1, q1, i2, q2 = (np.asarray(v, dtype=float) for v in (i1, q1, i2, q2))
    dphi = np.arctan2(i1 * q2 - i2 * q1, i1 * i2 + q1 * q2)
    return -(C_LIGHT / carrier_hz) * dphi / (np.pi * t_int)
