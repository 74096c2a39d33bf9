"""Snapshot-positioning table (``gnssrx snapshot --every``): one row per snapshot in the HDF5 table
``/snapshot`` (a compound dataset, NaN where a snapshot has no fix) with the run's settings as attributes,
written atomically (receiver/safeio.py), and the same rows as CSV."""
from __future__ import annotations

import csv

import numpy as np

from ..safeio import AtomicH5, check_output

#: columns of /snapshot (name, dtype, unit / meaning)
COLUMNS = (
    ("index", "i4", "snapshot number"), ("offset_s", "f8", "first sample, s into the file"),
    ("length_ms", "i4", "snapshot length"), ("ok", "i1", "1: fix, 0: none"),
    ("gps_week", "i4", "GPS week of the first sample (estimated)"),
    ("gps_tow_s", "f8", "GPS time of week of the first sample (estimated)"),
    ("time_sigma_s", "f8", "1-sigma of gps_tow_s"),
    ("x_m", "f8", "ECEF"), ("y_m", "f8", "ECEF"), ("z_m", "f8", "ECEF"),
    ("lat_deg", "f8", "WGS-84"), ("lon_deg", "f8", "WGS-84"), ("height_m", "f8", "above the ellipsoid"),
    ("vx_mps", "f8", "ECEF velocity"), ("vy_mps", "f8", "ECEF velocity"), ("vz_mps", "f8", "ECEF velocity"),
    ("n_sats", "i4", "satellites used"), ("residual_rms_m", "f8", "pseudorange residual RMS"),
    ("pdop", "f8", ""), ("hdop", "f8", ""), ("vdop", "f8", ""),
    ("n_detected", "i4", "satellites detected"), ("n_missed", "i4", "in the sky but not detected"),
)


def rows(results) -> np.ndarray:
    """The snapshot results (receiver.snapshot.run.SnapshotResult) as a structured array of COLUMNS, one row
    each; the numbers of a failed fix are NaN."""
    dt = np.dtype([(n, t) for n, t, _ in COLUMNS])
    out = np.zeros(len(results), dt)
    for i, r in enumerate(results):
        f = r.fix
        row = out[i]
        row["index"], row["offset_s"], row["length_ms"], row["ok"] = r.index, r.offset_s, r.length_ms, f.ok
        row["n_detected"], row["n_missed"] = len(r.detected), len(r.missed)
        if not f.ok:
            for n, t, _ in COLUMNS:
                if t == "f8" and n != "offset_s":
                    row[n] = np.nan
            continue
        row["gps_week"], row["gps_tow_s"], row["time_sigma_s"] = f.gps_week, f.gps_tow_s, f.time_sigma_s
        row["x_m"], row["y_m"], row["z_m"] = f.ecef
        row["lat_deg"], row["lon_deg"], row["height_m"] = f.lat_deg, f.lon_deg, f.height_m
        row["vx_mps"], row["vy_mps"], row["vz_mps"] = f.velocity_ecef
        row["n_sats"], row["residual_rms_m"] = f.n_sats, f.residual_rms_m
        row["pdop"], row["hdop"], row["vdop"] = (f.dops.get(k, np.nan) for k in ("pdop", "hdop", "vdop"))
    return out


def write_snapshot_table(h5_path, results, attrs: dict, reads=()) -> tuple[str, str]:
    """Write ``results`` (receiver.snapshot.run.SnapshotResult) to ``h5_path`` (/snapshot) and the CSV
    beside it (same stem, .csv).  Returns the two paths."""
    table = rows(results)
    out = AtomicH5(h5_path, "snapshot output", reads=reads)
    try:
        ds = out.f.create_dataset("snapshot", data=table)
        for n, _, meaning in COLUMNS:
            if meaning:
                ds.attrs[f"{n}"] = meaning
        for k, v in attrs.items():
            out.f.attrs[k] = "" if v is None else v
        out.check()
        out.commit()
    except BaseException:
        out.abort()
        raise
    csv_path = str(h5_path).rsplit(".", 1)[0] + ".csv" if str(h5_path).endswith((".h5", ".hdf5")) \
        else str(h5_path) + ".csv"
    csv_path = check_output(csv_path, reads, "snapshot CSV")
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([n for n, _, _ in COLUMNS])
        for row in table:
            w.writerow([f"{v:.3f}" if isinstance(v, float) and n in ("x_m", "y_m", "z_m", "height_m")
                        else (f"{v:.9f}" if n in ("lat_deg", "lon_deg", "gps_tow_s") else v)
                        for n, v in zip(table.dtype.names, row.tolist())])
    return str(out.path), csv_path
