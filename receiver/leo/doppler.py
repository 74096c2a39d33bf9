"""Doppler measurement model for a static receiver and LEO satellites, and the measurement simulator.

Model (everything Earth-fixed, so a static receiver has zero velocity):

    f_d = -(f0 / c) * d|X_s - X|/dt + f_u + eps
        = -(f0 / c) * v_s . e + f_u + eps,          e = (X_s - X) / |X_s - X|

with X the receiver position, X_s / v_s the satellite Earth-fixed position / velocity (Earth rotation
is in v_s through the frame transformation), f_u the receiver frequency offset (oscillator error, which
may drift linearly) and eps white Gaussian noise.  The state of the positioning problem is
[x, y, z, f_u] (m, m, m, Hz).

Jacobian with respect to the receiver position:  d f_d / d X = (f0 / c) (v_s - (v_s . e) e) / rho,
and d f_d / d f_u = 1.

Measurement files (HDF5, written by :func:`save_measurements`):

    /time_utc           (T,)    ISO-8601 UTC strings
    /t_s                (T,)    seconds since the first epoch
    /sat_names          (N,)    satellite names from the TLE file
    /sat_pos_m          (T,N,3) Earth-fixed satellite positions
    /sat_vel_mps        (T,N,3) Earth-fixed satellite velocities
    /doppler_hz         (T,N)   measured Doppler, NaN where the satellite is not observed
    /elevation_deg      (T,N)   elevation seen from the true receiver position
    /truth/position_ecef_m (3,), /truth/freq_offset_hz (T,), /truth/doppler_hz (T,N)  (simulation only)
    attributes: carrier_hz, noise_sigma_hz, elevation_mask_deg, seed, tle_file, generator
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import UserError
from ..runfile.reader import open_h5
from ..gnss.geodesy import lla2ecef
from ..gnss.signals import C_LIGHT
from .constellation import Constellation, to_datetime64

IRIDIUM_CARRIER_HZ = 1626.270833e6


# --------------------------------------------------------------------------------------------------
# Model
# --------------------------------------------------------------------------------------------------
def range_rate(rx, sat_pos, sat_vel):
    """d|X_s - X|/dt for receiver positions rx (..., M, 3) or (3,) and satellites (K, 3): (M, K)."""
    rx = np.asarray(rx, float)
    d = sat_pos[None, :, :] - np.atleast_2d(rx)[:, None, :]
    rho = np.sqrt(np.einsum("mki,mki->mk", d, d))
    return np.einsum("ki,mki->mk", sat_vel, d) / rho


def doppler_model(states, sat_pos, sat_vel, f0):
    """Predicted Doppler (Hz) for states (M, 4) [x, y, z, f_u] (or (4,)) and K satellites -> (M, K)."""
    s = np.atleast_2d(np.asarray(states, float))
    return -(f0 / C_LIGHT) * range_rate(s[:, :3], sat_pos, sat_vel) + s[:, 3:4]


def doppler_jacobian(state, sat_pos, sat_vel, f0):
    """d f_d / d [x, y, z, f_u] at one state: (K, 4)."""
    x = np.asarray(state, float)
    d = sat_pos - x[None, :3]
    rho = np.linalg.norm(d, axis=1)
    e = d / rho[:, None]
    ve = np.einsum("ki,ki->k", sat_vel, e)
    J = np.empty((len(sat_pos), 4))
    J[:, :3] = (f0 / C_LIGHT) * (sat_vel - ve[:, None] * e) / rho[:, None]
    J[:, 3] = 1.0
    return J


def elevation_from(rx_ecef, sat_pos):
    """Elevation (rad) of satellites (..., 3) above the ellipsoid normal at rx (3,)."""
    from ..gnss.geodesy import ecef2lla
    lat, lon, _ = ecef2lla(np.asarray(rx_ecef, float))
    lat, lon = np.radians(lat), np.radians(lon)
    up = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    d = np.asarray(sat_pos, float) - rx_ecef
    return np.arcsin(np.clip(d @ up / np.linalg.norm(d, axis=-1), -1.0, 1.0))


# --------------------------------------------------------------------------------------------------
# Data container
# --------------------------------------------------------------------------------------------------
@dataclass
class DopplerData:
    """Doppler observations of several LEO satellites over a window of epochs."""
    time_utc: np.ndarray             # (T,) datetime64[us]
    t_s: np.ndarray                  # (T,)
    sat_names: list
    sat_pos: np.ndarray              # (T, N, 3) m
    sat_vel: np.ndarray              # (T, N, 3) m/s
    doppler_hz: np.ndarray           # (T, N), NaN = not observed
    carrier_hz: float
    elevation_deg: np.ndarray | None = None
    truth_ecef: np.ndarray | None = None
    truth_freq_offset_hz: np.ndarray | None = None
    truth_doppler_hz: np.ndarray | None = None
    attrs: dict = field(default_factory=dict)

    @property
    def n_epochs(self) -> int:
        """Number of epochs T."""
        return len(self.t_s)

    @property
    def observed(self) -> np.ndarray:
        """(T, N) mask of the satellites observed at each epoch (finite Doppler)."""
        return np.isfinite(self.doppler_hz)

    def epoch(self, k: int):
        """(sat_pos (K, 3), sat_vel (K, 3), doppler (K,)) of the satellites observed at epoch k."""
        m = np.isfinite(self.doppler_hz[k])
        return self.sat_pos[k, m], self.sat_vel[k, m], self.doppler_hz[k, m]

    def stacked(self):
        """All observations as flat arrays: (epoch index, sat_pos, sat_vel, doppler)."""
        k, j = np.nonzero(self.observed)
        return k, self.sat_pos[k, j], self.sat_vel[k, j], self.doppler_hz[k, j]

    def with_doppler(self, doppler_hz) -> "DopplerData":
        """A copy with the Doppler measurements (T, N; Hz, NaN = not observed) replaced."""
        return replace(self, doppler_hz=np.asarray(doppler_hz, float))

    def window(self, start_utc=None, stop_utc=None, step_s=None) -> "DopplerData":
        """Sub-window [start, stop] (inclusive), optionally decimated to step_s."""
        keep = np.ones(self.n_epochs, bool)
        if start_utc is not None:
            keep &= self.time_utc >= to_datetime64(start_utc)
        if stop_utc is not None:
            keep &= self.time_utc <= to_datetime64(stop_utc)
        idx = np.nonzero(keep)[0]
        if step_s is not None and len(idx):
            t = self.t_s[idx] - self.t_s[idx[0]]
            q = t / step_s
            idx = idx[np.abs(q - np.round(q)) < 1e-6]
        if len(idx) == 0:
            raise UserError("no measurement epochs in the requested window")

        def sub(a):
            return None if a is None else a[idx]
        return replace(self, time_utc=self.time_utc[idx], t_s=self.t_s[idx] - self.t_s[idx[0]],
                       sat_pos=self.sat_pos[idx], sat_vel=self.sat_vel[idx],
                       doppler_hz=self.doppler_hz[idx], elevation_deg=sub(self.elevation_deg),
                       truth_freq_offset_hz=sub(self.truth_freq_offset_hz),
                       truth_doppler_hz=sub(self.truth_doppler_hz))


# --------------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------------
def epoch_times(start_utc, stop_utc, step_s) -> np.ndarray:
    """UTC epochs from start to stop (inclusive when on the grid) every step_s seconds, datetime64[us]."""
    t0, t1 = to_datetime64(start_utc), to_datetime64(stop_utc)
    if t1 < t0:
        raise UserError("time.stop_utc must not be before time.start_utc")
    step_us = int(round(step_s * 1e6))
    n = int((t1 - t0).astype(np.int64) // step_us) + 1
    return t0 + np.arange(n) * np.timedelta64(step_us, "us")


def simulate(cfg, constellation: Constellation | None = None) -> DopplerData:
    """Simulate Doppler measurements for the scenario config (see receiver.leo.config)."""
    if constellation is None:
        constellation = Constellation.from_file(cfg.constellation.tle_file)
    times = epoch_times(cfg.time.start_utc, cfg.time.stop_utc, cfg.time.step_s)
    if len(times) > 200_000:
        raise UserError(f"{len(times)} epochs requested; reduce the span or raise time.step_s")
    rx = lla2ecef(cfg.receiver.lat_deg, cfg.receiver.lon_deg, cfg.receiver.height_m)
    pos, vel, bad = constellation.propagate_ecef(times, cfg.constellation.dut1_s)
    with np.errstate(invalid="ignore"):
        el = np.degrees(elevation_from(rx, pos))           # NaN where SGP4 failed
    t_s = (times - times[0]).astype(np.int64) / 1e6
    f0 = cfg.constellation.carrier_hz
    fu = cfg.receiver.freq_offset_hz + cfg.receiver.freq_drift_hz_per_s * t_s
    true = np.full(el.shape, np.nan)
    for k in range(len(times)):
        ok = ~bad[k]
        true[k, ok] = doppler_model(np.r_[rx, fu[k]], pos[k, ok], vel[k, ok], f0)[0]
    visible = np.isfinite(el) & (el >= cfg.measurement.elevation_mask_deg)
    if cfg.measurement.max_satellites is not None:
        for k in range(len(times)):
            idx = np.nonzero(visible[k])[0]
            if len(idx) > cfg.measurement.max_satellites:
                drop = idx[np.argsort(-el[k, idx])][cfg.measurement.max_satellites:]
                visible[k, drop] = False
    rng = np.random.default_rng(cfg.measurement.seed)
    noise = rng.normal(0.0, cfg.measurement.noise_sigma_hz, size=true.shape)
    meas = np.where(visible, true + noise, np.nan)
    return DopplerData(
        time_utc=times, t_s=t_s, sat_names=list(constellation.names), sat_pos=pos, sat_vel=vel,
        doppler_hz=meas, carrier_hz=f0, elevation_deg=el, truth_ecef=rx, truth_freq_offset_hz=fu,
        truth_doppler_hz=true,
        attrs=dict(noise_sigma_hz=cfg.measurement.noise_sigma_hz,
                   elevation_mask_deg=cfg.measurement.elevation_mask_deg,
                   seed=-1 if cfg.measurement.seed is None else cfg.measurement.seed,
                   tle_file=(os.path.abspath(cfg.constellation.tle_file) if cfg.constellation.tle_file
                             else "data/iridium_synthetic.tle (shipped)")))


# --------------------------------------------------------------------------------------------------
# HDF5 I/O
# --------------------------------------------------------------------------------------------------
def save_measurements(path, data: DopplerData):
    """Write the measurements to HDF5 atomically (temporary file renamed on success)."""
    import h5py
    path = os.fspath(path)
    tmp = path + ".part"
    try:
        with h5py.File(tmp, "w") as f:
            f.create_dataset("time_utc", data=np.array([str(t) for t in data.time_utc], dtype="S"))
            f["t_s"] = data.t_s
            f.create_dataset("sat_names", data=np.array(data.sat_names, dtype="S"))
            f["sat_pos_m"] = data.sat_pos
            f["sat_vel_mps"] = data.sat_vel
            f["doppler_hz"] = data.doppler_hz
            if data.elevation_deg is not None:
                f["elevation_deg"] = data.elevation_deg
            if data.truth_ecef is not None:
                g = f.create_group("truth")
                g["position_ecef_m"] = data.truth_ecef
                if data.truth_freq_offset_hz is not None:
                    g["freq_offset_hz"] = data.truth_freq_offset_hz
                if data.truth_doppler_hz is not None:
                    g["doppler_hz"] = data.truth_doppler_hz
            f.attrs["carrier_hz"] = data.carrier_hz
            f.attrs["generator"] = "gnssrx leo simulate"
            for k, v in data.attrs.items():
                f.attrs[k] = v
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def load_measurements(path) -> DopplerData:
    """Read a measurement file written by :func:`save_measurements` (with its truth when present); a missing or
    malformed file is a one-line UserError."""
    path = os.fspath(path)
    f = open_h5(path, "measurement file")
    with f:
        need = ("time_utc", "t_s", "sat_names", "sat_pos_m", "sat_vel_mps", "doppler_hz")
        missing = [k for k in need if k not in f]
        if missing:
            raise UserError(f"{path} is not a LEO measurement file (missing '{missing[0]}')")
        if "carrier_hz" not in f.attrs:
            raise UserError(f"{path} has no 'carrier_hz' attribute")
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in f["sat_names"][()]]
        d = DopplerData(
            time_utc=to_datetime64([t.decode() if isinstance(t, bytes) else t
                                    for t in f["time_utc"][()]]),
            t_s=f["t_s"][()], sat_names=names, sat_pos=f["sat_pos_m"][()],
            sat_vel=f["sat_vel_mps"][()], doppler_hz=f["doppler_hz"][()],
            carrier_hz=float(f.attrs["carrier_hz"]),
            elevation_deg=f["elevation_deg"][()] if "elevation_deg" in f else None,
            attrs={k: (v.item() if hasattr(v, "item") else v) for k, v in f.attrs.items()})
        if "truth" in f:
            g = f["truth"]
            d.truth_ecef = g["position_ecef_m"][()] if "position_ecef_m" in g else None
            d.truth_freq_offset_hz = g["freq_offset_hz"][()] if "freq_offset_hz" in g else None
            d.truth_doppler_hz = g["doppler_hz"][()] if "doppler_hz" in g else None
    T, N = d.doppler_hz.shape if d.doppler_hz.ndim == 2 else (None, None)
    if T is None or d.sat_pos.shape != (T, N, 3) or d.sat_vel.shape != (T, N, 3) or len(d.t_s) != T:
        raise UserError(f"{path}: inconsistent array shapes in the measurement file")
    return d
