"""Config schemas of the LEO Doppler positioning commands (same machinery as the receiver config).

* ``SCENARIO_SCHEMA``: ``gnssrx leo simulate scenario.yaml -o meas.h5``
* ``FIX_SCHEMA``:      ``gnssrx leo fix config.yaml meas.h5``
"""
from __future__ import annotations

import datetime

from ..config import P, build, read_yaml
from ..errors import UserError
from .constellation import to_datetime64
from .doppler import IRIDIUM_CARRIER_HZ

SOLVERS = ("lsm", "ekf", "ckf", "sqrt_ckf")

SCENARIO_SCHEMA = {
    "constellation": {
        "tle_file": P(None, "str", "TLE file (2- or 3-line format); empty: the shipped synthetic "
                                   "Iridium-NEXT-like set data/iridium_synthetic.tle", nullable=True),
        "carrier_hz": P(IRIDIUM_CARRIER_HZ, "float", "carrier frequency f0 (Iridium ring-alert "
                                                     "channel 1626.270833 MHz)", lo=1e6),
        "dut1_s": P(0.0, "float", "UT1 - UTC used for the TEME -> Earth-fixed rotation", lo=-1.0,
                    hi=1.0),
    },
    "receiver": {
        "lat_deg": P(39.9042, "float", "true receiver geodetic latitude", lo=-90.0, hi=90.0),
        "lon_deg": P(116.4074, "float", "true receiver longitude", lo=-180.0, hi=180.0),
        "height_m": P(60.0, "float", "true receiver ellipsoidal height", lo=-1000.0, hi=100000.0),
        "freq_offset_hz": P(150.0, "float", "receiver frequency offset f_u at the first epoch"),
        "freq_drift_hz_per_s": P(0.0, "float", "linear drift of f_u"),
    },
    "time": {
        "start_utc": P("2022-04-05T12:01:50", "any", "first epoch (ISO-8601 UTC string or YAML timestamp)"),
        "stop_utc": P("2022-04-05T12:03:30", "any", "last epoch (ISO-8601 UTC, inclusive)"),
        "step_s": P(5.0, "float", "epoch interval", lo=0.001),
    },
    "measurement": {
        "elevation_mask_deg": P(10.0, "float", "satellites below this elevation are not observed",
                                lo=-10.0, hi=90.0),
        "noise_sigma_hz": P(0.5, "float", "standard deviation of the Gaussian Doppler noise", lo=0.0),
        "seed": P(1, "int", "random seed of the noise (empty: non-reproducible)", nullable=True,
                  lo=0),
        "max_satellites": P(None, "int", "keep only the highest satellites per epoch (empty: all)",
                            nullable=True, lo=1),
    },
}

FIX_SCHEMA = {
    "leo": {
        "solver": P("sqrt_ckf", "str", "positioning algorithm", choices=SOLVERS),
        "init": P("geosot", "str", "initial value: GeoSOT grid search, the Earth's centre, or "
                                   "leo.init_lla", choices=("geosot", "earth_center", "given")),
        "init_lla": P(None, "list_float", "[lat_deg, lon_deg, h_m] used when leo.init is 'given'",
                      nullable=True),
        "sigma_hz": P(None, "float", "Doppler noise standard deviation for R (empty: the "
                                     "noise_sigma_hz attribute of the measurement file)",
                      nullable=True, lo=1e-6),
        "start_utc": P(None, "any", "first epoch used, ISO-8601 UTC (empty: first in the file)",
                       nullable=True),
        "stop_utc": P(None, "any", "last epoch used, ISO-8601 UTC (empty: last in the file)",
                      nullable=True),
        "step_s": P(None, "float", "decimate the epochs to this interval (empty: all)",
                    nullable=True, lo=0.001),
    },
    "filter": {
        "sigma_d2_m2": P(10.0, "float", "sigma_D^2 of the position process noise, "
                                        "Sp = sigma_D^2 / 3 (m^2/s)", lo=0.0),
        "sf_hz2_per_s": P(0.01, "float", "frequency-offset process noise density Sf (Hz^2/s)",
                          lo=0.0),
        "init_sigma_m": P(None, "float", "initial position standard deviation per axis (empty: "
                                         "the diagonal of the final GeoSOT cell, at least 500 m; "
                                         "2000 km when starting at the Earth's centre)",
                          nullable=True, lo=0.0),
        "init_sigma_fu_hz": P(50.0, "float", "initial frequency-offset standard deviation", lo=0.0),
    },
    "lsm": {
        "max_iter": P(10, "int", "Gauss-Newton iterations per epoch", lo=1, hi=1000),
        "tol_m": P(1e-3, "float", "stop when the position step is below this", lo=0.0),
        "window_epochs": P(None, "int", "batch of the most recent epochs (empty: all epochs so far)",
                           nullable=True, lo=1),
        "min_observations": P(4, "int", "report the previous estimate until the batch holds this many "
                                        "observations", lo=1),
        "hold_until_better": P(True, "bool", "report the previous estimate while the formal 3-D "
                                             "standard deviation of the batch solution exceeds that "
                                             "of the initial value (sqrt(3) * initial sigma)"),
    },
    "geosot": {
        "start_level": P(9, "int", "GeoSOT level of the first, exhaustive search (9 = 1 deg cells)",
                         lo=1, hi=20),
        "end_level": P(18, "int", "GeoSOT level of the final cell (15 = 1', 21 = 1\")", lo=1,
                       hi=32),
        "keep": P(32, "int", "cells kept and refined at each level", lo=1, hi=1000),
        "height_m": P(0.0, "float", "ellipsoidal height of the searched surface", lo=-1000.0,
                      hi=100000.0),
        "clock": P("fit", "str", "'fit': remove the least-squares frequency offset from the residual "
                                 "vector; 'ignore': use Y_i = f0 (v_i.e_i)/c - f_di as is",
                   choices=("fit", "ignore")),
        "mask_margin_deg": P(5.0, "float", "search region: points that see every observed satellite "
                                           "above (elevation mask - margin)", lo=0.0, hi=90.0),
        "elevation_mask_deg": P(10.0, "float", "elevation mask assumed for the search region",
                                lo=-10.0, hi=90.0),
    },
}


