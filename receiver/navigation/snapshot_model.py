"""Coarse-time (snapshot) navigation, the shared model: the measurement (SnapObs), the result (SnapshotFix),
the options (SnapshotSettings), the ephemerides of a RINEX file and the satellites' geometry seen from a
receiver (positions at transmission, clocks, atmospheric corrections, DOPs, the pseudorange noise model).

The solver is receiver/navigation/snapshot.py, the Doppler solutions snapshot_doppler.py, the time from
data-bit transitions snapshot_time.py.  Pure numpy over receiver.gnss.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..gnss.atmosphere import klobuchar_delay_s, saastamoinen_m
from ..gnss.ephemeris import earth_rotation, sat_state, select
from ..gnss.geodesy import azel, ecef2lla, enu_matrix
from ..gnss.signals import CA_CHIP_RATE, C_LIGHT, L1_HZ

MS_M = C_LIGHT * 1e-3                  # one code period in metres
CHIP_M = C_LIGHT / CA_CHIP_RATE        # one chip in metres
LAMBDA = C_LIGHT / L1_HZ


@dataclass
class SnapObs:
    """One satellite's snapshot measurement at the first sample."""
    prn: int
    code_phase_chips: float           # code phase of the received signal at the first sample
    doppler_hz: float                 # carrier Doppler (> 0 approaching), including the oscillator's error
    cn0_dbhz: float = 45.0
    length_ms: float = 10.0           # snapshot length (the noise model of the weights)


@dataclass
class SnapshotFix:
    """A coarse-time snapshot fix (coarse_time_fix): ok and a message, the position (ECEF m and WGS-84
    lat/lon/height), the estimated GPS time of the first sample, velocity and clock drift, the satellites
    used with their residuals, DOPs and how the prior and the time were found."""
    ok: bool
    message: str = ""
    ecef: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    lat_deg: float = float("nan")
    lon_deg: float = float("nan")
    height_m: float = float("nan")
    gps_week: int = 0
    gps_tow_s: float = float("nan")    # true GPS time of the first sample (estimated)
    time_sigma_s: float = float("nan")
    time_correction_s: float = float("nan")     # estimated minus the coarse time given
    clock_bias_m: float = float("nan")          # range bias b (mod 1 ms meaningless in absolute terms)
    velocity_ecef: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    clock_drift_mps: float = float("nan")
    sigma_enu_m: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    dops: dict = field(default_factory=dict)
    prns: list = field(default_factory=list)
    residuals_m: list = field(default_factory=list)
    doppler_residuals_mps: list = field(default_factory=list)
    rejected: list = field(default_factory=list)
    residual_rms_m: float = float("nan")
    prior: str = ""                   # 'position', 'doppler', 'doppler (moving)'
    prior_ecef: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    height_aided: bool = False
    iterations: int = 0
    time_source: str = "code phases"  # or "bit transitions of N satellites" (snapshot_time.refine_time)

    @property
    def n_sats(self) -> int:
        """Number of satellites used in the fix."""
        return len(self.prns)


@dataclass
class SnapshotSettings:
    """Options of the snapshot solver (coarse_time_fix): corrections, elevation mask, residual and PDOP
    limits, altitude and time aiding, and the rejection limits of a fix."""
    troposphere: bool = True
    ionosphere: bool = True
    elevation_mask_deg: float = 5.0
    residual_threshold_m: float = 30.0
    max_norm_residual: float = 6.0        # Baarda's w-test: a residual beyond this many of its sigmas is excluded
    max_pdop: float = 20.0
    height_m: float | None = None     # altitude aiding: height constraint (m above the ellipsoid)
    height_sigma_m: float = 10.0
    time_sigma_s: float | None = None     # time aiding: the coarse time's 1-sigma as a constraint on dt
    max_move_m: float = 250e3             # a fix farther than this from its prior is rejected
    max_doppler_rms_mps: float = 15.0     # the Doppler-only prior needs its residual RMS below this
    max_time_shift_s: float = 120.0       # a fix whose time moved farther from the coarse time is rejected
    max_iter: int = 12


class Ephemerides:
    """The ephemerides of a RINEX file (dict prn -> list) with selection at a time."""

    def __init__(self, by_prn: dict, iono=None, max_age_s: float = 4 * 3600.0):
        self.by_prn, self.iono, self.max_age_s = by_prn, iono, max_age_s

    def get(self, prn: int, week: int, tow: float):
        """The ephemeris of ``prn`` valid at GPS week ``week``, seconds of week ``tow`` (the healthy one with
        the nearest toe within max_age_s), or None."""
        return select(self.by_prn.get(prn, ()), tow, week, self.max_age_s)

    def covered(self, week: int, tow: float) -> list:
        """PRNs with a healthy ephemeris valid at that time."""
        return [p for p in sorted(self.by_prn) if self.get(p, week, tow) is not None]


