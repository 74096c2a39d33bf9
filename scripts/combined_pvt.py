"""Combined GPS + BeiDou single-point fixes from two runs over simultaneous recordings (issue 21, step 3).

(One run can now track both signals: `signals: [gps_l1ca, bds_b1i]`, scripts/multi_acceptance.py.)  This
script combines the observables of a GPS L1 C/A run and a BeiDou B1I run
of the same receiver and clock (e.g. two simulations with the same time, clock and seed) epoch by epoch and
solves them with receiver.navigation.pvt.NavSolver, which estimates one receiver clock plus an inter-system
bias for BeiDou (Observation.system).  The BeiDou pseudoranges are referred to the GPS run's receiver clock
reading of the same epoch: the constant offset between the two runs' clock readings is absorbed by the
inter-system bias.  BeiDou PRN p is satellite 400 + p in the combined epoch.

Prints, for GPS only / BeiDou only / GPS + BeiDou / GPS reduced to N satellites (highest elevation) +
BeiDou / GPS reduced alone: epochs with a fix, mean satellites used, mean PDOP, 3D RMS against the truth.

With ``--rinex DIR``: writes the combined epochs as a mixed RINEX 3 observation file (G + C) and a mixed
navigation file, solves them with RTKLIB's rnx2rtkp (-sys G,C) when installed and prints the distance to
the combined fixes, and writes NMEA (talker GN).

    PYTHONPATH=. python scripts/combined_pvt.py GPS.h5 BDS.h5 TRUTH.truth.h5 [--gps-max 3] [--rinex DIR]
"""
from __future__ import annotations

import argparse
import os
import sys
import types

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from receiver.gnss.registry import get_signal  # noqa: E402
from receiver.gnss.signals import C_LIGHT  # noqa: E402
from receiver.navigation.pvt import NavSolver, Observation  # noqa: E402
from receiver.runfile.reader import load_run  # noqa: E402
from receiver.runfile.truth import load_truth  # noqa: E402

BDS_KEY = 400


def epochs(run, system, key_offset, wavelength):
    """round(gps_tow, ms) -> [rx clock reading, week, rows, obs row indices]."""
    o, rx = run.obs, run.rx_tow()
    out = {}
    for i in range(len(o)):
        k = round(float(o["gps_tow"][i]), 3)
        e = out.get(k)
        if e is None or abs(float(o["time_s"][e[3][0]]) - float(o["time_s"][i])) > 1e-6:
            # a new epoch (the first fix's epoch and the next may fall on the same millisecond: keep the later)
            e = out[k] = [float(rx[i]), int(o["gps_week"][i]), [], []]
        e[2].append((int(o["prn"][i]) + key_offset, float(o["pseudorange_m"][i]), float(o["doppler_hz"][i]),
                     float(o["cn0_dbhz"][i]), float(o["elevation_deg"][i]), system, wavelength))
        e[3].append(i)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("gps_run")
    ap.add_argument("bds_run")
    ap.add_argument("truth")
    ap.add_argument("--gps-max", type=int, default=3)
    ap.add_argument("--rinex", default=None, help="directory for the mixed RINEX / NMEA files")
    a = ap.parse_args(argv)
    rg, rc = load_run(a.gps_run), load_run(a.bds_run)
    truth = load_truth(a.truth)
    x_true = np.asarray(truth["ecef"][0], float) if isinstance(truth, dict) else None
    if x_true is None:
        import h5py
        with h5py.File(a.truth, "r") as f:
            x_true = f["receiver"]["ecef"][0]
    ephs = {e.prn: e for e in rg.ephemerides}
    ephs.update({BDS_KEY + e.prn: e for e in rc.ephemerides})
    iono = rg.iono()
    cfg = types.SimpleNamespace(**{k: rg.cfg(f"navigation.{k}") for k in
                                   ("elevation_mask_deg", "weighting", "troposphere", "ionosphere",
                                    "residual_threshold_m", "max_pdop")})
    eg = epochs(rg, "G", 0, C_LIGHT / get_signal("gps_l1ca").carrier_hz)
    ec = epochs(rc, "C", BDS_KEY, C_LIGHT / get_signal("bds_b1i").carrier_hz)
    common = sorted(set(eg) & set(ec))
    cases = {"GPS only": [], "BeiDou only": [], "GPS + BeiDou": [],
             f"GPS {a.gps_max} + BeiDou": [], f"GPS {a.gps_max} alone": []}
    solver = NavSolver(cfg)
    merged_obs, merged_fix = [], []
    for k in common:
        rx, week, g, ig = eg[k]
        _, _, c, ic = ec[k]
        g3 = sorted(g, key=lambda r: -r[4])[:a.gps_max]

        def obs(rows):
            return [Observation(prn=p, tx_tow=rx - pr / C_LIGHT, doppler_hz=d, cn0_dbhz=cn, system=sy,
                                wavelength_m=lam) for p, pr, d, cn, el, sy, lam in rows]
        for name, rows in (("GPS only", g), ("BeiDou only", c), ("GPS + BeiDou", g + c),
                           (f"GPS {a.gps_max} + BeiDou", g3 + c), (f"GPS {a.gps_max} alone", g3)):
            f = solver.fix(week, rx, obs(rows), ephs, iono, x0=x_true + 100.0)
            cases[name].append(None if f is None else (np.linalg.norm(f.ecef - x_true), f.n_sats, f.pdop,
                                                       f.isb_m.get("C", np.nan)))
            if name == "GPS + BeiDou" and f is not None:
                merged_fix.append((f, float(rg.obs["time_s"][ig[0]])))
                for run, rows, off in ((rg, ig, 0), (rc, ic, BDS_KEY)):
                    r = run.obs[rows].copy()
                    r["prn"] += off
                    r["time_s"] = rg.obs["time_s"][ig[0]]
                    r["gps_tow"], r["gps_week"], r["epoch"] = f.gps_tow, f.gps_week, len(merged_fix) - 1
                    r["used_in_fix"] = np.isin(r["prn"], f.prns)
                    merged_obs.append(r)
    print(f"{len(common)} common epochs ({a.gps_run} + {a.bds_run})")
    print(f"{'case':22s} {'fixes':>6s} {'sats':>5s} {'PDOP':>6s} {'3D RMS m':>9s} {'ISB C m (std)':>15s}")
    for name, res in cases.items():
        ok = [r for r in res if r is not None]
        if not ok:
            print(f"{name:22s} {0:6d}")
            continue
        d = np.array([r[0] for r in ok])
        isb = np.array([r[3] for r in ok])
        isb_s = f"{np.nanmean(isb):8.2f} ({np.nanstd(isb):.2f})" if np.isfinite(isb).any() else ""
        print(f"{name:22s} {len(ok):6d} {np.mean([r[1] for r in ok]):5.1f} {np.mean([r[2] for r in ok]):6.2f} "
              f"{np.sqrt(np.mean(d ** 2)):9.3f} {isb_s:>15s}")


    if a.rinex:
        write_mixed(a, rg, merged_obs, merged_fix, list(ephs.values()), iono)


