"""RTKLIB's single-point solutions on gnssrx's RINEX files of Galileo runs (issue 33 acceptance: rnx2rtkp
-sys G,E on our mixed RINEX within 0.5 m of our own fixes).

Our simulator makes the recording (no troposphere, and no ionosphere or the GPS Klobuchar one on every
satellite; the receiver and RTKLIB then apply the same models -- none, or Klobuchar from the navigation file's
header --, so both programs solve the same equations and any difference is one of reading the files);
``gnssrx run`` makes the fixes with ``navigation.weighting: rtklib`` (RTKLIB's single-point error model);
the exported observation + navigation files go to ``rnx2rtkp`` with the run's elevation mask, broadcast
ephemerides; the RTKLIB solution of every epoch is compared with our fix of that epoch.
"""
import shutil
import subprocess

import numpy as np
import pytest

from repo_paths import ROOT

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(shutil.which("rnx2rtkp") is None,
                                 reason="RTKLIB rnx2rtkp not installed (apt-get install rtklib)")]

#: RTKLIB navsys bits
NAVSYS = {"G": 1, "E": 8, "J": 16, "C": 32}
RTKLIB_CONF = """\
pos1-posmode       =single
pos1-frequency     =l1
pos1-soltype       =forward
pos1-elmask        ={elmask}
pos1-ionoopt       ={iono}
pos1-tropopt       ={trop}
pos1-sateph        =brdc
pos1-navsys        ={navsys}
out-solformat      =xyz
out-outhead        =on
out-timesys        =gpst
out-timeform       =tow
out-timendec       =6
"""


def _record_and_run(d, scenario, receiver, sim_over, rx_over):
    """Simulate ``scenario`` into ``d``, run ``receiver`` on it, export RINEX; returns (run file, truth ecef)."""
    import h5py

    from receiver.export import export_all
    from receiver.pipeline import run
    from receiver.schema import load_receiver_config
    from receiver.sim.simulate import simulate
    rec = d / "rec.bin"
    simulate(str(ROOT / scenario), str(rec), overrides=sim_over, progress=False)
    h5 = d / "run.h5"
    cfg = load_receiver_config(ROOT / receiver, [f"input.path={rec}", f"output.path={h5}",
                                                 "navigation.weighting=rtklib", "navigation.troposphere=none",
                                                 "navigation.ionosphere=none"] + rx_over)
    run(cfg, quiet=True, log=lambda *a: None)
    export_all(h5, {"rinex": True})
    with h5py.File(d / "rec.truth.h5", "r") as t:
        x_true = t["receiver"]["ecef"][0]
    rec.unlink()                                     # hundreds of MB: keep only the run file and its outputs
    return h5, x_true


def _rnx2rtkp(h5, systems: str, d):
    """RTKLIB's solutions (week, tow, x, y, z, Q, ns, ...) of the run's exported files, its settings as the run's."""
    from receiver.runfile.reader import load_run
    r = load_run(h5)
    conf = d / "spp.conf"
    conf.write_text(RTKLIB_CONF.format(
        elmask=r.cfg("navigation.elevation_mask_deg"),
        iono="brdc" if r.cfg("navigation.ionosphere") == "klobuchar" else "off",
        trop="saas" if r.cfg("navigation.troposphere") == "saastamoinen" else "off",
        navsys=sum(NAVSYS[s] for s in systems.split(","))))
    pos = d / "spp.pos"
    cmd = ["rnx2rtkp", "-k", str(conf), "-sys", systems, "-o", str(pos), str(h5.with_suffix(".obs")),
           str(h5.with_suffix(".nav"))]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    return np.loadtxt(pos, comments="%", ndmin=2), r