def _check_times(section, prefix):
    for key in ("start_utc", "stop_utc"):
        if key in section and section[key] is not None:
            if not isinstance(section[key], (str, datetime.datetime, datetime.date)):
                raise UserError(f"config key '{prefix}.{key}' must be an ISO-8601 time, got "
                                f"{section[key]!r}")
            try:
                to_datetime64(section[key])
            except UserError:
                raise UserError(f"config key '{prefix}.{key}' is not an ISO-8601 time: "
                                f"{section[key]!r}") from None


def load_scenario(path=None, overrides=None):
    """The ``gnssrx leo simulate`` scenario (SCENARIO_SCHEMA) from a YAML file (None: defaults) and overrides;
    invalid keys or times are a one-line UserError."""
    cfg = build(SCENARIO_SCHEMA, read_yaml(path) if path is not None else {}, overrides)
    _check_times(cfg.time, "time")
    if to_datetime64(cfg.time.stop_utc) < to_datetime64(cfg.time.start_utc):
        raise UserError("config key 'time.stop_utc' is before 'time.start_utc'")
    return cfg


def load_fix_config(path=None, overrides=None):
    """The ``gnssrx leo fix`` configuration (FIX_SCHEMA) from a YAML file (None: defaults) and overrides, checked
    (times, ``leo.init_lla`` for a given initial value, GeoSOT levels); errors are one-line UserErrors."""
    cfg = build(FIX_SCHEMA, read_yaml(path) if path is not None else {}, overrides)
    _check_times(cfg.leo, "leo")
    if cfg.leo.init == "given":
        lla = cfg.leo.init_lla
        if lla is None or len(lla) != 3:
            raise UserError("config key 'leo.init_lla' must be [lat_deg, lon_deg, h_m] when "
                            "leo.init is 'given'")
        if not (-90 <= lla[0] <= 90 and -180 <= lla[1] <= 180):
            raise UserError("config key 'leo.init_lla' holds an invalid latitude/longitude")
    if cfg.geosot.end_level < cfg.geosot.start_level:
        raise UserError("config key 'geosot.end_level' must be >= geosot.start_level")
    return cfg


def fix_settings(cfg):
    """Plain dict of the solver settings (used by receiver.leo.solvers)."""
    return dict(sigma_d2_m2=cfg.filter.sigma_d2_m2, sf_hz2_per_s=cfg.filter.sf_hz2_per_s,
                init_sigma_m=cfg.filter.init_sigma_m, init_sigma_fu_hz=cfg.filter.init_sigma_fu_hz,
                lsm_max_iter=cfg.lsm.max_iter, lsm_tol_m=cfg.lsm.tol_m,
                lsm_window_epochs=cfg.lsm.window_epochs, lsm_min_observations=cfg.lsm.min_observations,
                lsm_hold_until_better=cfg.lsm.hold_until_better)

