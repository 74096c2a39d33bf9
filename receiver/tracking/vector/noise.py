"""Measurement noise of the vector-loop discriminators from the channel's C/N0 (``vector.r_model: cn0``).

The papers' fixed R (1500 m^2 code, 900 (m/s)^2 frequency) is one number for every channel; the variance of
both discriminators depends on C/N0 and on the coherent integration T by orders of magnitude (a 27 dB-Hz
channel with 20-ms integration and a 45 dB-Hz one with 1 ms differ by ~10x in code and ~100x in
frequency variance).  With ``r_model: cn0`` each channel's R follows its own estimate:

Code (normalised early-minus-late envelope, total spacing d chips; thermal noise, infinite bandwidth):
    var_tau = d / (4 T C/N0) * (1 + 2 / ((2 - d) T C/N0))          [chips^2]
Frequency (cross/dot of the two halves of one integration, each T/2 long at SNR C/N0 T/2; the phase of
each half has a variance of 1 / (2 SNR), the difference twice that, plus the noise-times-noise term of
the cross and dot products, relatively 1 / SNR):
    var_dphi = 2 / (C/N0 T) * (1 + 2 / (C/N0 T))                    [rad^2]
    var_rate = (lambda / (pi T))^2 var_dphi                          [(m/s)^2]
BOC(1,1) (Galileo E1-C): the early-minus-late difference has three times BPSK's slope (6 against 2 per chip) and
its noise three times the variance (2 (1 - R(d)) = 6 d against 2 d), so var_tau is a third of the BPSK formula's
(the thermal term; code_factor 1/3). A channel that averages n epochs of T_int into one filter epoch has var / n.
The C/N0 used is the channel's estimate, never below ``vector.r_cn0.min_cn0_dbhz`` (an M2M4 estimate on noise
alone reads 20-30 dB-Hz: the floor keeps a channel without signal from being weighted like one with), and R never
falls below the floors ``vector.r_cn0.floor_code_m2`` / ``floor_carrier_m2s2`` (multipath, the unmodelled band
limit, the prediction error of a manoeuvring receiver over T). ``vector.r_cn0.scale``
multiplies both (1 = the formulas).
"""
from __future__ import annotations

import numpy as np

from ...gnss.signals import C_LIGHT, CA_CHIP_RATE, L1_HZ

LAMBDA = C_LIGHT / L1_HZ
METRES_PER_CHIP = C_LIGHT / CA_CHIP_RATE


def code_var_m2(cn0_dbhz, t_s, spacing_chips, metres_per_chip=METRES_PER_CHIP):
    """Variance (m^2) of the normalised E-L envelope code discriminator (one integration of t_s; chips of
    metres_per_chip, default L1 C/A's)."""
    q = 10.0 ** (np.asarray(cn0_dbhz, dtype=float) / 10.0) * t_s
    d = np.asarray(spacing_chips, dtype=float)
    return d / (4.0 * q) * (1.0 + 2.0 / ((2.0 - d) * q)) * np.asarray(metres_per_chip, dtype=float) ** 2


def rate_var_m2s2(cn0_dbhz, t_s, wavelength_m=LAMBDA):
    """Variance ((m/s)^2) of the cross/dot frequency discriminator of the two halves of one integration
    (carrier wavelength_m, default L1's)."""
    q = 10.0 ** (np.asarray(cn0_dbhz, dtype=float) / 10.0) * t_s
    return (np.asarray(wavelength_m, dtype=float) / (np.pi * t_s)) ** 2 * 2.0 / q * (1.0 + 2.0 / q)


def channel_r(cn0_dbhz, int_ms, grid_ms, spacing_chips, rc, metres_per_chip=METRES_PER_CHIP, wavelength_m=LAMBDA,
              code_factor=1.0):
    """(R code m^2, R rate (m/s)^2) of channels with C/N0 estimates cn0_dbhz integrating int_ms per
    correlation epoch in a filter epoch of grid_ms (a shorter integration is averaged grid/int times);
    rc: the vector.r_cn0 config section; metres_per_chip / wavelength_m: per channel, of its signal;
    code_factor: per channel, on the code variance (BOC(1,1): 1/3, see the module docstring)."""
    cn0 = np.maximum(np.asarray(cn0_dbhz, dtype=float), float(rc.min_cn0_dbhz))
    t = np.maximum(np.asarray(int_ms, dtype=float), 1.0) * 1e-3
    n = np.maximum(float(grid_ms) * 1e-3 / t, 1.0)
    s = float(rc.scale)
    r_code = np.maximum(s * np.asarray(code_factor, dtype=float) * code_var_m2(cn0, t, spacing_chips, metres_per_chip)
                        / n, float(rc.floor_code_m2))
    r_rate = np.maximum(s * rate_var_m2s2(cn0, t, wavelength_m) / n, float(rc.floor_carrier_m2s2))
    return r_code, r_rate