def _compare(rtk, run, x_true, label):
    """3D differences RTKLIB - gnssrx per fix (NaN: no RTKLIB solution at that epoch), the share of epochs where
    both used as many satellites; prints the numbers (and each against the truth)."""
    fx = run.fixes
    assert len(fx) >= 10
    rtk = rtk[rtk[:, 5] == 5]                                   # single-point solutions
    k = np.abs(fx["gps_tow"][:, None] - rtk[None, :, 1]).argmin(axis=1)
    ok = np.abs(fx["gps_tow"] - rtk[k, 1]) < 1e-3
    assert ok.mean() > 0.95, f"{ok.sum()} of {len(fx)} fixes have an RTKLIB solution"
    d = np.where(ok, np.linalg.norm(fx["ecef"] - rtk[k, 2:5], axis=1), np.nan)
    same_sats = float(np.mean(rtk[k[ok], 6].astype(int) == fx["n_sats"][ok]))
    e_ours = np.linalg.norm(fx["ecef"][ok] - x_true, axis=1)
    e_rtk = np.linalg.norm(rtk[k[ok], 2:5] - x_true, axis=1)
    print(f"\n{label}: {ok.sum()} epochs, satellites {np.median(fx['n_sats']):.0f} (median; same count in "
          f"{100 * same_sats:.0f} % of epochs); |RTKLIB - gnssrx| 3D mean {np.nanmean(d):.3f} max "
          f"{np.nanmax(d):.3f} m; 3D RMS vs truth gnssrx {np.sqrt(np.mean(e_ours ** 2)):.3f} m, RTKLIB "
          f"{np.sqrt(np.mean(e_rtk ** 2)):.3f} m")
    return d, same_sats


def test_rnx2rtkp_galileo_only(tmp_path):
    """Galileo E1 alone (rnx2rtkp -sys E): every epoch within 0.5 m of our fix."""
    h5, x_true = _record_and_run(tmp_path, "configs/scenarios/static_galileo.yaml", "configs/gal_e1_nav.yaml",
                                 ["time.duration_s=29", "atmosphere.troposphere=none"], [])
    rtk, run = _rnx2rtkp(h5, "E", tmp_path)
    d, same = _compare(rtk, run, x_true, "rnx2rtkp -sys E, Galileo-only run")
    assert same > 0.95
    assert np.nanmax(d) < 0.5


def test_rnx2rtkp_gps_galileo_mixed_files(tmp_path):
    """GPS + Galileo in one recording and one run (rnx2rtkp -sys G,E on the mixed M files, the GPS Klobuchar
    set of the navigation file's header correcting both systems in both programs): every epoch within 0.5 m
    of our fix (issue 33 acceptance)."""
    h5, x_true = _record_and_run(
        tmp_path, "configs/scenarios/gps_gal_static.yaml", "configs/gps_gal_bds_nav.yaml",
        ["time.duration_s=33", "atmosphere.troposphere=none"],
        ["signals=[gps_l1ca, gal_e1]", "input.sample_rate_hz=4000000", "input.if_hz=0",
         "navigation.ionosphere=klobuchar"])
    obs_text = h5.with_suffix(".obs").read_text()
    assert obs_text.splitlines()[0][40:41] == "M"
    assert "E    4 C1C L1C D1C S1C" in obs_text and "G    4 C1C L1C D1C S1C" in obs_text
    rtk, run = _rnx2rtkp(h5, "G,E", tmp_path)
    letters = {ln[:1] for ln in obs_text.splitlines() if ln[:1] in "GE" and ln[1:3].isdigit()}
    assert letters == {"G", "E"}
    d, same = _compare(rtk, run, x_true, "rnx2rtkp -sys G,E, GPS + Galileo run")
    assert same > 0.95
    assert np.nanmax(d) < 0.5
    # the epochs whose fix used both systems (the I/NAV ephemerides come ~9 s after the LNAV ones)
    from receiver.gnss.satid import sat_system
    o = run.obs
    gal = np.array([sat_system(int(p), run.system) == "E" for p in o["prn"]]) & (o["used_in_fix"] == 1)
    both = np.isin(run.fixes["time_s"], np.unique(o["time_s"][gal]))
    assert both.sum() >= 30 and np.all(np.isfinite(d[both]))
    print(f"  fixes with GPS and Galileo: {both.sum()}, |RTKLIB - gnssrx| 3D mean {d[both].mean():.3f} max "
          f"{d[both].max():.3f} m; GPS alone: {(~both).sum()}, mean {np.nanmean(d[~both]):.3f} max "
          f"{np.nanmax(d[~both]):.3f} m")
