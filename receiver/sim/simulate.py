"""Truth-tagged IF simulator (GPS L1 C/A, QZSS, BeiDou B1I): ``simulate(scenario, out_path)``.

Time conventions (see also docs/how-it-works/simulator.md and the truth file attributes)
-----------------------------------------------------------------------------------
* Receiver clock = sample counter: the receiver time of sample n is ``T = tow_s + n / fs`` (fs nominal).
  ``time_s`` in the truth file is ``n / fs``.
* Clock bias ``b = T - t`` (t true GPS time), drift ``y = db/dt`` = the oscillator's fractional frequency
  error: the true sample interval is ``1 / (fs (1 + y))`` and the local oscillator runs at
  ``(f_L1 - IF)(1 + y)``, so every carrier appears shifted by about ``-y f_L1``.
* A satellite signal received at true time t left the satellite at t - tau, where tau solves
  ``c tau = |r_rx(t) - R_z(omega_e tau) r_sat(t - tau)| + I + T`` (Sagnac by rotating the satellite into
  the ECEF frame at reception; I, T ionospheric and tropospheric group delays, metres).  The code it
  carries is the satellite clock time ``t - tau + dt_sv`` (dt_sv: af0.. + relativistic - TGD, as
  :func:`receiver.gnss.ephemeris.sat_state`).  The carrier arrives with the ionosphere ADVANCED:
  its phase is that of satellite time ``t - tau_c + dt_sv`` with ``c tau_c = rho - I + T``.
* Hence with D_code = b + tau - dt_sv and D_carr = b + tau_c - dt_sv (seconds, functions of T):
    pseudorange_m        = c D_code   (= c (receiver clock reading - satellite transmit time))
    code phase (chips)   = 1.023e6 (T - D_code) mod 1023
    carrier phase (cyc)  = -f_L1 D_carr + phi_scint / 2 pi      (the IF term IF*T excluded)
    sample phase         = IF (T - tow_s) + carrier phase       signal = amp code data exp(+j 2 pi phase)
    doppler_hz           = d(carrier phase)/dT  (observed frequency - nominal carrier - IF; >0 approaching)
  LNAV bits change where the satellite time of the received code crosses a multiple of 20 ms; subframe 1
  of each frame starts at a satellite TOW multiple of 30 s.
* C/N0: complex formats: C/N0 = A^2 fs / (2 sigma^2) (sigma: noise std per component);
  real formats: C/N0 = (A^2/2) / (2 sigma^2 / fs).

Generation streams in blocks (``output.block_s``): the propagation geometry is computed every 10 ms of
receiver time (on the truth rows) and carried to a 1 ms grid by cubic Hermite interpolation of the delays
and their exact rates; receiver clock, scintillation and visibility are evaluated on the 1 ms grid; the
numba kernel interpolates code phase, carrier phase and amplitude linearly between grid points.  The
truth file is appended block by block (buffered), so memory does not grow with the duration.

The simulator's time base, per-satellite state and block synthesis stay together: they share the truth
conventions above; the compiled synthesis is receiver.sim.kernel.
"""
from __future__ import annotations

import math
import os

import numpy as np
import yaml

from .. import __version__
from .. import interrupt
from ..errors import UserError
from ..suggest import did_you_mean
from ..estimation.interpolation import hermite
from ..safeio import TMP_SUFFIX, GuardedFile, OutputLock, check_output, write_error_message
from ..gnss.geodesy import ecef2lla
from ..source.io import Encoder, is_complex
from ..source.metadata import write_sigmf, write_tag
from ..gnss.atmosphere import klobuchar_delay_s, saastamoinen_m
from ..gnss.ephemeris import IonoUtc, earth_rotation, sat_state
from ..gnss.lnav import encode_subframes
from ..gnss.registry import get_signal
from ..gnss.satid import MIXED, sat_key, sat_label, split_key
from ..gnss.signals import CA_CHIP_RATE, C_LIGHT, L1_HZ, OMEGA_E, ca_code  # noqa: F401
from ..gnss.signals_bds import data_signs
from ..gnss.time import WEEK_S
from .blockage import Blockage
from .clock import ClockGenerator
from .constellation import load_constellation, quantize_iono
from .impairments import Impairments
from .kernel import quantize_fast, synth_block
from .scenario import clock_h, load_scenario, noise_sigma, resolve_path
from .scintillation import Scintillation
from .trajectory import CsvTrajectory, make_trajectory

GRID_S = 1e-3                     # truth / interpolation grid of the kernel (receiver time)
NODE_STEPS = 10                   # geometry computed every 10 grid steps (10 ms), Hermite in between
_FRAME_MS = 30000
_WEEK_FRAMES = int(WEEK_S) // 30


# ------------------------------------------------------------------------------------------ helpers
def output_paths(out_path) -> dict:
    """IF file, truth file (<stem>.truth.h5), receiver input fragment (<stem>.yaml) and SigMF metadata
    (<stem>.sigmf-meta; <stem> drops a .bin or .sigmf-data extension) and PocketSDR tag (<out>.tag: only for
    the formats PocketSDR names, receiver/source/metadata.py)."""
    out_path = os.fspath(out_path)
    stem = out_path
    for ext in (".bin", ".sigmf-data"):
        if out_path.endswith(ext):
            stem = out_path[:-len(ext)]
    return {"if": out_path, "truth": stem + ".truth.h5", "yaml": stem + ".yaml", "sigmf": stem + ".sigmf-meta",
            "tag": out_path + ".tag"}


