"""``gnssrx snapshot``: a position from milliseconds of signal and a broadcast ephemeris (coarse-time
navigation).  UserError is reported by the main CLI as one line, exit code 2."""
from __future__ import annotations

import json
import math
import os

import click


def _clean(v):
    """JSON-safe: NaN / inf -> None, numpy scalars -> Python."""
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


@click.command("snapshot")
@click.argument("config", type=str)
@click.option("--input", "input_path", type=str, help="IF file (overrides input.path)")
@click.option("--ephemeris", "ephemeris", type=str, required=True,
              help="RINEX 2/3 broadcast navigation file covering the recording's time")
@click.option("--time", "time_text", type=str, default=None,
              help="coarse time of the first sample: ISO 8601 (UTC, e.g. 2022-03-27T11:32:04Z; a date alone "
                   "searches that day) or GPS WEEK:TOW; default: the input's metadata")
@click.option("--time-uncertainty", "time_unc", type=click.FloatRange(min=0.0), default=60.0, show_default=True,
              help="uncertainty of that time (s); beyond 600 s hypotheses 10 min apart are searched")
@click.option("--position", "position", type=str, default=None,
              help="a-priori position LAT,LON,H (deg, deg, m); default: a Doppler-only solution")
@click.option("--position-uncertainty", "pos_unc", type=click.FloatRange(min=0.0), default=100e3,
              show_default=True, help="uncertainty of the a-priori position (m): widens the satellites searched")
@click.option("--height", "height", type=float, default=None,
              help="altitude aiding: constrain the height (m above the ellipsoid); allows 4-satellite fixes")
@click.option("--length", "length_ms", type=click.IntRange(min=1), default=None,
              help="snapshot length (ms); default: the file up to 40 ms")
@click.option("--every", "every_s", type=click.FloatRange(min=0.001), default=None,
              help="one snapshot every S seconds along the file (table: HDF5 /snapshot + CSV)")
@click.option("--independent", is_flag=True,
              help="--every: solve every snapshot from the given priors alone (default: each starts from the "
                   "previous fix, its time carried over by the sample counter and used as a constraint)")
@click.option("--output", "-o", "output", type=str, default=None,
              help="HDF5 table of --every (default <input stem>.snapshot.h5 in the current directory; CSV "
                   "beside it)")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="override a config key")
def snapshot(config, input_path, ephemeris, time_text, time_unc, position, pos_unc, height, length_ms, every_s,
             independent, output, as_json, sets):
    """Snapshot position of a short recording (coarse-time navigation from a broadcast ephemeris)."""
    from ..schema import load_receiver_config
    from ..errors import UserError
    from .run import snapshot_file
    cfg = load_receiver_config(config, list(sets) + ([("input.path", input_path)] if input_path else []))
    log = None if (as_json or not every_s) else click.echo
    results = snapshot_file(cfg, ephemeris, time_text, time_unc, position, pos_unc, length_ms, every_s, height,
                            log=log, independent=independent)
    if not every_s:
        r = results[0]
        if not r.fix.ok:
            found = " ".join(str(a.prn) for a in r.detected) or "none"
            raise UserError(f"no snapshot fix: {r.fix.message} (detected: {found})")
        if as_json:
            click.echo(json.dumps(_clean(r.as_dict())))
        else:
            click.echo(_text(r))
        return
    from ..runfile.snapshot import write_snapshot_table
    if output is None:
        stem = os.path.splitext(os.path.basename(cfg.input.path))[0]
        output = f"{stem}.snapshot.h5"
    attrs = {"input": str(cfg.input.path), "ephemeris": str(ephemeris), "every_s": float(every_s),
             "time": time_text or "", "position": position or "", "independent": int(independent),
             "length_ms": int(results[0].length_ms)
             if results else 0}
    h5, csv_path = write_snapshot_table(output, results, attrs, reads=[cfg.input.path, ephemeris, config])
    ok = [r for r in results if r.fix.ok]
    if as_json:
        click.echo(json.dumps(_clean({"snapshots": [r.as_dict() for r in results], "n_fixes": len(ok),
                                      "hdf5": h5, "csv": csv_path})))
    else:
        click.echo(f"{len(ok)} of {len(results)} snapshots fixed; table {h5}, {csv_path}")
    if not ok:
        raise UserError(f"no snapshot of {cfg.input.path} gave a fix ({results[0].fix.message if results else ''})")


def _text(r) -> str:
    f = r.fix
    lines = [f"position  {f.lat_deg:.7f} {f.lon_deg:.7f} {f.height_m:.1f} m (lat, lon, height above WGS-84)",
             f"ECEF      {f.ecef[0]:.2f} {f.ecef[1]:.2f} {f.ecef[2]:.2f} m",
             f"sigma ENU {f.sigma_enu_m[0]:.1f} {f.sigma_enu_m[1]:.1f} {f.sigma_enu_m[2]:.1f} m",
             f"time      GPS week {f.gps_week} TOW {f.gps_tow_s:.6f} s ({_utc(f)}), 1-sigma "
             f"{f.time_sigma_s * 1e3:.3f} ms ({f.time_source}), {f.time_correction_s:+.3f} s from the coarse time",
             f"velocity  {f.velocity_ecef[0]:.2f} {f.velocity_ecef[1]:.2f} {f.velocity_ecef[2]:.2f} m/s (ECEF), "
             f"clock drift {f.clock_drift_mps:.1f} m/s",
             "DOP       " + " ".join(f"{k.upper()} {v:.2f}" for k, v in f.dops.items()),
             f"prior     {f.prior}{' + height constraint' if f.height_aided else ''}; snapshot "
             f"{r.length_ms} ms at {r.offset_s:.3f} s",
             f"{'PRN':>4} {'C/N0':>5} {'doppler_hz':>11} {'code_phase':>11} {'resid_m':>8}"]
    res = dict(zip(f.prns, f.residuals_m))
    for a in r.detected:
        rr = f"{res[a.prn]:8.2f}" if a.prn in res else "  unused"
        lines.append(f"{a.prn:4d} {a.cn0_dbhz:5.1f} {a.doppler_hz:11.1f} {a.code_phase_chips:11.4f} {rr}")
    lines.append(f"used {f.n_sats} satellites, residual RMS {f.residual_rms_m:.2f} m"
                 + (f"; rejected {' '.join(map(str, f.rejected))}" if f.rejected else ""))
    lines.append(f"in the sky but not found: {' '.join(map(str, r.missed)) or 'none'}")
    return "\n".join(lines)


def _utc(f) -> str:
    from .run import utc_text
    return utc_text(f.gps_week, f.gps_tow_s)
