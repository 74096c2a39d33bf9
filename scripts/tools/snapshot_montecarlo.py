"""Monte Carlo of snapshot positioning (``gnssrx snapshot``) on gnssrx's own simulator.

Per trial: a random place (uniform on the sphere, 0-1000 m), a random time of 2022-01-01 (GPS week 2190,
ephemerides of ../shared/data/brdc0010.22n), a random oscillator error (+/-1 ppm) and clock bias; one
recording of the longest snapshot per C/N0 (constant over the satellites), whose first 2, 5, 10, 20, 100 ms
are the snapshots.  Each snapshot is acquired once (the 100-ms one reuses the 20-ms search: the same
dwell) and solved twice:
  (a) coarse time within +/-2 s (uniform) and an a-priori position within 100 km (uniform direction,
      horizontal distance uniform in 0-100 km);
  (b) coarse time within +/-60 s and no position (Doppler-only prior).
With ``--moving`` the receiver moves at 80-150 m/s (random heading, constant velocity) and the velocity
error (from the Dopplers) is scored too; mode (b) then needs the moving Doppler solution (>= 8 satellites).

Prints a table per mode, C/N0 and length: fixes, no-fixes, false fixes (farther than FALSE_FIX_M from the
truth), 3D error percentiles (50 / 95 %), first-sample time errors and the share within 1 ms, (moving) the
velocity error and the share within 1 m/s; writes all rows, with each snapshot's measurements, as JSON
(``--out``; ``--table`` prints the table of several such files together).  Seeded: the same ``--seed``
gives the same trials.  About 12 s of CPU per trial (both C/N0s, every length) with one BLAS thread:

    OPENBLAS_NUM_THREADS=1 GNSSRX_THREADS=1 PYTHONPATH=. nice -n 19 \
        python scripts/tools/snapshot_montecarlo.py --trials 20 --seed 11 --out /tmp/s11.json
    PYTHONPATH=. python scripts/tools/snapshot_montecarlo.py --table /tmp/s11.json /tmp/s12.json
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from receiver.gnss.geodesy import enu_matrix  # noqa: E402
from receiver.navigation.snapshot import SnapObs, SnapshotSettings, coarse_time_fix, in_sky  # noqa: E402
from receiver.navigation.snapshot_time import with_bit_edges  # noqa: E402
from receiver.runfile.truth import TruthFile  # noqa: E402
from receiver.sim.simulate import simulate  # noqa: E402
from receiver.snapshot.acquire import snapshot_acquire  # noqa: E402
from receiver.snapshot.run import load_ephemerides  # noqa: E402
from receiver.source.io import SampleReader  # noqa: E402

RINEX = os.environ.get("GNSSRX_SNAPSHOT_RINEX") or os.path.join(os.path.dirname(ROOT), "shared", "data",
                                                                "brdc0010.22n")
WEEK = 2190
TOW_LO, TOW_HI = 518400.0 + 1800.0, 604800.0 - 1800.0          # 2022-01-01 00:30 .. 23:30 GPS time
LENGTHS = (2, 5, 10, 20, 100)
CN0S = (45.0, 38.0)

SCENARIO = """time: {{gps_week: {week}, tow_s: {tow:.6f}, duration_s: {dur:.3f}, seed: {seed}}}
constellation: {{source: rinex, rinex: {rinex}, elevation_mask_deg: 5.0}}
receiver: {{trajectory: {traj}, lat_deg: {lat:.7f}, lon_deg: {lon:.7f}, height_m: {h:.2f},
           velocity_enu_mps: [{ve:.3f}, {vn:.3f}, 0.0]}}
