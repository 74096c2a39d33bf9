"""Scalar vs vector tracking on BeiDou B1I, GPS + BeiDou and GPS + QZSS recordings (README "Vector loops on
every system").

    PYTHONPATH=. python scripts/bench/accuracy_vector_gnss.py OUTDIR            # 25 s, every satellite in view,
    handover 10 s
    PYTHONPATH=. python scripts/bench/accuracy_vector_gnss.py OUTDIR --short    # tests/system/test_vector_gnss.py's
    7-s scenarios

Simulates (45 dB-Hz, static Tokyo, 5 MS/s complex baseband, one file per signal recorded at the same instant;
QZSS case: 42 dB-Hz, 2.6 MS/s), writes the simulator's ephemerides as RINEX (assisted mode, mixed file for
GPS + BeiDou) and runs each case scalar only and with the vector loop (adaptive_r; T = 1 and 5 ms),
printing the fixes' 3D error against the truth after the handover.  OUTDIR receives ~1.5 GB (25 s).
"""
import argparse
import os
from pathlib import Path

import h5py
import numpy as np

REPO = Path(__file__).resolve().parents[2]

from receiver.batch.tasks import write_nav_for_scenario  # noqa: E402
from receiver.schema import load_receiver_config  # noqa: E402
from receiver.gnss.rinex import read_rinex_nav, write_rinex_nav  # noqa: E402
from receiver.pipeline import run  # noqa: E402
from receiver.sim.simulate import simulate  # noqa: E402

COMMON = """time: {{gps_week: 2300, tow_s: 345600.0, duration_s: {dur}, seed: 7}}
receiver: {{trajectory: static, lat_deg: 35.681298, lon_deg: 139.766247, height_m: 10.0}}
clock: {{bias_s: 2.5e-4, freq_error_ppm: 0.5, noise: tcxo}}
cn0: {{mode: constant, dbhz: 45.0}}
frontend: {{sample_rate_hz: 5000000.0, if_hz: 0.0, format: int8_iq}}
"""
QZSS = """time: {{gps_week: 2300, tow_s: 345597.0, duration_s: {dur}, seed: 4}}
constellation: {{source: embedded, elevation_mask_deg: 5.0, qzss: true, prns: [1, 7, 11, 15, 24, 193, 194, 195, 199]}}
receiver: {{trajectory: static, lat_deg: 35.68, lon_deg: 139.77, height_m: 40.0}}
clock: {{bias_s: 1.0e-4, freq_error_ppm: 0.1, noise: tcxo}}
cn0: {{mode: constant, dbhz: 42.0}}
frontend: {{sample_rate_hz: 2600000.0, if_hz: 0.0, format: int8_iq}}
"""


def simulate_case(d, name, text):
    sc = d / f"{name}.yaml"
    sc.write_text(text)
    (d / "sim").mkdir(exist_ok=True)
    simulate(str(sc), str(d / "sim" / f"{name}.bin"), progress=False)
    write_nav_for_scenario(str(sc), str(d / f"{name}.nav"))
    return d / "sim" / f"{name}.bin", d / f"{name}.nav", d / "sim" / f"{name}.truth.h5"


def errors(out, truth):
    with h5py.File(out, "r") as f, h5py.File(truth, "r") as t:
        if "navigation" not in f or "time_s" not in f["navigation"]:
            return (np.zeros(0),) * 5
        g = f["navigation"]
        ts = g["time_s"][:]
        tt, te = t["receiver"]["time_s"][:], t["receiver"]["ecef"][:]
        ref = np.stack([np.interp(ts, tt, te[:, a]) for a in range(3)], axis=1)
        return ts, g["mode"][:], np.linalg.norm(g["ecef"][:] - ref, axis=1), g["n_sats"][:], g["velocity_ecef"][:]


def rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if len(x) else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("outdir")
    ap.add_argument("--short", action="store_true", help="the 7-s scenarios of tests/system/test_vector_gnss.py")
    a = ap.parse_args()
    d = Path(a.outdir)
    d.mkdir(parents=True, exist_ok=True)
    dur, start, later = (7.0, 3.5, 5.5) if a.short else (25.0, 10.0, 15.0)
    gps_sel = "prns: [7, 11, 24]" if a.short else "elevation_mask_deg: 10.0"
    bds_sel = "prns: [1, 3, 6, 9, 20, 24, 25]" if a.short else "elevation_mask_deg: 10.0"
    gps = simulate_case(d, "l1", COMMON.format(dur=dur) + f"constellation: {{source: embedded, {gps_sel}}}\n")
    bds = simulate_case(d, "b1", "signal: bds_b1i\n" + COMMON.format(dur=dur) +
                        f"constellation: {{source: bds_nominal, {bds_sel}}}\n")
    qz = simulate_case(d, "qz", QZSS.format(dur=dur))
    g, iono = read_rinex_nav(str(d / "l1.nav"))
    b, _ = read_rinex_nav(str(d / "b1.nav"), systems=("C",))
    write_rinex_nav(str(d / "mixed.nav"), [e for lst in (*g.values(), *b.values()) for e in lst], iono)
    gp, bp, qp = list(range(1, 33)), list(range(1, 64)), [1, 7, 11, 15, 24, 193, 194, 195, 199]
    cases = {
        "BeiDou only": (bds[2], [("signal", "bds_b1i"), ("input.path", str(bds[0])),
                                 ("navigation.ephemeris", str(bds[1])), ("acquisition.prns", bp)]),
        "GPS only": (gps[2], [("input.path", str(gps[0])), ("navigation.ephemeris", str(gps[1])),
                              ("acquisition.prns", gp)]),
        "GPS + BeiDou": (bds[2], [("signals", ["gps_l1ca", "bds_b1i"]), ("input.path", str(gps[0])),
                                  ("navigation.ephemeris", str(d / "mixed.nav")),
                                  ("input.signal_files", {"bds_b1i": {"path": str(bds[0]), "if_hz": 0.0}}),
                                  ("acquisition.prns", gp), ("acquisition.prns_by_signal", {"bds_b1i": bp})]),
        "GPS + QZSS": (qz[2], [("input.path", str(qz[0])), ("input.sample_rate_hz", 2.6e6),
                               ("input.start_gps_tow_s", 345597.0), ("navigation.ephemeris", str(qz[1])),
                               ("acquisition.prns", qp)]),
    }
    print(f"{dur:g}-s recordings, handover at {start:g} s; 3D error over t > {start + 0.2:g} s "
          f"(and t > {later:g} s)")
    for name, (truth, sets) in cases.items():
        for vec, T in ((False, 1), (True, 1), (True, 5)):
            out = d / f"{name.replace(' ', '').replace('+', '_')}_{'v' if vec else 's'}{T}.h5"
            cfg = load_receiver_config(REPO / "configs/gps_bds_nav.yaml", [
                ("signals", []), ("input.sample_rate_hz", 5e6), ("input.if_hz", 0.0),
                ("input.start_gps_week", 2300), ("input.start_gps_tow_s", 345600.0), ("output.path", str(out)),
                ("vector.enabled", vec), ("vector.start_s", start), ("vector.integration_ms", T), *sets])
            cwd = os.getcwd()
            try:
                os.chdir(d)
                run(cfg, quiet=True, log=lambda *x: None)
            finally:
                os.chdir(cwd)
            ts, mode, err, nsat, vel = errors(out, truth)
            k, late = ts > start + 0.2, ts > later
            tag = f"vector T={T} ms" if vec else "scalar"
            if not k.any():
                print(f"{name:13s} {tag:15s} no fix", flush=True)
                continue
            print(f"{name:13s} {tag:15s} fixes {k.sum():4d} modes {sorted(set(mode[k].tolist()))} "
                  f"sats {np.median(nsat[k]):4.1f}  3D RMS {rms(err[k]):.3f} m (max {err[k].max():.2f} m), "
                  f"later {rms(err[late]):.3f} m  vel RMS {rms(np.linalg.norm(vel[k], axis=1)):.3f} m/s",
                  flush=True)


if __name__ == "__main__":
    main()
