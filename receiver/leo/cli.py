"""``gnssrx leo``: simulate Iridium-like Doppler measurements and position a static receiver.

    gnssrx leo simulate configs/leo/scenario_beijing.yaml -o meas.h5 [--set measurement.seed=7]
    gnssrx leo fix configs/leo/fix_default.yaml meas.h5 [--solver ekf] [-o fix.h5] [--set ...]

Bad input (config keys/values, missing or malformed files) is reported as one line on stderr with exit
code 2, and no output file is left behind.
"""
from __future__ import annotations

import os
import sys

import click
import numpy as np

from ..errors import UserError


def _fail(exc: UserError):
    click.echo(f"gnssrx: error: {exc}", err=True)
    sys.exit(2)


def _check_output(path):
    """Missing directories are made, as for every command's outputs (receiver/safeio.py check_output)."""
    from ..safeio import check_output
    check_output(path, suffixes=())


@click.group("leo")
def leo():
    """LEO (Iridium-like) Doppler positioning: simulate measurements, compute fixes."""


@leo.command("simulate")
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="HDF5 measurement file to write")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="override a scenario key (repeatable), e.g. measurement.noise_sigma_hz=1")
def simulate_cmd(scenario, output, overrides):
    """Simulate the Doppler of the visible satellites seen by a static receiver."""
    from .config import load_scenario
    from .doppler import save_measurements, simulate
    try:
        cfg = load_scenario(scenario, overrides)
        data = simulate(cfg)
        _check_output(output)            # after the input checks: bad input leaves no directory behind
        save_measurements(output, data)
    except UserError as exc:
        _fail(exc)
    n_obs = int(np.sum(data.observed))
    n_sat = int(np.sum(data.observed.any(axis=0)))
    click.echo(f"wrote {output}: {data.n_epochs} epochs, {n_obs} Doppler observations of {n_sat} "
               f"satellites (sigma {cfg.measurement.noise_sigma_hz:g} Hz, mask "
               f"{cfg.measurement.elevation_mask_deg:g} deg)")


def _resolve_settings(cfg, data, grid):
    from .config import fix_settings
    s = fix_settings(cfg)
    sigma = cfg.leo.sigma_hz
    if sigma is None:
        sigma = data.attrs.get("noise_sigma_hz")
        if sigma is None or not float(sigma) > 0:
            raise UserError("the measurement file states no positive noise_sigma_hz; set "
                            "leo.sigma_hz")
    s["sigma_hz"] = float(sigma)
    if s["init_sigma_m"] is None:
        if cfg.leo.init == "earth_center":
            s["init_sigma_m"] = 2.0e6
        elif grid is not None:
            s["init_sigma_m"] = max(grid.cell_size_m, 500.0)
        else:
            s["init_sigma_m"] = 5000.0
    return s


def run_fix(cfg, data):
    """Window the data, compute the initial value, run the configured solver.

    Returns (result, x0, grid_result_or_None, settings).
    """
    from . import solvers
    data = data.window(cfg.leo.start_utc, cfg.leo.stop_utc, cfg.leo.step_s)
    grid = None
    if cfg.leo.init == "geosot":
        g = cfg.geosot
        x0, grid = solvers.initial_state(data, g.start_level, g.end_level, g.keep, g.height_m,
                                         g.clock, g.elevation_mask_deg, g.mask_margin_deg)
    elif cfg.leo.init == "earth_center":
        x0 = solvers.earth_center_state()
    else:
        x0 = solvers.given_state(*cfg.leo.init_lla)
    settings = _resolve_settings(cfg, data, grid)
    res = solvers.solve(data, cfg.leo.solver, x0, settings)
    return data, res, x0, grid, settings


@leo.command("fix")
@click.argument("config", type=click.Path(dir_okay=False))
@click.argument("measurements", type=click.Path(dir_okay=False))
@click.option("--solver", type=click.Choice(("lsm", "ekf", "ckf", "sqrt_ckf")), default=None,
              help="override leo.solver")