def corrections(x, sat_pos, tow, iono, settings):
    """Ionospheric + tropospheric delays (m) and elevations (rad) seen from x."""
    az, el = azel(x, sat_pos)
    lat, lon, h = ecef2lla(x)
    d = np.zeros(len(el))
    plausible = -1000.0 < float(h) < 20000.0           # far from the surface: no atmosphere model
    if plausible and settings.ionosphere and iono is not None:
        d += C_LIGHT * klobuchar_delay_s(iono, np.radians(lat), np.radians(lon), az, np.maximum(el, 0.0), tow)
    if plausible and settings.troposphere:
        d += saastamoinen_m(np.radians(lat), max(float(h), -500.0), np.maximum(el, np.radians(1.0)))
    return d, el


def sat_geometry(ephs: Ephemerides, prns, week: int, t_rx: float, x, t_travel=None):
    """Satellite positions (rotated into the ECEF frame at reception), velocities, clock bias (m) and
    drift (m/s) for a reception at true GPS time t_rx (s of ``week``) at position x.  Transmission at
    t_rx - range / c (iterated twice from 75 ms)."""
    n = len(prns)
    tau = np.full(n, 0.075) if t_travel is None else np.array(t_travel, float)
    if n == 0:
        return np.empty((0, 3)), np.empty((0, 3)), np.empty(0), np.empty(0), tau
    eph = [ephs.get(prn, week, t_rx) for prn in prns]     # one vectorised orbit evaluation for all satellites
    x = np.asarray(x, float)
    for _ in range(2):
        p, v, cb, cd = sat_state(eph, t_rx - tau)
        pr = earth_rotation(p, tau)
        tau = np.linalg.norm(pr - x, axis=-1) / C_LIGHT
    pos, vel = pr.reshape(n, 3), earth_rotation(v, tau).reshape(n, 3)
    clk, drift = C_LIGHT * np.asarray(cb, float).reshape(n), C_LIGHT * np.asarray(cd, float).reshape(n)
    return pos, vel, clk, drift, tau


def dops(h_geo, x, ncols_clock=1):
    """DOPs from the rows [-u, 1, (rate)] (no weights): GDOP, PDOP, HDOP, VDOP, TDOP in the local frame."""
    q = None
    if h_geo.shape[0] >= h_geo.shape[1]:
        try:
            q = np.linalg.inv(h_geo.T @ h_geo)
        except np.linalg.LinAlgError:
            q = None
    if q is None or not np.all(np.isfinite(q)) or np.any(np.diag(q) < 0):
        return {k: float("inf") for k in ("gdop", "pdop", "hdop", "vdop", "tdop")}
    lat, lon, _ = ecef2lla(x)
    r = enu_matrix(lat, lon)
    qe = r @ q[:3, :3] @ r.T
    return {"gdop": float(np.sqrt(np.trace(q[:4, :4]))), "pdop": float(np.sqrt(np.trace(q[:3, :3]))),
            "hdop": float(np.sqrt(qe[0, 0] + qe[1, 1])), "vdop": float(np.sqrt(qe[2, 2])),
            "tdop": float(np.sqrt(q[3, 3]) / C_LIGHT * 1e9) if ncols_clock else float("nan")}


def sigma_m(cn0_dbhz, length_ms=10.0):
    """Pseudorange noise model (m) for the weights: ~3 m at 45 dB-Hz over 10 ms (the narrow early-late
    code phase of receiver/snapshot/acquire.py on simulated snapshots at 4 MS/s), 1 / sqrt(C/N0 x length)."""
    return 3.0 * 10 ** ((45.0 - np.asarray(cn0_dbhz, float)) / 20.0) * np.sqrt(10.0 / np.asarray(length_ms, float))


def line_of_sight(ephs, prns, week, t, x, iono, settings):
    """The satellites' state at GPS time ``t`` (s of week) seen from ECEF ``x``: position, velocity (m, m/s),
    clock and clock drift (m, m/s), atmospheric corrections (m), elevations, ranges (m), unit vectors."""
    pos, vel, clk, cdrift, _ = sat_geometry(ephs, prns, week, t, x)
    corr, el = corrections(x, pos, t, iono, settings)
    los = pos - x
    rng = np.linalg.norm(los, axis=1)
    return pos, vel, clk, cdrift, corr, el, rng, los / rng[:, None]


def in_sky(ephs: Ephemerides, week: int, tow: float, x, mask_deg: float = 5.0) -> list[int]:
    """PRNs above ``mask_deg`` at position x and time (week, tow) according to the ephemerides."""
    prns = ephs.covered(week, tow)
    if not prns:
        return []
    pos, *_ = sat_geometry(ephs, prns, week, tow, np.asarray(x, float))
    _, el = azel(np.asarray(x, float), pos)
    return [p for p, e in zip(prns, el) if np.degrees(e) >= mask_deg]