def write_mixed(a, rg, merged_obs, merged_fix, ephs, iono):
    """Mixed RINEX 3 obs + nav and NMEA of the combined epochs; rnx2rtkp -sys G,C against our fixes."""
    import shutil
    import subprocess
    from dataclasses import replace as dc_replace

    from receiver.export.nmea import write_nmea
    from receiver.export.rinex_obs import write_rinex_obs
    from receiver.gnss.geodesy import ecef2lla
    from receiver.gnss.rinex import write_rinex_nav
    from receiver.runfile.record import FIX_DTYPE, IONO_BROADCAST, IONO_NONE
    os.makedirs(a.rinex, exist_ok=True)
    fx = np.zeros(len(merged_fix), FIX_DTYPE)
    iono_params = IONO_BROADCAST if iono is not None and rg.cfg("navigation.ionosphere", "klobuchar") == "klobuchar" else IONO_NONE
    for i, (f, t_s) in enumerate(merged_fix):
        lat, lon, h = ecef2lla(f.ecef)
        fx[i] = (f.gps_week, f.gps_tow, t_s, f.ecef, f.velocity_ecef, f.clock_bias_m, f.clock_drift_mps,
                 f.n_sats, f.pdop, f.hdop, f.vdop, f.gdop, 0, lat, lon, h, iono_params)
    run = dc_replace(rg, path=os.path.join(a.rinex, "combined.h5"), fixes=fx, obs=np.concatenate(merged_obs),
                     ephemerides=ephs, _used=None)
    obs_path, nav_path = os.path.join(a.rinex, "combined.obs"), os.path.join(a.rinex, "combined.nav")
    write_rinex_obs(obs_path, run)
    write_rinex_nav(nav_path, ephs, iono)
    write_nmea(os.path.join(a.rinex, "combined.nmea"), run)
    print(f"mixed RINEX: {obs_path}, {nav_path}")
    if shutil.which("rnx2rtkp") is None:
        return
    conf = os.path.join(a.rinex, "spp.conf")
    with open(conf, "w") as fh:
        fh.write(f"pos1-posmode=single\npos1-frequency=l1\npos1-elmask={rg.cfg('navigation.elevation_mask_deg')}\n"
                 "pos1-ionoopt=brdc\npos1-tropopt=saas\npos1-sateph=brdc\npos1-navsys=33\n"
                 "out-solformat=xyz\nout-timesys=gpst\nout-timeform=tow\nout-timendec=6\n")
    pos = os.path.join(a.rinex, "spp.pos")
    subprocess.run(["rnx2rtkp", "-k", conf, "-sys", "G,C", "-o", pos, obs_path, nav_path],
                   capture_output=True, check=True)
    rtk = np.loadtxt(pos, comments="%", ndmin=2)
    rtk = rtk[rtk[:, 5] == 5]
    k = np.abs(fx["gps_tow"][:, None] - rtk[None, :, 1]).argmin(axis=1)
    ok = np.abs(fx["gps_tow"] - rtk[k, 1]) < 1e-3
    d = np.linalg.norm(fx["ecef"][ok] - rtk[k[ok], 2:5], axis=1)
    print(f"rnx2rtkp -sys G,C: {ok.sum()} / {len(fx)} epochs, satellites {np.unique(rtk[:, 6]).astype(int)}; "
          f"|gnssrx - RTKLIB| median {np.median(d):.3f} RMS {np.sqrt(np.mean(d ** 2)):.3f} max {d.max():.3f} m")


if __name__ == "__main__":
    main()