@click.option("-o", "--output", default=None, type=click.Path(dir_okay=False),
              help="optional HDF5 file with the per-epoch estimates")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="override a config key (repeatable), e.g. geosot.end_level=16")
def fix_cmd(config, measurements, solver, output, overrides):
    """Position a static receiver from LEO Doppler measurements."""
    from ..gnss.geodesy import ecef2enu, ecef2lla
    from .config import load_fix_config
    from .doppler import load_measurements
    overrides = list(overrides) + ([f"leo.solver={solver}"] if solver else [])
    try:
        cfg = load_fix_config(config, overrides)
        data = load_measurements(measurements)
        if output:
            _check_output(output)        # after the input checks: bad input leaves no directory behind
        data, res, x0, grid, settings = run_fix(cfg, data)
        if output:
            _write_fix(output, cfg, data, res, x0, grid, settings)
    except UserError as exc:
        _fail(exc)
    x = res.final
    if grid is not None:
        click.echo(f"initial value: GeoSOT level {grid.level} cell {grid.code} "
                   f"({grid.lat_deg:.5f}, {grid.lon_deg:.5f}), {grid.n_evaluated} cells evaluated, "
                   f"f_u {grid.freq_offset_hz:.1f} Hz")
    if res.failed:
        click.echo(f"warning: {res.message}", err=True)
        valid = np.nonzero(np.all(np.isfinite(res.estimates), axis=1))[0]
        if len(valid) == 0:
            sys.exit(1)
        x = res.estimates[valid[-1]]
    lat, lon, h = ecef2lla(x[:3])
    click.echo(f"solver {cfg.leo.solver}: {data.n_epochs} epochs, {int(data.observed.sum())} "
               f"observations, {res.runtime_s * 1e3:.1f} ms")
    click.echo(f"position: lat {float(lat):.6f} deg, lon {float(lon):.6f} deg, h {float(h):.1f} m; "
               f"ECEF [{x[0]:.1f}, {x[1]:.1f}, {x[2]:.1f}] m; f_u {x[3]:.2f} Hz")
    if res.covariances is not None and np.all(np.isfinite(res.covariances[-1])):
        sd = np.sqrt(np.clip(np.diag(res.covariances[-1]), 0, None))
        click.echo(f"formal std: x {sd[0]:.1f} m, y {sd[1]:.1f} m, z {sd[2]:.1f} m, "
                   f"f_u {sd[3]:.2f} Hz")
    if data.truth_ecef is not None:
        err = x[:3] - data.truth_ecef
        enu = ecef2enu(x[:3], data.truth_ecef)
        click.echo(f"error vs truth: ECEF [{err[0]:.1f}, {err[1]:.1f}, {err[2]:.1f}] m, "
                   f"ENU [{enu[0]:.1f}, {enu[1]:.1f}, {enu[2]:.1f}] m, 3-D {np.linalg.norm(err):.1f} m")
    if output:
        click.echo(f"wrote {output}")
    if res.failed:
        sys.exit(1)


def _write_fix(path, cfg, data, res, x0, grid, settings):
    import h5py
    tmp = path + ".part"
    try:
        with h5py.File(tmp, "w") as f:
            f.create_dataset("time_utc", data=np.array([str(t) for t in data.time_utc], dtype="S"))
            f["t_s"] = data.t_s
            f["estimates"] = res.estimates
            if res.covariances is not None:
                f["covariances"] = res.covariances
            f["initial_state"] = x0
            f.attrs["solver"] = res.method
            f.attrs["runtime_s"] = res.runtime_s
            f.attrs["failed"] = res.failed
            f.attrs["message"] = res.message
            f.attrs["config_yaml"] = cfg.to_yaml()
            for k, v in settings.items():
                if v is not None:
                    f.attrs["setting_" + k] = v
            if grid is not None:
                f.attrs["geosot_code"] = grid.code
                f.attrs["geosot_level"] = grid.level
            if data.truth_ecef is not None:
                f["truth_ecef_m"] = data.truth_ecef
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
