"""Snapshot positioning of a recording: open the input through the receiver's input stages, cut one or
many snapshots, acquire them (:mod:`.acquire`) and solve each with the coarse-time solver
(receiver/navigation/snapshot.py).

Priors per snapshot: the user's position (``position``) when given, else the previous snapshot's fix
(``every``), else a Doppler-only solution.  Time: ``time`` (ISO 8601 UTC or GPS WEEK:TOW), else the
input metadata's time hint (SigMF core:datetime, PocketSDR .tag, input.start_gps_week / _tow_s).
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import UserError
from ..gnss.geodesy import lla2ecef
from ..gnss.rinex import read_rinex_nav
from ..gnss.time import GPS_EPOCH, WEEK_S, leap_seconds_at, normalize_week_tow, gps_datetime
from ..navigation.snapshot import Ephemerides, SnapObs, SnapshotSettings, coarse_time_fix, in_sky
from ..navigation.snapshot_time import with_bit_edges
from .acquire import snapshot_acquire

#: the longest snapshot used by default (ms) and the shortest accepted
DEFAULT_LENGTH_MS = 40
MIN_LENGTH_MS = 1


@dataclass
class SnapshotResult:
    """One snapshot of ``gnssrx snapshot``: where it is in the file (s), its length (ms), the coarse time
    given, its fix (SnapshotFix) and the PRNs detected, searched and missed."""
    index: int
    offset_s: float                  # first sample of the snapshot, seconds into the file
    length_ms: int
    coarse_week: int
    coarse_tow_s: float
    fix: object                      # receiver.navigation.snapshot.SnapshotFix
    detected: list = field(default_factory=list)     # SnapAcq of the detections
    searched: list = field(default_factory=list)
    missed: list = field(default_factory=list)       # in the sky (ephemeris, fix) but not found

    def as_dict(self) -> dict:
        """The result as a JSON-ready dict (the fix's position, time, residuals ... when it is ok)."""
        f = self.fix
        d = {"index": self.index, "offset_s": self.offset_s, "length_ms": self.length_ms, "ok": bool(f.ok),
             "message": f.message, "coarse_gps_week": self.coarse_week, "coarse_gps_tow_s": self.coarse_tow_s,
             "detected": [a.prn for a in self.detected], "missed": list(self.missed)}
        if f.ok:
            d.update({"ecef_m": [float(v) for v in f.ecef], "lat_deg": f.lat_deg, "lon_deg": f.lon_deg,
                      "height_m": f.height_m, "gps_week": f.gps_week, "gps_tow_s": f.gps_tow_s,
                      "utc": utc_text(f.gps_week, f.gps_tow_s),
                      "time_sigma_s": f.time_sigma_s, "time_correction_s": f.time_correction_s,
                      "time_source": f.time_source,
                      "sigma_enu_m": [float(v) for v in f.sigma_enu_m],
                      "velocity_ecef_mps": [float(v) for v in f.velocity_ecef],
                      "clock_drift_mps": f.clock_drift_mps, "n_sats": f.n_sats, "prns": f.prns,
                      "residuals_m": f.residuals_m, "residual_rms_m": f.residual_rms_m,
                      "doppler_residuals_mps": f.doppler_residuals_mps, "rejected": f.rejected,
                      "dops": f.dops, "prior": f.prior, "height_aided": f.height_aided,
                      "cn0_dbhz": {a.prn: a.cn0_dbhz for a in self.detected}})
        else:
            d.update({"n_sats": 0})
        return d


def utc_text(week: int, tow: float) -> str:
    """GPS week and seconds of week as a UTC ISO 8601 text with milliseconds (``...Z``)."""
    g = gps_datetime(week, tow)
    return (g - _dt.timedelta(seconds=leap_seconds_at(g))).isoformat(timespec="milliseconds") + "Z"


def parse_time(text: str) -> tuple[int, float, bool]:
    """``WEEK:TOW`` (GPS) or an ISO 8601 time (UTC unless it has an offset; a date alone means its noon)
    -> (week, tow, date_only)."""
    text = text.strip()
    if ":" in text and "-" not in text and "T" not in text.upper():
        try:
            w, t = text.split(":")
            week, tow = int(w), float(t)
        except ValueError:
            raise UserError(f"--time {text!r}: expected WEEK:TOW (GPS week and seconds of week) or an "
                            "ISO 8601 UTC time such as 2022-03-27T11:32:04Z") from None
        if not 0 <= tow < WEEK_S or week < 0:
            raise UserError(f"--time {text!r}: seconds of week must be in [0, 604800)")
        return week, tow, False
    date_only = len(text) == 10
    try:
        t = _dt.datetime.fromisoformat(text.replace("Z", "+00:00").replace("z", "+00:00"))
    except ValueError:
        raise UserError(f"--time {text!r} is neither WEEK:TOW nor an ISO 8601 time "
                        "(e.g. 2022-03-27T11:32:04Z)") from None
    if date_only:
        t = t + _dt.timedelta(hours=12)
    if t.tzinfo is not None:
        t = t.astimezone(_dt.timezone.utc).replace(tzinfo=None)
    sec = (t - GPS_EPOCH).total_seconds()
    if sec < 0:
        raise UserError(f"--time {text!r} is before the GPS epoch")
    sec += leap_seconds_at(GPS_EPOCH + _dt.timedelta(seconds=sec))
    week = int(sec // WEEK_S)
    return week, sec - week * WEEK_S, date_only


def parse_position(text: str) -> np.ndarray:
    """``LAT,LON,H`` (deg, deg, m above the ellipsoid) -> ECEF."""
    try:
        lat, lon, h = (float(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--position {text!r}: expected LAT,LON,H (degrees, degrees, metres)") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 360):
        raise UserError(f"--position {text!r}: latitude or longitude out of range")
    return lla2ecef(lat, lon, h)


def load_ephemerides(path) -> Ephemerides:
    """The GPS ephemerides of a RINEX navigation file (and its ionosphere parameters) as Ephemerides."""
    by_prn, iono = read_rinex_nav(path, systems=("G",))
    return Ephemerides(by_prn, iono)


def _check_ephemeris(ephs: Ephemerides, path, week: int, tow: float):
    if not ephs.covered(week, tow):
        lo = min((e.week * WEEK_S + e.toe for v in ephs.by_prn.values() for e in v), default=None)
        hi = max((e.week * WEEK_S + e.toe for v in ephs.by_prn.values() for e in v), default=None)
        span = ""
        if lo is not None:
            span = (f" (it covers {utc_text(int(lo // WEEK_S), lo % WEEK_S)[:16]} to "
                    f"{utc_text(int(hi // WEEK_S), hi % WEEK_S)[:16]} UTC +/- 4 h)")
        raise UserError(f"no ephemeris in {path} for {utc_text(week, tow)[:19]} UTC (GPS week {week}, "
                        f"TOW {tow:.0f} s){span}; give the broadcast ephemeris of the recording's day")


def snapshot_file(cfg, ephemeris_path: str, time: str | None = None, time_uncertainty_s: float = 60.0,
                  position: str | None = None, position_uncertainty_m: float = 100e3,
                  length_ms: int | None = None, every_s: float | None = None, height_m: float | None = None,
                  log=None, time_aiding: bool = True, independent: bool = False) -> list[SnapshotResult]:
    """Position snapshots of the configured input (one, or one every ``every_s`` seconds).  Along a file
    (``every_s``) each snapshot after a fix starts from that fix (position, unless one is given, and time
    carried over by the sample counter); ``time_aiding``: that time's 1-sigma also constrains the time
    estimate (a scalar Kalman filter on the time of the file's first sample); ``independent``: every
    snapshot from the given priors alone."""
    from ..gnss.registry import get_signal
    from ..pipeline import run_signals
    sigs = run_signals(cfg)
    if sigs[0] != "gps_l1ca" or len(sigs) > 1:
        raise UserError(f"snapshot positioning is for GPS L1 C/A only (the config's signal is {sigs[0]})")
    ephs = load_ephemerides(ephemeris_path)
    reader, n1, first, avail_ms = _open(cfg)
    length = _length(length_ms, avail_ms, reader)
    week, tow, time_uncertainty_s = _coarse_time(cfg, time, time_uncertainty_s)
    _check_ephemeris(ephs, ephemeris_path, week, tow)
    ctx = _Context(cfg, ephs, reader, get_signal("gps_l1ca"), length, n1,
                   parse_position(position) if position else None, position_uncertainty_m, time_aiding,
                   _settings(cfg, height_m, time_uncertainty_s))
    if every_s:
        starts = np.arange(0.0, (avail_ms - length) * 1e-3 + 1e-9, float(every_s))
    else:
        starts = np.array([0.0])
    results = []
    last, last_offset = None, 0.0                 # previous good fix: the prior of the next snapshot
    for k, off in enumerate(starts):
        x = reader.read(first + int(round(off * reader.fs)), length * n1)
        if len(x) < length * n1:
            break
        res = _one_snapshot(ctx, k, float(off), np.asarray(x, np.complex64), normalize_week_tow(week, tow + off),
                            time_uncertainty_s, last, last_offset)
        if res.fix.ok and not independent:
            last, last_offset = res.fix, float(off)
        results.append(res)
        if log is not None:
            log(_line(res))
    return results


@dataclass
class _Context:
    """What every snapshot of a file shares: config, ephemerides, reader, signal, length (ms) and samples per
    ms, the user's prior position and its uncertainty, time aiding, the solver's settings."""
    cfg: object
    ephs: Ephemerides
    reader: object
    sig: object
    length: int
    n1: int
    prior: object
    position_uncertainty_m: float
    time_aiding: bool
    settings: SnapshotSettings


def _open(cfg):
    """The input stages of the config: (reader, samples per ms, first sample, whole ms available)."""
    from ..pipeline import open_input
    reader = open_input(cfg)
    fs = float(reader.fs)
    n1 = fs * 1e-3
    if abs(n1 - round(n1)) > 1e-6:
        raise UserError(f"sample rate {fs:g} Hz is not a whole number of samples per millisecond: set "
                        "input.decimate: auto to resample it")
    n1 = int(round(n1))
    avail = int(reader.n_samples)                 # from input.skip_s on (reader.first)
    if avail // n1 < MIN_LENGTH_MS:
        raise UserError(f"input too short for a snapshot: {avail / fs * 1e3:.2f} ms, at least "
                        f"{MIN_LENGTH_MS} ms needed")
    return reader, n1, int(getattr(reader, "first", 0)), avail // n1


def _length(length_ms, avail_ms, reader) -> int:
    """The snapshot length (ms): ``length_ms`` or the default, at most the input."""
    want = int(length_ms) if length_ms else DEFAULT_LENGTH_MS
    if want < MIN_LENGTH_MS:
        raise UserError(f"--length must be at least {MIN_LENGTH_MS} ms")
    if length_ms and want > avail_ms:
        raise UserError(f"--length {want} ms is longer than the input ({reader.n_samples / reader.fs * 1e3:.1f} ms)")
    return min(want, avail_ms)


def _coarse_time(cfg, time, time_uncertainty_s):
    """The coarse time of the first sample: (week, tow, uncertainty s) from ``time`` or the input metadata."""
    if time is not None:
        week, tow, date_only = parse_time(time)
        if date_only:
            time_uncertainty_s = max(time_uncertainty_s, 43200.0)
        return week, tow, time_uncertainty_s
    week, tow = cfg.input.start_gps_week, cfg.input.start_gps_tow_s
    if week is None or tow is None:
        raise UserError("no time for the first sample: give --time (ISO 8601 UTC or GPS WEEK:TOW) or "
                        "input.start_gps_week / start_gps_tow_s (or SigMF / .tag metadata)")
    return int(week), float(tow), time_uncertainty_s


def _settings(cfg, height_m, time_uncertainty_s) -> SnapshotSettings:
    """The solver's settings from the config's navigation section."""
    nav = cfg.navigation
    return SnapshotSettings(troposphere=nav.troposphere != "none", ionosphere=nav.ionosphere != "none",
                            elevation_mask_deg=float(nav.elevation_mask_deg),
                            residual_threshold_m=float(nav.residual_threshold_m),
                            max_pdop=float(nav.max_pdop), height_m=height_m,
                            max_time_shift_s=max(120.0, 2.0 * min(time_uncertainty_s, 300.0)))


def _one_snapshot(ctx: _Context, k: int, off: float, x, t_nominal, time_uncertainty_s, last, last_offset):
    """Acquire and solve the snapshot ``x`` (its first sample ``off`` s into the file, coarse time
    ``t_nominal``), from the previous fix ``last`` (at ``last_offset``) when there is one."""
    a, ephs, s = ctx.cfg.acquisition, ctx.ephs, ctx.settings
    wk, tw = t_nominal
    searched = [p for p in a.prns if 1 <= p <= 32 and ephs.get(p, wk, tw) is not None]
    x_prior, t_coarse, unc = ctx.prior, (wk, tw), time_uncertainty_s
    if last is not None:
        # the previous fix: its position (unless the user gave one) and its time carried over by the
        # sample counter, with its 1-sigma (and 2 ppm of the elapsed time) as a time constraint
        elapsed = off - last_offset
        x_prior = last.ecef if x_prior is None else x_prior
        t_coarse = normalize_week_tow(last.gps_week, last.gps_tow_s + elapsed)
        unc = 1.0
        sig_t = float(np.hypot(last.time_sigma_s, 2e-6 * elapsed))
        if ctx.time_aiding and np.isfinite(sig_t) and sig_t > 0:
            s = replace(s, time_sigma_s=sig_t)
    if x_prior is not None and unc <= 600:
        # only satellites that can be above the horizon from within the prior's uncertainty
        near = set(in_sky(ephs, t_coarse[0], t_coarse[1], x_prior, mask_deg=-5.0
                          - math.degrees(ctx.position_uncertainty_m / 6.4e6)))
        searched = [p for p in searched if p in near]
    acq = snapshot_acquire(x, float(ctx.reader.fs), float(ctx.reader.if_hz), searched,
                           doppler_max_hz=float(a.doppler_max_hz),
                           doppler_center_hz=float(getattr(ctx.reader, "doppler_centre_hz", 0.0)),
                           pfa=float(a.pfa), threshold=float(a.threshold), width_ratio=float(a.width_ratio),
                           signal=ctx.sig)
    det = [r for r in acq if r.detected]
    obs = [SnapObs(r.prn, r.code_phase_chips, r.doppler_hz, r.cn0_dbhz if np.isfinite(r.cn0_dbhz) else 40.0,
                   float(ctx.length)) for r in det]
    fix = _solve(obs, ephs, t_coarse, unc, x_prior, s)
    missed = []
    if fix.ok:
        fix = with_bit_edges(fix, obs, {r.prn: r.edge_s for r in det if np.isfinite(r.edge_s)}, ephs, s)
        seen = {r.prn for r in det}
        missed = [p for p in in_sky(ephs, fix.gps_week, fix.gps_tow_s, fix.ecef, s.elevation_mask_deg)
                  if p not in seen]
    return SnapshotResult(k, off, ctx.length, int(t_coarse[0]), float(t_coarse[1]), fix, det, searched, missed)


def _solve(obs, ephs, t_coarse, unc, x_prior, settings):
    """The coarse-time fix; a time uncertainty beyond what one solution absorbs (> 10 min) is searched
    in steps of 10 min (a Doppler solution from each)."""
    week, tow = t_coarse
    fix = coarse_time_fix(obs, ephs, week, tow, x_prior, settings)
    if fix.ok or unc <= 600.0:
        return fix
    best = fix
    for dt in np.arange(600.0, unc + 1.0, 600.0):
        for sgn in (-1.0, 1.0):
            w, t = normalize_week_tow(week, tow + sgn * dt)
            if not ephs.covered(w, t):
                continue
            f = coarse_time_fix(obs, ephs, w, t, x_prior, settings)
            if f.ok and (not best.ok or f.residual_rms_m < best.residual_rms_m):
                best = f
        if best.ok:
            return best
    return best


def _line(r: SnapshotResult) -> str:
    f = r.fix
    if not f.ok:
        return f"snapshot {r.index} at {r.offset_s:.3f} s: no fix ({f.message})"
    return (f"snapshot {r.index} at {r.offset_s:.3f} s: {f.lat_deg:.6f} {f.lon_deg:.6f} {f.height_m:.1f} m, "
            f"{f.n_sats} sats, rms {f.residual_rms_m:.1f} m")