def enu_components(vec, lat_deg, lon_deg):
    """ENU components of ECEF vectors (N,3) at per-row geodetic lat/lon (deg)."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    x, y, z = vec[..., 0], vec[..., 1], vec[..., 2]
    e = -so * x + co * y
    n = -sl * co * x - sl * so * y + cl * z
    u = cl * co * x + cl * so * y + sl * z
    return e, n, u


class _Overlap:
    """Wrap a stream ``take(n)`` so that consecutive blocks share their boundary grid point."""

    def __init__(self, take):
        self._take = take
        self._last = None

    def get(self, n_steps):
        if self._last is None:
            cur = self._take(n_steps + 1)
        else:
            new = self._take(n_steps)
            cur = tuple(np.concatenate(([l], v)) for l, v in zip(self._last, new))
        self._last = tuple(v[-1] for v in cur)
        return cur


class _NavBits:
    """LNAV bits of one satellite, frame by frame, as data signs per code period (ms) of satellite time."""

    def __init__(self, eph, iono, week, page18_every_frame, enabled):
        self.eph, self.iono, self.week = eph, iono, week
        self.page18 = page18_every_frame
        self.enabled = enabled
        self._frames = {}

    def _frame(self, f):
        bits = self._frames.get(f)
        if bits is None:
            wk = self.week + f // _WEEK_FRAMES
            tow = (f % _WEEK_FRAMES) * 30.0
            bits = encode_subframes(self.eph, self.iono, tow, wk, page18_every_frame=self.page18)
            self._frames[f] = bits
            for old in [k for k in self._frames if k < f - 1]:
                del self._frames[old]
        return bits

    def signs(self, ms_abs0, count):
        """+1/-1 (float32) for the code periods starting at satellite-time ms ms_abs0 .. +count-1."""
        if not self.enabled:
            return np.ones(count, np.float32)
        ms = ms_abs0 + np.arange(count, dtype=np.int64)
        frames = ms // _FRAME_MS
        out = np.empty(count, np.float32)
        for f in np.unique(frames):
            sel = frames == f
            bit = (ms[sel] - f * _FRAME_MS) // 20
            out[sel] = 1.0 - 2.0 * self._frame(int(f))[bit].astype(np.float32)
        return out


class _GalNav:
    """Galileo E1 symbols of one satellite per 4-ms code period of satellite time: the E1-B I/NAV symbols
    (receiver.gnss.gal_inav.InavStream) and the E1-C CS25 chips."""

    def __init__(self, content, gps_week, enabled):
        from ..gnss.gal_codes import cs25_signs
        from ..gnss.gal_inav import GST_WEEK_OFFSET, InavStream
        self.stream = InavStream(content, gps_week - GST_WEEK_OFFSET)     # GGTO zero: GST = GPS time
        self.enabled = enabled
        self.cs25 = cs25_signs()

    def signs(self, period0, count):
        """(E1-B symbols, E1-C secondary chips), +/-1 float32, for code periods period0 .. +count-1 of the
        week (4-ms periods since the start of the GPS week of the scenario)."""
        k = np.int64(period0) + np.arange(count, dtype=np.int64)
        sym = self.stream.signs(period0, count) if self.enabled else np.ones(count, np.float32)
        return sym, self.cs25[k % 25]


class _Cn0:
    """Nominal C/N0 (dB-Hz) per satellite and grid point."""

    def __init__(self, cfg):
        self.mode = cfg.mode
        self.dbhz, self.horizon = cfg.dbhz, cfg.horizon_dbhz
        try:
            self.per_prn = {int(k): float(v) for k, v in (cfg.per_prn or {}).items()}
        except (TypeError, ValueError):
            raise UserError("config key 'cn0.per_prn' must map PRN numbers to dB-Hz values") from None
        self.schedules = []
        for i, item in enumerate(cfg.schedule or []):
            key = f"cn0.schedule[{i}]"
            if not isinstance(item, dict) or "t_s" not in item or "dbhz" not in item:
                raise UserError(f"config key '{key}' must be a mapping with t_s and dbhz lists")
            unknown = set(item) - {"prns", "t_s", "dbhz"}
            if unknown:
                raise UserError(f"unknown config key '{key}.{sorted(unknown)[0]}'"
                                + did_you_mean(sorted(unknown)[0], ("prns", "t_s", "dbhz")))
            try:
                t = np.asarray(item["t_s"], dtype=float).ravel()
                v = np.asarray(item["dbhz"], dtype=float).ravel()
                prns = None if item.get("prns") is None else {int(p) for p in item["prns"]}
            except (TypeError, ValueError):
                raise UserError(f"config key '{key}' must hold numbers") from None
            if t.size == 0 or t.size != v.size or np.any(np.diff(t) < 0):
                raise UserError(f"config key '{key}': t_s and dbhz need the same (non-zero) length, "
                                "t_s increasing")
            self.schedules.append((prns, t, v))
        if self.mode == "schedule" and not self.schedules:
            raise UserError("config key 'cn0.schedule' must not be empty when cn0.mode is 'schedule'")

    def __call__(self, prn, t_rel, el_deg):
        if prn in self.per_prn:
            return np.full(t_rel.shape, self.per_prn[prn])
        if self.mode == "elevation":
            e = np.clip(el_deg, 0.0, 90.0) / 90.0
            return self.horizon + (self.dbhz - self.horizon) * e
        if self.mode == "schedule":
            for prns, t, v in self.schedules:
                if prns is None or prn in prns:
                    return np.interp(t_rel, t, v)
        return np.full(t_rel.shape, self.dbhz)


# ------------------------------------------------------------------------------------------ geometry
class SatelliteTrack:
    """Satellite position, velocity and clock at TRUE GPS times, by cubic Hermite interpolation.

    :func:`receiver.gnss.ephemeris.sat_state` is evaluated at nodes ``step`` apart (true time; position,
    velocity, clock offset and drift at each node) covering [t_lo, t_hi]; between nodes the cubic Hermite
    interpolant of (value, derivative) is accurate to far below a micrometre for GPS orbits at
    step = 0.1 s (error ~ step^4 n^4 a / 384).
    """

    def __init__(self, eph, t_lo, t_hi, step=0.1):
        k0, k1 = math.floor(t_lo / step) - 1, math.ceil(t_hi / step) + 1
        self.t_lo, self.t_hi = (k0 + 1) * step, (k1 - 1) * step
        self.tn = np.arange(k1 - k0 + 1) * step + k0 * step
        clk = np.zeros_like(self.tn)
        for _ in range(2):               # sat_state takes satellite-clock time: t_sv = t + clk(t)
            pos, vel, clk, drift = sat_state(eph, self.tn + clk)
        self.pos, self.vel, self.clk, self.drift = pos, vel, clk, drift

    def covers(self, t_lo, t_hi):
        """True when the interpolation nodes span the true times [t_lo, t_hi] (s)."""
        return self.t_lo <= t_lo and t_hi <= self.t_hi

    def __call__(self, t, rates=True):
        """(pos (n,3), vel (n,3), clk (n,), clk_dot (n,)) at true times t (vel/clk_dot None without rates)."""
        pos = hermite(self.tn, self.pos, self.vel, t)
        clk = hermite(self.tn, self.clk, self.drift, t)
        if not rates:
            return pos, None, clk, None
        return (pos, hermite(self.tn, self.pos, self.vel, t, True), clk,
                hermite(self.tn, self.clk, self.drift, t, True))


def satellite_geometry(track, t_rx, rx_pos, rx_vel, lat_deg, lon_deg, h_m, iono, tropo, iono_scale=1.0):
    """Propagation quantities of one satellite at reception times t_rx (true GPS s of week, array).

    track: a :class:`SatelliteTrack` (or any callable t_true -> pos, vel, clk, clk_dot).
    Returns a dict of arrays: rho (m, geometric incl. Sagnac), rho_dot (m/s, d rho/dt), iono_m, tropo_m
    (group delays, m), clk (s, satellite clock offset incl. relativity - TGD), clk_dot, el, az (rad),
    tau (s, total code propagation time).  iono_scale: the Klobuchar delay is the model's times this factor
    ((f_ref / f)^2 for a signal on another frequency than the model's reference).
    """
    n = t_rx.size
    tau = np.full(n, 0.075)
    atm = np.zeros(n)
    iono_m = np.zeros(n)
    tropo_m = np.zeros(n)
    lat_r, lon_r = np.radians(lat_deg), np.radians(lon_deg)
    for it in range(4):
        pos, vel, clk, clk_dot = track(t_rx - tau, rates=it == 3)
        rot = earth_rotation(pos, tau)
        los = rot - rx_pos
        rho = np.sqrt(np.einsum("ij,ij->i", los, los))
        if it == 1:
            e, nn, u = enu_components(los, lat_deg, lon_deg)
            el_c = np.maximum(np.arctan2(u, np.hypot(e, nn)), 0.0)
            az = np.arctan2(e, nn) % (2 * np.pi)
            if iono is not None:
                iono_m = C_LIGHT * klobuchar_delay_s(iono, lat_r, lon_r, az, el_c, t_rx)
                if iono_scale != 1.0:
                    iono_m = iono_m * iono_scale
            if tropo:
                tropo_m = saastamoinen_m(lat_r, h_m, el_c)
            atm = iono_m + tropo_m
        if it < 3:
            tau = (rho + atm) / C_LIGHT
    e, nn, u = enu_components(los, lat_deg, lon_deg)
    el = np.arctan2(u, np.hypot(e, nn))
    az = np.arctan2(e, nn) % (2 * np.pi)
    # range rate: d/dt |R(w tau) r_sat(t - tau) - r_rx(t)|, with d tau/dt = rho_dot / c
    uvec = los / rho[:, None]
    vrot = earth_rotation(vel, tau)
    sag = OMEGA_E * np.stack([rot[:, 1], -rot[:, 0], np.zeros(n)], axis=1)
    num = np.einsum("ij,ij->i", uvec, vrot - rx_vel)
    den = 1.0 - np.einsum("ij,ij->i", uvec, sag - vrot) / C_LIGHT
    return {"rho": rho, "rho_dot": num / den, "iono_m": iono_m, "tropo_m": tropo_m, "clk": clk,
            "clk_dot": clk_dot, "el": el, "az": az, "tau": tau}


def _scan_elevations(ephs, traj, t_ref_true, duration):
    """(t (s since the start), {prn: elevation (deg) at t}): coarse scan over the run, no light time."""
    step = 1.0 if duration <= 3600 else 10.0
    ts = np.append(np.arange(0.0, duration, step), duration)
    pos = traj.state(ts)[0]
    lat, lon, _ = ecef2lla(pos)
    out = {}
    for prn, eph in ephs.items():
        sp = sat_state(eph, t_ref_true + ts)[0]
        e, n, u = enu_components(earth_rotation(sp, 0.075) - pos, lat, lon)
        out[prn] = np.degrees(np.arctan2(u, np.hypot(e, n)))
    return ts, out


# ------------------------------------------------------------------------------------------ truth file
class _TruthWriter:
    """Truth HDF5 file; rows are buffered and appended every ``flush_rows`` rows (bounded memory)."""

    def __init__(self, path, attrs, prns, sat_attrs, flush_rows=6000, system="G"):
        import h5py
        self.flush_rows = flush_rows
        self.path = path
        self._buf = []
        self._rows = 0
        self._file = GuardedFile(path)      # a write error (disk full) is kept, not passed to HDF5
        self.f = h5py.File(self._file, "w")
        for k, v in attrs.items():
            self.f.attrs[k] = v
        self.rx = self.f.create_group("receiver")
        g = self.f.create_group("satellites")
        g.attrs["prns"] = np.array(sorted(prns), dtype=np.int32)
        self.sats = {}
        for prn in sorted(prns):
            sg = g.create_group(sat_label(prn, system))
            sg.attrs["prn"] = prn
            for k, v in sat_attrs[prn].items():
                sg.attrs[k] = v
            self.sats[prn] = sg

    @staticmethod
    def _append(group, name, data):
        """Append rows to a resizable, LZF-compressed dataset (created on first use)."""
        data = np.ascontiguousarray(data)
        if name not in group:
            group.create_dataset(name, data=data, maxshape=(None,) + data.shape[1:],
                                 chunks=(8192,) + data.shape[1:], compression="lzf", shuffle=True)
        else:
            ds = group[name]
            n = ds.shape[0]
            ds.resize(n + len(data), axis=0)
            ds[n:] = data

    def append(self, rx_rows: dict, sat_rows: dict):
        self._buf.append((rx_rows, sat_rows))
        self._rows += len(rx_rows["time_s"])
        if self._rows >= self.flush_rows:
            self.flush()

    def flush(self):
        if not self._buf:
            return
        for k in self._buf[0][0]:
            self._append(self.rx, k, np.concatenate([b[0][k] for b in self._buf]))
        for prn, grp in self.sats.items():
            for k in self._buf[0][1][prn]:
                self._append(grp, k, np.concatenate([b[1][prn][k] for b in self._buf]))
        self._buf, self._rows = [], 0
        self.check()

    def check(self):
        if self._file.error is not None:
            raise UserError(write_error_message("truth file", self.path, self._file.error))

    def close(self):
        if self.f is not None:
            try:
                self.flush()
            finally:
                self.f.close()
                self.f = None
                self._file.sync()
                self._file.close()
            self.check()


# ------------------------------------------------------------------------------------------ simulate
def _remove(paths):
    for p in paths:
        try:
            if os.path.exists(p):
                os.remove(p)
        except OSError:
            pass


def _files_read(scenario, sc) -> list:
    """The scenario file and every existing file a scenario value names (RINEX, trajectory CSV, ...)."""
    out = [os.fspath(scenario)] if isinstance(scenario, (str, os.PathLike)) else []

    def walk(v):
        if isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, list):
            for x in v:
                walk(x)
        elif isinstance(v, str) and v and ("/" in v or "." in v):
            try:
                p = resolve_path(v)
            except UserError:
                return
            if os.path.isfile(p):
                out.append(p)
    walk(sc.to_dict())
    return out


@interrupt.deferred()     # SIGINT/SIGTERM only set a flag, checked once per block
def simulate(scenario, out_path, overrides=(), progress=True) -> dict:
    """Simulate a scenario (YAML path, dict or Section) into ``out_path`` (+ truth and fragment files).

    Returns {"if": ..., "truth": ..., "yaml": ...}.  The three files are written under temporary names
    (``.partial``) and renamed together at the end; on any error or SIGINT/SIGTERM none is left behind.
    """
    sc = load_scenario(scenario, overrides)
    paths = output_paths(out_path)
    reads = _files_read(scenario, sc)
    if len(set(map(os.path.abspath, paths.values()))) < len(paths):
        raise UserError(f"output {paths['if']}: the IF, truth and receiver-input names must differ "
                        f"(use a .bin name)")
    if sc.l5.enabled:                    # + an L5 file on the same clock (sim/multiband.py)
        from .multiband import simulate_l1_l5
        return simulate_l1_l5(sc, out_path, reads, progress, _Simulator, _remove, output_paths, scale_ionosphere)
    sim = _Simulator(sc)                 # input errors surface here, before any file or directory is made
    scale_ionosphere(sim, sc.atmosphere.iono_scale)
    for kind, p in paths.items():        # missing directories are made (as for every command's outputs)
        check_output(p, reads, what={"if": "output", "truth": "truth file",
                                     "yaml": "receiver-input fragment", "sigmf": "SigMF metadata",
                                     "tag": "PocketSDR tag"}[kind])
    lock = OutputLock(paths["if"]).acquire()
    tmp = {k: v + TMP_SUFFIX for k, v in paths.items()}
    try:
        try:
            sim.run(paths, progress, tmp)
        except OSError as exc:
            raise UserError(write_error_message("output", paths["if"], exc)) from None
        interrupt.check()
        for k in ("truth", "yaml", "sigmf", "tag", "if"):  # the IF file last: its presence means complete
            if k == "tag" and not os.path.exists(tmp[k]):
                _remove([paths[k]])            # a format PocketSDR does not name: no (stale) tag
                continue
            os.replace(tmp[k], paths[k])
    except BaseException:
        _remove(tmp.values())
        raise
    finally:
        lock.release()
    return paths


def scale_ionosphere(sim, factor: float):
    """The true ionosphere of simulator ``sim`` is ``factor`` times its model (atmosphere.iono_scale; the
    broadcast parameters unchanged; exactly no change for 1.0)."""
    if factor != 1.0:
        sim.iono_scale = {p: v * factor for p, v in sim.iono_scale.items()}


# formats written by the numba quantiser in kernel.py; the others go through source.io.Encoder
_FAST_FORMATS = ("int8_iq", "int16_iq", "complex64", "float32_real", "int8_real", "int16_real")


class _Simulator:
    """Models of one scenario and the block loop (see the module docstring for the conventions)."""

    def __init__(self, sc):
        fe, tm = sc.frontend, sc.time
        self.sc = sc
        self.fs = fe.sample_rate_hz
        self.fmt = fe.format
        self.cplx = is_complex(self.fmt)
        self.if_hz = fe.if_hz
        self.sigma = noise_sigma(sc)
        self.noise = fe.noise
        self.duration = duration = tm.duration_s
        self.n_total = int(round(duration * self.fs))
        if self.n_total < 1:
            raise UserError("time.duration_s is shorter than one sample")
        self.spg = self.fs * GRID_S                               # samples per grid step
        self.n_grid = int(math.ceil(self.n_total / self.spg - 1e-9))
        self.decim = int(round(1000.0 / sc.output.truth_rate_hz))
        blk = max(int(round(sc.output.block_s / GRID_S)), 1)
        self.blk = max(self.decim, blk - blk % self.decim)         # blocks hold whole truth steps

        self.t_ref = t_ref = tm.tow_s                             # receiver clock reading of sample 0
        self.week = week = tm.gps_week
        self.b0 = sc.clock.bias_s
        t0_true = t_ref - self.b0
        self.m_ref = int(math.floor(t_ref * 1000.0 + 1e-6))
        self.r_ref = t_ref - self.m_ref * 1e-3                    # t_ref = m_ref ms + r_ref
        self.m_ref_gal = int(math.floor(t_ref / 4e-3 + 1e-6))     # Galileo: 4-ms code periods
        self.r_ref_gal = t_ref - self.m_ref_gal * 4e-3
        self.rng = np.random.default_rng(np.random.SeedSequence([tm.seed, 1]))

        self.traj = traj = make_trajectory(sc.receiver, lambda p: resolve_path(p, "trajectory CSV"), t0_true)
        if isinstance(traj, CsvTrajectory) and (traj.t_first > 1e-6 or traj.t_last < duration + 0.01):
            raise UserError(f"trajectory CSV covers {traj.t_first:.3f}..{traj.t_last:.3f} s but the run "
                            f"needs 0..{duration:.3f} s after the first sample")
        con, atm = sc.constellation, sc.atmosphere
        names = list(sc.signals or []) or [sc.signal]
        self.multi = len(names) > 1
        if self.multi and (sorted(names) != ["bds_b1i", "gps_l1ca"] or
                           con.source not in ("embedded", "rinex")):
            raise UserError("config key 'signals': a recording of several signals is [gps_l1ca, bds_b1i] (either "
                            "order) with constellation.source embedded or rinex (GPS; BeiDou: "
                            "constellation.bds_file)")
        if not self.multi and names[0] not in ("gps_l1ca", "bds_b1i", "gal_e1"):
            raise UserError(f"config key 'signals': unknown signal {names[0]!r}")
        self.signals = [get_signal(n) for n in names]
        bds_src = con.source in ("bds_nominal", "bds_rinex")
        if bds_src and names[0] != "bds_b1i":
            raise UserError(f"constellation.source '{con.source}' needs signal: bds_b1i")
        self.gal = names[0] == "gal_e1" and not self.multi
        if self.gal and (con.source != "embedded" or atm.ionosphere != "none"):
            raise UserError("signal gal_e1: the Galileo orbits come from constellation.gal_file (leave "
                            "constellation.source at embedded) and the ionosphere must be none (Galileo "
                            "broadcasts NeQuick-G, not the simulator's Klobuchar model): set atmosphere.ionosphere: "
                            "none")
        if self.gal:                            # Galileo orbits + I/NAV content (sim/gal_constellation.py)
            from .gal_constellation import gal_nominal_content, source_name as gal_source_name
            path = resolve_path(con.gal_file, "constellation file")
            self.gal_content = gal_nominal_content(path, week, t_ref)
            b_ephs, b_iono = {p: c.eph for p, c in self.gal_content.items()}, None
            cons = None
        elif bds_src:                           # BeiDou orbits + D1/D2 messages (sim/bds_constellation.py)
            from .bds_constellation import bds_nominal_ephemerides, bds_rinex_ephemerides, source_name
            if con.source == "bds_nominal":
                path = resolve_path(con.bds_file, "constellation file")
                b_ephs, b_iono = bds_nominal_ephemerides(path, week, t_ref)
            else:
                if not con.rinex:
                    raise UserError("constellation.source is 'bds_rinex' but constellation.rinex is empty")
                path = resolve_path(con.rinex, "RINEX file")
                b_ephs, b_iono = bds_rinex_ephemerides(path, week, t_ref + duration / 2.0)
            cons = None
        else:
            cons = load_constellation(con.source, resolve_path(con.rinex, "RINEX file") if con.rinex else None,
                                      resolve_path(con.nominal_file, "constellation file"), week, t_ref,
                                      t_ref + duration / 2.0,
                                      resolve_path(con.qzss_file, "constellation file") if con.qzss else None)
        if cons is None:
            from types import SimpleNamespace
            cons = SimpleNamespace(source=gal_source_name(path) if self.gal else source_name(path, con.source),
                                   ephemerides=b_ephs,
                                   iono_utc=quantize_iono(b_iono) if b_iono is not None else None)
        self.source = cons.source
        iono_b = cons.iono_utc
        if atm.klobuchar_alpha is not None or atm.klobuchar_beta is not None:
            base = iono_b or IonoUtc(wnt=week, dt_ls=18, tot=math.floor(t_ref / 4096.0) * 4096.0)
            iono_b = quantize_iono(IonoUtc(**{**base.__dict__,
                                              "alpha": tuple(atm.klobuchar_alpha or base.alpha),
                                              "beta": tuple(atm.klobuchar_beta or base.beta)}))
        if atm.ionosphere == "klobuchar" and iono_b is None:
            raise UserError("atmosphere.ionosphere is 'klobuchar' but the RINEX file has no ION ALPHA/BETA: "
                            "set atmosphere.klobuchar_alpha/beta or atmosphere.ionosphere: none")
        self.iono = iono_b if atm.ionosphere == "klobuchar" else None
        self.tropo = atm.troposphere == "saastamoinen"

        ephs = dict(cons.ephemerides)
        if self.multi:                          # + the nominal BeiDou constellation, keyed 400 + PRN
            from .bds_constellation import bds_nominal_ephemerides
            b_multi, _ = bds_nominal_ephemerides(resolve_path(con.bds_file, "constellation file"), week, t_ref)
            ephs.update({sat_key("C", p): e for p, e in b_multi.items()})
        if con.prns:
            missing = [p for p in con.prns if p not in ephs]
            if missing:
                raise UserError(f"constellation.prns: no ephemeris for PRN {missing[0]} in {cons.source}")
            ephs = {p: e for p, e in ephs.items() if p in con.prns}
        for p in con.exclude_prns:
            ephs.pop(p, None)
        self.mask = con.elevation_mask_deg
        el_scan = _scan_elevations(ephs, traj, t0_true, duration)
        self.prns = sorted(p for p, e in el_scan[1].items() if np.max(e) >= min(self.mask, 0.0) - 1.0)
        if not self.prns:
            raise UserError("no satellite rises above the horizon during the run")
        self.ephs = {p: ephs[p] for p in self.prns}

        self.clock = _Overlap(ClockGenerator(
            self.b0, sc.clock.freq_error_ppm * 1e-6, *clock_h(sc), GRID_S, duration,
            np.random.default_rng(np.random.SeedSequence([tm.seed, 2])),
            aging_per_s=sc.clock.aging_ppb_per_s * 1e-9, white_fm_corner_hz=sc.clock.white_fm_corner_hz).take)
        self.scint = self._scintillation(sc.scintillation, tm.seed)
        self.cn0 = _Cn0(sc.cn0)
        self.impair = Impairments(sc.impairments, self.fs, self.if_hz, self.sigma, self.cplx)
        self.blockage = Blockage(sc.blockage, self.prns, duration, tm.seed, el_scan, self.mask)
        # per satellite (key): its signal, the signal's PRN and IF (several signals: one LO, the first
        # signal at frontend.if_hz)
        first = self.signals[0]
        self.signal = first
        self.sat_sig = {}
        for p in self.prns:
            letter, q = split_key(p) if self.multi else (first.system, p)
            sig = next(g for g in self.signals if g.system == ("C" if letter == "C" else "G")) if self.multi \
                else first
            self.sat_sig[p] = (sig, q, self.if_hz + (sig.carrier_hz - first.carrier_hz))
        for sig in self.signals[1:]:
            f_if = self.if_hz + (sig.carrier_hz - first.carrier_hz)
            if not (abs(f_if) < self.fs / 2 and (self.cplx or f_if > 0)):
                raise UserError(f"signal {sig.name} would sit at IF {f_if / 1e6:+.3f} MHz (frontend.if_hz + its "
                                f"carrier - {first.name}'s), outside the {self.fs / 1e6:g} MS/s band")
        # several signals: the one Klobuchar model (the GPS set, L1 delays) is the ionosphere of all; a signal
        # on another carrier is delayed (f_L1 / f)^2 times as much (B1I: +1.84 %).  One signal: the model's
        # delay as it is (a BeiDou set gives B1I delays, BDS-SIS-ICD-B1I)
        self.iono_scale = {p: (first.carrier_hz / self.sat_sig[p][0].carrier_hz) ** 2 if self.multi else 1.0
                           for p in self.prns}
        self.nav = {}
        for p in self.prns:
            sig, q, _ = self.sat_sig[p]
            if self.gal:
                self.nav[p] = _GalNav(self.gal_content[p], week, sc.navigation.data)
            elif bds_src or (self.multi and sig.system == "C"):
                from ..gnss.bds_nav import BdsNavBits
                from ..gnss.signals_bds import is_geo
                self.nav[p] = BdsNavBits(self.ephs[p], iono_b, week, is_geo(q), sc.navigation.data)
            else:
                self.nav[p] = _NavBits(self.ephs[p], iono_b, week, sc.navigation.page18_every_frame,
                                       sc.navigation.data)
        self.codes = {p: self.sat_sig[p][0].code(self.sat_sig[p][1]) for p in self.prns}
        if self.gal:                            # E1-B and E1-C rows: BOC(1,1) half-chips, each half the power
            from ..gnss.gal_codes import boc11, e1b_code, e1c_code
            k = np.float32(1.0 / math.sqrt(2.0))
            self.gal_codes = {p: (k * boc11(e1b_code(p)), -k * boc11(e1c_code(p))) for p in self.prns}
        self.amp_k = (2.0 if self.cplx else 4.0) * self.sigma ** 2 / self.fs     # A^2 = amp_k * C/N0
        self.node_step = math.gcd(NODE_STEPS, self.decim)   # geometry nodes (grid steps), on truth rows
        self._tracks = {}

    def _scintillation(self, sci, seed):
        if not sci.enabled:
            return {}
        per = {}
        for k, v in (sci.per_prn or {}).items():
            if not isinstance(v, dict) or set(v) - {"s4", "sigma_phi_rad", "tau0_s"}:
                raise UserError(f"config key 'scintillation.per_prn.{k}' must be a mapping of "
                                "s4, sigma_phi_rad, tau0_s")
            per[int(k)] = v
        out = {}
        for prn in self.prns:
            if sci.prns and prn not in sci.prns and prn not in per:
                continue
            o = per.get(prn, {})
            try:
                s4, sp, t0 = (float(o.get("s4", sci.s4)), float(o.get("sigma_phi_rad", sci.sigma_phi_rad)),
                              float(o.get("tau0_s", sci.tau0_s)))
            except (TypeError, ValueError):
                s4 = -1.0
            if not (0.0 <= s4 < 1.0 and sp >= 0.0 and t0 > 0.0):
                raise UserError(f"config key 'scintillation.per_prn.{prn}': need 0 <= s4 < 1, "
                                "sigma_phi_rad >= 0, tau0_s > 0")
            rng = np.random.default_rng(np.random.SeedSequence([seed, 3, prn]))
            out[prn] = _Overlap(Scintillation(s4, sp, t0, GRID_S, rng, sci.window_s).take)
        return out

    def attrs(self) -> dict:
        sc = self.sc
        return {
            "scenario": sc.to_yaml(), "gnssrx_version": __version__, "seed": sc.time.seed,
            "gps_week": self.week, "start_gps_tow_s": self.t_ref, "sample_rate_hz": self.fs,
            "if_hz": self.if_hz, "format": self.fmt, "duration_s": self.duration, "n_samples": self.n_total,
            "noise_sigma": self.sigma, "ephemeris_source": self.source,
            "signals": ",".join(g.name for g in self.signals), "system": MIXED if self.multi else self.signal.system,
            "truth_rate_hz": 1000.0 / self.decim,
            "conventions": (
                "time_s = sample_index / sample_rate_hz; receiver clock reading = start_gps_tow_s + time_s; "
                "clock_bias_m = c (clock reading - gps_tow); gps_tow = true GPS time (s since the start of "
                "gps_week); pseudorange_m = c (clock reading - satellite transmit time); doppler_hz = "
                "d(carrier_phase_cycles)/d(time_s), > 0 approaching, includes the oscillator error; "
                "signal = A code data exp(+j 2 pi (if_hz time_s + carrier_phase_cycles))"),
        }

    def run(self, paths, progress, tmp=None):
        """Write the files under the names ``tmp`` (default: ``paths``); the receiver input fragment
        names the final ones."""
        tmp = tmp or paths
        sat_attrs = {p: {"toe": e.toe, "iode": e.iode, "week": e.week} for p, e in self.ephs.items()}
        self.writer = None
        self.fh = open(tmp["if"], "wb")
        self.writer = _TruthWriter(tmp["truth"], self.attrs(), self.prns, sat_attrs,
                                   system=MIXED if self.multi else self.signal.system)
        fe = self.sc.frontend
        self.encoder = None if self.fmt in _FAST_FORMATS else Encoder(self.fmt, 1.0, fe.bit_order, fe.encoding)
        bar = None
        try:
            self.blockage.write(self.writer.f)
            if progress:
                from tqdm import tqdm
                bar = tqdm(total=round(self.duration, 3), unit="s", desc="simulate", leave=False,
                           bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s [{elapsed}<{remaining}]")
            g0 = 0
            while g0 < self.n_grid:
                interrupt.check()                   # SIGINT/SIGTERM: stop between blocks
                n = min(self.blk, self.n_grid - g0)
                self._block(g0, n)
                if bar is not None:
                    bar.update(round(n * GRID_S, 3))
                g0 += n
            if self.encoder is not None:
                self.fh.write(self.encoder.flush())
        finally:
            self.fh.close()
            if self.writer is not None:
                self.writer.close()
            if bar is not None:
                bar.close()
        packed = {"bit_order": fe.bit_order, "encoding": fe.encoding} if "packed" in self.fmt else {}
        frag = {"input": {"path": os.path.basename(paths["if"]), "format": self.fmt, **packed,
                          "sample_rate_hz": self.fs, "if_hz": self.if_hz, "start_gps_week": self.week,
                          "start_gps_tow_s": self.t_ref}}
        if self.multi:
            frag = {"signals": [g.name for g in self.signals], **frag}
        elif self.signal.name != "gps_l1ca":            # the run config's default signal is GPS L1 C/A
            frag = {"signal": self.signal.name, **frag}
        write_sigmf(tmp["if"], self.fmt, self.fs, self.if_hz, self.signal.carrier_hz, self.week, self.t_ref,
                    description="gnssrx simulator output; truth: " + os.path.basename(paths["truth"]),
                    bit_order=fe.bit_order, encoding=fe.encoding, version=__version__, meta=tmp["sigmf"])
        write_tag(tmp["if"], self.fmt, self.fs, self.if_hz, self.signal.carrier_hz, self.week, self.t_ref,
                  tag=tmp["tag"])
        with open(tmp["yaml"], "w") as f:
            f.write(f"# gnssrx simulator output (gnssrx {__version__}): receiver input section for "
                    f"{os.path.basename(paths['if'])}\n# truth: {os.path.basename(paths['truth'])}\n")
            yaml.safe_dump(frag, f, sort_keys=False)

    def _visibility(self, t_rel, el_deg):
        return self.blockage.visibility(t_rel, el_deg, self.mask)

    def _track(self, prn, t_lo, t_hi):
        tr = self._tracks.get(prn)
        if tr is None or not tr.covers(t_lo, t_hi):
            tr = self._tracks[prn] = SatelliteTrack(self.ephs[prn], t_lo, max(t_hi, t_lo + 30.0))
        return tr

    def _block(self, g0, n):
        """Grid steps g0 .. g0+n-1 (grid points g0 .. g0+n): append the samples and the truth rows.

        The propagation geometry is computed at nodes every ``node_step`` grid points (and the last
        point); the smooth parts of the code and carrier delays are carried to every grid point by cubic
        Hermite interpolation (values and exact rates at the nodes), the receiver clock, scintillation and
        visibility are evaluated at every grid point.
        """
        c = C_LIGHT
        g = g0 + np.arange(n + 1)
        t_rel = g * GRID_S                                   # receiver time since sample 0
        bias, y = self.clock.get(n)                          # clock bias (s), drift (s/s)
        t_true_rel = t_rel - (bias - self.b0)                # true time since the first sample
        t_abs = self.t_ref + t_rel - bias                    # true GPS time (s of the scenario week)
        nodes = np.unique(np.append(np.arange(0, n + 1, self.node_step), n))
        tn_rel, tn_true, tn_abs, yn = t_rel[nodes], t_true_rel[nodes], t_abs[nodes], y[nodes]
        rx_pos, rx_vel, rx_acc = self.traj.state(tn_true)
        lat, lon, hgt = ecef2lla(rx_pos)
        geo = {}
        for p in self.prns:
            track = self._track(p, tn_abs[0] - 0.2, tn_abs[-1])
            geo[p] = satellite_geometry(track, tn_abs, rx_pos, rx_vel, lat, lon, hgt, self.iono, self.tropo,
                                        self.iono_scale[p])
        el_n = np.array([np.degrees(geo[p]["el"]) for p in self.prns])
        el_deg = np.array([np.interp(t_rel, tn_rel, e) for e in el_n]) if nodes.size < n + 1 else el_n
        visible = self._visibility(t_rel, el_deg)

        # samples of this block: grid step j covers samples seg_start[j] .. seg_start[j+1]-1
        first = int(math.ceil(g0 * self.spg - 1e-9))
        seg_pos = g * self.spg
        seg_abs = np.minimum(np.ceil(seg_pos - 1e-9).astype(np.int64), self.n_total)
        seg_x0 = seg_abs[:-1] - seg_pos[:-1]
        seg_start = seg_abs - first
        n_samp = int(seg_start[-1])
        rows = np.nonzero((g[nodes] % self.decim == 0) & (nodes < n) & (tn_rel < self.duration - 1e-12))[0]
        if nodes.size > 1:
            dtn = np.gradient(tn_true)

            def rate(v):                                    # d/dt (true time) at the nodes
                return np.gradient(v) / dtn
        else:
            def rate(v):
                return np.zeros_like(v)

        sig, truth_sat = [], {}
        con_src = self.sc.constellation.source
        for i, p in enumerate(self.prns):
            q = geo[p]
            i_dot, t_dot = rate(q["iono_m"]), rate(q["tropo_m"])
            tau_dot = (q["rho_dot"] + i_dot + t_dot) / c
            clk_rate = q["clk_dot"] * (1.0 - tau_dot)       # d dt_sv(t - tau) / dt
            # delays without the receiver clock, and their rates w.r.t. receiver time (dt/dT = 1/(1+y))
            gc = (q["rho"] + q["iono_m"] + q["tropo_m"]) / c - q["clk"]
            gp = (q["rho"] - q["iono_m"] + q["tropo_m"]) / c - q["clk"]
            gc_dot = (tau_dot - clk_rate) / (1.0 + yn)
            gp_dot = ((q["rho_dot"] - i_dot + t_dot) / c - clk_rate) / (1.0 + yn)
            if nodes.size < n + 1:
                d_code = bias + hermite(tn_rel, gc, gc_dot, t_rel)
                d_carr = bias + hermite(tn_rel, gp, gp_dot, t_rel)
            else:
                d_code, d_carr = bias + gc, bias + gp
            sig_p, _, if_p = self.sat_sig[p]
            chips_total = (self.r_ref + t_rel - d_code) * sig_p.chip_rate  # since ms m_ref, sat. time
            f_carr, CODE_N = sig_p.carrier_hz, float(sig_p.code_len)
            if p in self.scint:
                s_amp, s_ph = self.scint[p].get(n)
            else:
                s_amp, s_ph = np.ones(n + 1), np.zeros(n + 1)
            cn0_db = self.cn0(p, t_rel, el_deg[i])
            amp = np.sqrt(self.amp_k * 10.0 ** (cn0_db / 10.0)) * s_amp * visible[i]
            carr = -f_carr * d_carr + s_ph / (2.0 * np.pi)
            if self.gal:                                     # chips since a 4-ms period boundary
                chips_total = (self.r_ref_gal + t_rel - d_code) * sig_p.chip_rate
            if n_samp > 0 and np.any(amp > 0) and self.gal:
                per0 = int(math.floor(chips_total[0] / CODE_N))
                chips_blk = 2.0 * (chips_total - per0 * CODE_N)          # BOC(1,1) half-chips
                count = int(chips_blk[-1] // (2 * CODE_N)) + 2
                sym_b, sec_c = self.nav[p].signs(self.m_ref_gal + per0, count)
                ph = if_p * t_rel + carr
                a32 = amp.astype(np.float32)
                sig.append((p, chips_blk, ph, a32, sym_b, self.gal_codes[p][0]))
                sig.append((p, chips_blk, ph, a32, sec_c, self.gal_codes[p][1]))
            elif n_samp > 0 and np.any(amp > 0):
                ms0 = int(math.floor(chips_total[0] / CODE_N))
                chips_blk = chips_total - ms0 * CODE_N
                if sig_p.name == "bds_b1i" and not self.multi and con_src not in ("bds_nominal", "bds_rinex"):
                    dsign = data_signs(p, self.m_ref + ms0, int(chips_blk[-1] // CODE_N) + 2,
                                       self.sc.time.seed, self.sc.navigation.data)
                else:
                    dsign = self.nav[p].signs(self.m_ref + ms0, int(chips_blk[-1] // CODE_N) + 2)
                sig.append((p, chips_blk, if_p * t_rel + carr, amp.astype(np.float32), dsign, self.codes[p]))
            if rows.size:
                r = rows
                gr = nodes[r]                                # grid indices of the truth rows
                ph_rate = np.gradient(s_ph, GRID_S)[gr] if n >= 1 else np.zeros(r.size)
                doppler = -f_carr * (y[gr] / (1.0 + y[gr]) + gp_dot[r]) + ph_rate / (2.0 * np.pi)
                truth_sat[p] = {
                    "time_s": t_rel[gr], "gps_tow": t_abs[gr], "pseudorange_m": c * d_code[gr],
                    "range_m": q["rho"][r], "range_rate_mps": q["rho_dot"][r], "doppler_hz": doppler,
                    "carrier_phase_cycles": carr[gr], "code_phase_chips": np.mod(chips_total[gr], CODE_N),
                    "cn0_dbhz": cn0_db[gr], "visible": visible[i][gr], "scint_amplitude": s_amp[gr],
                    "scint_phase_rad": s_ph[gr], "elevation_deg": el_n[i][r],
                    "azimuth_deg": np.degrees(q["az"][r]), "iono_delay_m": q["iono_m"][r],
                    "tropo_delay_m": q["tropo_m"][r], "sat_clock_s": q["clk"][r]}

        if n_samp > 0:
            out = np.zeros(n_samp, np.complex64)
            for code_len in sorted({r[5].size for r in sig}):               # (one call per code length)
                grp = [r for r in sig if r[5].size == code_len]
                n_ms = max(r[4].size for r in grp)
                dsign = np.ones((len(grp), n_ms), np.float32)
                for k, r in enumerate(grp):
                    dsign[k, :r[4].size] = r[4]
                phase = np.stack([r[2] for r in grp])
                synth_block(out, seg_start, seg_x0, 1.0 / self.spg,
                            np.stack([r[5] for r in grp]), np.stack([r[1] for r in grp]),
                            np.mod(phase, 1.0), np.diff(phase, axis=1), np.stack([r[3] for r in grp]), dsign)
            if self.noise:
                view = out.view(np.float32)
                if self.cplx:
                    view += np.float32(self.sigma) * self.rng.standard_normal(view.size, dtype=np.float32)
                else:
                    view[0::2] += np.float32(self.sigma) * self.rng.standard_normal(n_samp, dtype=np.float32)
            out = self.impair.apply(out, first)          # front-end impairments (sim/impairments.py)
            if self.encoder is None:
                quantize_fast(out, self.fmt).tofile(self.fh)
            else:
                self.fh.write(self.encoder.encode(out))

        if rows.size:
            gr = nodes[rows]
            self.writer.append({"time_s": t_rel[gr], "gps_tow": t_abs[gr], "ecef": rx_pos[rows],
                                "velocity_ecef": rx_vel[rows], "accel_ecef": rx_acc[rows],
                                "clock_bias_m": c * bias[gr], "clock_drift_mps": c * y[gr]}, truth_sat)