clock: {{bias_s: {bias:.6f}, freq_error_ppm: {ppm:.4f}, noise: none}}
cn0: {{mode: constant, dbhz: {cn0}}}
atmosphere: {{ionosphere: klobuchar, troposphere: saastamoinen}}
frontend: {{sample_rate_hz: {fs}, if_hz: 0.0, format: int8_iq}}
"""


def trial_params(rng, moving):
    lat = float(np.degrees(np.arcsin(rng.uniform(-1, 1))))
    lon = float(rng.uniform(-180, 180))
    p = {"lat": lat, "lon": lon, "h": float(rng.uniform(0, 1000)), "tow": float(rng.uniform(TOW_LO, TOW_HI)),
         "bias": float(rng.uniform(-0.3, 0.3)), "ppm": float(rng.uniform(-1, 1)), "seed": int(rng.integers(1, 10 ** 6)),
         "dt_a": float(rng.uniform(-2, 2)), "dt_b": float(rng.uniform(-60, 60)),
         "prior_az": float(rng.uniform(0, 2 * np.pi)), "prior_km": float(rng.uniform(0, 100)),
         "speed": float(rng.uniform(80, 150)) if moving else 0.0, "heading": float(rng.uniform(0, 2 * np.pi))}
    return p


def run_trial(p, cn0, fs, tmp, ephs, max_len, lengths=LENGTHS, search="all"):
    path = os.path.join(tmp, "snap.bin")
    scen = os.path.join(tmp, "scen.yaml")
    with open(scen, "w") as fh:
        fh.write(SCENARIO.format(week=WEEK, tow=p["tow"], dur=max_len * 1e-3 + 0.002, seed=p["seed"], rinex=RINEX,
                                 traj="constant_velocity" if p["speed"] else "static", lat=p["lat"], lon=p["lon"],
                                 h=p["h"], ve=p["speed"] * np.sin(p["heading"]), vn=p["speed"] * np.cos(p["heading"]),
                                 bias=p["bias"], ppm=p["ppm"], cn0=cn0, fs=fs))
    simulate(scen, path, progress=False)
    with TruthFile(os.path.join(tmp, "snap.truth.h5")) as tf:
        rx = tf.table("receiver")
        x_true, v_true, tow_true = rx["ecef"][0], rx["velocity_ecef"][0], float(rx["gps_tow"][0])
    reader = SampleReader(path, "int8_iq", fs)
    n1 = int(round(fs * 1e-3))
    sky = in_sky(ephs, WEEK, tow_true, x_true, 5.0)
    # "all": every PRN with an ephemeris (what mode (b) searches); "sky": those above -5 deg at the truth (what
    # mode (a) searches; fewer false detections for the integrity to catch, a third of the CPU)
    prns = ephs.covered(WEEK, tow_true) if search == "all" else in_sky(ephs, WEEK, tow_true, x_true, -5.0)
    lat, lon = p["lat"], p["lon"]
    enu = enu_matrix(lat, lon)
    prior = x_true + p["prior_km"] * 1e3 * (np.sin(p["prior_az"]) * enu[0] + np.cos(p["prior_az"]) * enu[1])
    rows = []
    cache = {}
    for length in [n for n in lengths if n <= max_len]:
        x = reader.read(0, length * n1)
        t0 = time.time()
        out = []
        coarse = cache.get("20") if length > 20 else None        # the same dwell (dwell_plan: <= 20 ms)
        acq = snapshot_acquire(x, fs, 0.0, prns, doppler_max_hz=7000.0, coarse=coarse, search_out=out)
        if length == 20:
            cache["20"] = out
        t_acq = time.time() - t0
        det = [a for a in acq if a.detected]
        obs = [SnapObs(a.prn, a.code_phase_chips, a.doppler_hz, a.cn0_dbhz if np.isfinite(a.cn0_dbhz) else 40.0,
                       float(length)) for a in det]
        edges = {a.prn: a.edge_s for a in det if np.isfinite(a.edge_s)}
        false = [a.prn for a in det if a.prn not in sky]
        meas = {"obs": [[o.prn, o.code_phase_chips, o.doppler_hz, o.cn0_dbhz] for o in obs],
                "edges": {str(k): v for k, v in edges.items()}}
        for mode, dt, xp in (("a", p["dt_a"], prior), ("b", p["dt_b"], None)):
            t0 = time.time()
            fix = coarse_time_fix(obs, ephs, WEEK, tow_true + dt, xp, SnapshotSettings())
            fix = with_bit_edges(fix, obs, edges, ephs, SnapshotSettings())
            row = {"cn0": cn0, "length_ms": length, "mode": mode, "ok": bool(fix.ok), "n_det": len(det),
                   "n_sky": len(sky), "false": false, "t_acq_s": t_acq, "t_solve_s": time.time() - t0,
                   "speed": p["speed"], "msg": fix.message, "time_source": fix.time_source,
                   "prior": fix.prior, "n_edges": len(edges), "tow_true": tow_true, "x_true": list(x_true),
                   "v_true": list(v_true), "tow_coarse": tow_true + dt, "x_prior": None if xp is None else list(xp),
                   **meas}
            if fix.ok:
                row.update({"err3d_m": float(np.linalg.norm(fix.ecef - x_true)),
                            "err_h_m": float(np.linalg.norm((enu @ (fix.ecef - x_true))[:2])),
                            "dtime_ms": (fix.gps_tow_s - tow_true) * 1e3, "time_sigma_ms": fix.time_sigma_s * 1e3,
                            "vel_err_mps": float(np.linalg.norm(fix.velocity_ecef - v_true)),
                            "n_used": fix.n_sats, "rms_m": fix.residual_rms_m, "pdop": fix.dops.get("pdop")})
            rows.append(row)
    return rows


#: a fix farther than this from the truth is counted as a false fix (wrong whole milliseconds, time or detections;
#: it stays in the percentiles)
FALSE_FIX_M = 1000.0


def table(rows, moving=False):
    """The table: per mode, C/N0 and length the fixes (of the trials), no-fixes, false fixes (> FALSE_FIX_M),
    3D error percentiles, |time error| percentiles and the share within 1 ms, (moving) velocity error
    percentiles and the share within 1 m/s; percentiles and shares over the fixes."""
    lines = []
    hdr = (f"{'mode':>4} {'C/N0':>5} {'len_ms':>6} {'fixes':>9} {'nofix':>5} {'false':>5} {'3D50_m':>8} {'3D95_m':>8} "
           f"{'|dt|50_ms':>9} {'|dt|95_ms':>9} {'dt<1ms':>7}"
           + (f" {'v50_mps':>8} {'v95_mps':>8} {'v<1mps':>7}" if moving else ""))
    lines.append(hdr)
    for mode in ("a", "b"):
        for cn0 in CN0S:
            for length in LENGTHS:
                sel = [r for r in rows if r["mode"] == mode and r["cn0"] == cn0 and r["length_ms"] == length]
                if not sel:
                    continue
                ok = [r for r in sel if r["ok"]]
                e = np.array([r["err3d_m"] for r in ok])
                t = np.abs(np.array([r["dtime_ms"] for r in ok]))
                v = np.array([r["vel_err_mps"] for r in ok])
                pct = (lambda a, q: f"{np.percentile(a, q):8.1f}" if a.size else f"{'-':>8}")
                tp = (lambda a, q: f"{np.percentile(a, q):9.2f}" if a.size else f"{'-':>9}")
                n_false = int(np.sum(e > FALSE_FIX_M))
                line = (f"{mode:>4} {cn0:5.0f} {length:6d} {len(ok):4d}/{len(sel):<4d} {len(sel) - len(ok):5d} "
                        f"{n_false:5d} {pct(e, 50)} {pct(e, 95)} "
                        f"{tp(t, 50)} {tp(t, 95)} {(100 * np.mean(t < 1.0) if t.size else 0):6.0f}%")
                if moving:
                    line += f" {pct(v, 50)} {pct(v, 95)} {(100 * np.mean(v < 1.0) if v.size else 0):6.0f}%"
                lines.append(line)
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trials", type=int, default=20, help="random places/times (each: every C/N0 and length)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--fs", type=float, default=4e6, help="sample rate (whole samples per ms)")
    ap.add_argument("--moving", action="store_true", help="receiver at 80-150 m/s")
    ap.add_argument("--max-length", type=int, default=100, help="longest snapshot (ms)")
    ap.add_argument("--cn0", type=float, nargs="*", default=list(CN0S))
    ap.add_argument("--lengths", type=int, nargs="*", default=list(LENGTHS), help="snapshot lengths (ms)")
    ap.add_argument("--search", choices=("all", "sky"), default="all",
                    help="PRNs searched: all with an ephemeris, or those above -5 deg at the truth (faster)")
    ap.add_argument("--out", type=str, default=None, help="JSON file of all rows")
    ap.add_argument("--table", type=str, nargs="*", default=None,
                    help="only print the table of JSON files of rows (several: their rows together)")
    args = ap.parse_args(argv)
    if args.table:
        rows, moving = [], False
        for path in args.table:
            with open(path) as fh:
                d = json.load(fh)
            n = len({r["trial"] for r in d["rows"]})
            print(f"{path}: {n} trials, seed {d['args']['seed']}, moving {d['args']['moving']}")
            rows += d["rows"]
            moving = moving or d["args"]["moving"]
        print(table(rows, moving))
        return
    if not os.path.exists(RINEX):
        sys.exit(f"needs {RINEX}")
    ephs = load_ephemerides(RINEX)
    rng = np.random.default_rng(args.seed)
    rows = []
    with tempfile.TemporaryDirectory(prefix="snapmc") as tmp:
        for i in range(args.trials):
            p = trial_params(rng, args.moving)
            for cn0 in args.cn0:
                rs = run_trial(p, cn0, args.fs, tmp, ephs, args.max_length, args.lengths, args.search)
                for r in rs:
                    r["trial"] = i
                rows += rs
                print(f"trial {i} C/N0 {cn0:g}: " + " ".join(
                    f"{r['length_ms']}{r['mode']}:{r.get('err3d_m', float('nan')):.0f}" for r in rs), flush=True)
            if args.out:
                with open(args.out, "w") as fh:
                    json.dump({"args": vars(args), "rows": rows}, fh)
    print(table(rows, args.moving))


if __name__ == "__main__":
    main()
