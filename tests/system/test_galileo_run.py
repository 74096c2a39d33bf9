"""Galileo E1 through ``gnssrx run`` (issue 33) on the project's simulator: a Galileo-only recording is acquired,
tracked (E1-C pilot, E1-B symbols), decoded (I/NAV) and positioned by the receiver pipeline -- the decoded
ephemerides equal the simulated ones within one LSB, the fixes are within a bound of the truth --; a GPS +
Galileo recording gives combined fixes with more satellites and a lower PDOP than GPS alone, and still fixes
with only three GPS satellites in the sky.  RTKLIB's single-point solutions (``rnx2rtkp -sys E`` / ``-sys
G,E``) on the RINEX files exported from the same runs agree with our fixes within 0.5 m at every epoch.

The scenarios start 0.5 s before GST second 20 of a 30-s I/NAV sub-frame: words 1, 3, 5 arrive first, words 2
and 4 at the next sub-frame's seconds 1-4, so a Galileo ephemeris is complete ~15.5 s after the first sample.
The recordings have no troposphere and the runs apply none, and the runs use ``navigation.weighting: rtklib``
(RTKLIB's single-point error model): both programs then solve the same equations, so any difference between
them is one of reading the files.  One recording and one run per system set serve every test of this module
(Galileo runs are the slow part).
"""
import shutil
import subprocess

import numpy as np
import pytest

from receiver.gnss.gal_inav import EPH_LSB
from receiver.gnss.satid import sat_key, sat_system
from receiver.runfile.reader import RunFile
from receiver.runfile.truth import TruthFile

from clirun import cli
from repo_paths import ROOT

pytestmark = pytest.mark.slow
TOW0 = 345619.5
WEEK = 2300
GAL_PRNS = [1, 2, 3, 5, 11, 12, 18, 19, 20]
needs_rnx2rtkp = pytest.mark.skipif(shutil.which("rnx2rtkp") is None,
                                    reason="RTKLIB rnx2rtkp not installed (apt-get install rtklib)")

def _simulate(tmp_path, scenario, duration, extra=()):
    from receiver.sim.simulate import simulate
    out = tmp_path / "rec.bin"
    simulate(ROOT / "configs" / "scenarios" / scenario, out,
             [("time.tow_s", TOW0), ("time.duration_s", duration), *extra], progress=False)
    return out


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


def _truth_ecef(rec):
    with TruthFile(str(rec)[:-4] + ".truth.h5") as tf:
        return np.asarray(tf.receiver(("ecef",))["ecef"], float).mean(axis=0)


def _export_rinex(h5):
    from receiver.export import export_all
    export_all(h5, {"rinex": True})


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


@pytest.fixture(scope="module")
def gal_only(tmp_path_factory):
    """configs/scenarios/static_galileo.yaml (no troposphere), 24 s from TOW0, run with configs/gal_e1_nav.yaml
    (RTKLIB weighting, no troposphere) and exported to RINEX: (recording, run file, truth, CLI stdout)."""
    d = tmp_path_factory.mktemp("gal_only")
    rec = _simulate(d, "static_galileo.yaml", 24.0, [("atmosphere.troposphere", "none")])
    out = d / "gal.h5"
    code, stdout, stderr = cli(["run", ROOT / "configs" / "gal_e1_nav.yaml", "--input", rec, "-o", out, "-q",
                                "--set", f"acquisition.prns={GAL_PRNS}", "--set", "navigation.weighting=rtklib",
                                "--set", "navigation.troposphere=none"])
    assert code == 0, stderr
    _export_rinex(out)
    return rec, out, _truth_ecef(rec), stdout


def test_galileo_only_run_decodes_and_fixes(gal_only):
    rec, out, truth, stdout = gal_only
    assert "E11(" in stdout
    with RunFile(out) as r:
        assert r.system == "E"
        names = r.channel_names()
        assert {"E01", "E02", "E03", "E11", "E12", "E18", "E19", "E20"} <= set(names) and "E05" not in names
        ch = r.channel("E11")
        assert np.all(np.diff(ch["code_period"]) == 1) and np.all(ch["integration_ms"] == 4)
        # the reported C/N0 is the whole E1 signal's (E1-B + E1-C), as simulated, within 1 dB
        with TruthFile(str(rec)[:-4] + ".truth.h5") as tf:
            sim_cn0 = {k: float(np.median(v["cn0_dbhz"])) for k, v in tf.satellites(("cn0_dbhz",)).items()}
        for name in names:
            c = r.channel(name, ("cn0_dbhz", "pll_lock"))
            assert abs(np.median(c["cn0_dbhz"][c["pll_lock"] == 1]) - sim_cn0[name]) < 1.0, name
        # decoded ephemerides against the simulated I/NAV content
        from receiver.sim.gal_constellation import gal_nominal_content
        sim = gal_nominal_content(ROOT / "data" / "gal_nominal_constellation.yaml", WEEK, TOW0)
        ephs = {e.prn: e for e in r.ephemerides()}
        assert len(ephs) >= 6
        for prn, e in ephs.items():
            s = sim[prn].eph
            assert e.week == s.week and e.iode == s.iode
            for name, lsb in EPH_LSB.items():
                assert abs(getattr(e, name) - getattr(s, name)) <= lsb, (prn, name)
        fixes = r.fixes()
        obs = r.observables()
    assert len(fixes) >= 30
    first = float(fixes["time_s"][0])
    assert first < 18.0                                   # ephemeris at ~15.5 s, then the settle time
    err = np.linalg.norm(fixes["ecef"] - truth, axis=1)
    assert np.sqrt(np.mean(err ** 2)) < 3.0 and np.max(err) < 6.0
    assert np.all(fixes["n_sats"] >= 6)
    assert set(np.unique(obs["prn"]).tolist()) <= {1, 2, 3, 11, 12, 18, 19, 20}


@needs_rnx2rtkp
def test_rnx2rtkp_galileo_only(gal_only, tmp_path):
    """Galileo E1 alone (rnx2rtkp -sys E): every epoch within 0.5 m of our fix."""
    _, h5, x_true, _ = gal_only
    rtk, run = _rnx2rtkp(h5, "E", tmp_path)
    d, same = _compare(rtk, run, x_true, "rnx2rtkp -sys E, Galileo-only run")
    assert same > 0.95
    assert np.nanmax(d) < 0.5


@pytest.fixture(scope="module")
def gps_gal(tmp_path_factory):
    """configs/scenarios/gps_gal_static.yaml (no troposphere), 33 s from 1 s before a 30-s boundary (LNAV
    ephemerides after ~19 s, I/NAV ones after ~28 s), and the truth position."""
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("gps_gal")
    rec = d / "rec.bin"
    simulate(ROOT / "configs" / "scenarios" / "gps_gal_static.yaml", rec,
             [("time.duration_s", 33.0), ("atmosphere.troposphere", "none")], progress=False)
    return rec, _truth_ecef(rec)


def _run_mixed(rec, out, extra=()):
    code, _, stderr = cli(["run", ROOT / "configs" / "gps_gal_bds_nav.yaml", "--input", rec, "-q", "-o", out,
                           "--set", "input.sample_rate_hz=4000000", "--set", "input.if_hz=0",
                           "--set", "navigation.troposphere=none", *extra])
    assert code == 0, stderr
    with RunFile(out) as r:
        return r.system, r.channel_names(), r.fixes(), r.observables(), r.ephemerides()


@pytest.fixture(scope="module")
def mixed(gps_gal, tmp_path_factory):
    """The GPS + Galileo run of the recording (RTKLIB weighting, the GPS Klobuchar set on both systems),
    exported to RINEX: (run file, (system, channel names, fixes, observables, ephemerides))."""
    rec, _ = gps_gal
    out = tmp_path_factory.mktemp("mixed") / "mixed.h5"
    res = _run_mixed(rec, out, ["--set", "signals=[gps_l1ca, gal_e1]", "--set", "navigation.weighting=rtklib",
                                "--set", "navigation.ionosphere=klobuchar"])
    _export_rinex(out)
    return out, res


def test_gps_galileo_run_combines_the_systems(gps_gal, mixed, tmp_path):
    rec, truth = gps_gal
    system, names, fixes, obs, ephs = mixed[1]
    assert system == "M"
    assert any(n.startswith("E") for n in names) and any(n.startswith("G") for n in names)
    assert any(getattr(e, "system", "G") == "E" for e in ephs)
    used = obs[obs["used_in_fix"] == 1]
    gal = used["prn"] > sat_key("E", 0)
    assert gal.any() and (~gal).any()                     # both systems in the fixes
    both = fixes[fixes["time_s"] >= float(np.min(used["time_s"][gal]))]
    assert len(both) >= 10
    err = np.linalg.norm(both["ecef"] - truth, axis=1)
    assert np.sqrt(np.mean(err ** 2)) < 2.0
    # the same recording, GPS alone: fewer satellites, a larger PDOP at the same epochs
    _, _, gps, _, _ = _run_mixed(rec, tmp_path / "gps.h5", [
        "--set", "signals=[]", "--set", "signal=gps_l1ca", "--set", "acquisition.prns_by_signal={}",
        "--set", "navigation.weighting=rtklib", "--set", "navigation.ionosphere=klobuchar"])
    t = np.intersect1d(np.round(both["gps_tow"], 2), np.round(gps["gps_tow"], 2))
    assert len(t) >= 5
    m = both[np.isin(np.round(both["gps_tow"], 2), t)]
    g = gps[np.isin(np.round(gps["gps_tow"], 2), t)]
    assert np.all(m["n_sats"] > g["n_sats"]) and np.all(m["pdop"] < g["pdop"])


@needs_rnx2rtkp
def test_rnx2rtkp_gps_galileo_mixed_files(gps_gal, mixed, tmp_path):
    """GPS + Galileo in one recording and one run (rnx2rtkp -sys G,E on the mixed M files, the GPS Klobuchar
    set of the navigation file's header correcting both systems in both programs): every epoch within 0.5 m
    of our fix (issue 33 acceptance)."""
    _, x_true = gps_gal
    h5 = mixed[0]
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
    o = run.obs
    gal = np.array([sat_system(int(p), run.system) == "E" for p in o["prn"]]) & (o["used_in_fix"] == 1)
    both = np.isin(run.fixes["time_s"], np.unique(o["time_s"][gal]))
    assert both.sum() >= 30 and np.all(np.isfinite(d[both]))
    print(f"  fixes with GPS and Galileo: {both.sum()}, |RTKLIB - gnssrx| 3D mean {d[both].mean():.3f} max "
          f"{d[both].max():.3f} m; GPS alone: {(~both).sum()}, mean {np.nanmean(d[~both]):.3f} max "
          f"{np.nanmax(d[~both]):.3f} m")


def test_three_gps_satellites_still_fix_with_galileo(gps_gal, tmp_path):
    rec, truth = gps_gal
    with TruthFile(str(rec)[:-4] + ".truth.h5") as tf:       # the GPS satellites with signal in the recording
        gps = sorted(int(k[1:]) for k, v in tf.satellites(("visible",)).items()
                     if k.startswith("G") and v["visible"].size and bool(v["visible"].any()))
    assert len(gps) > 3
    # only three of the GPS satellites searched (the receiver sees three GPS satellites)
    _, names, fixes, obs, _ = _run_mixed(rec, tmp_path / "three.h5", [
        "--set", "signals=[gps_l1ca, gal_e1]", "--set", f"acquisition.prns={gps[:3]}"])
    assert len([n for n in names if n.startswith("G")]) == 3
    used = obs[obs["used_in_fix"] == 1]
    assert len(set(used["prn"][used["prn"] < sat_key("E", 0)].tolist())) == 3
    assert len(fixes) >= 10
    err = np.linalg.norm(fixes["ecef"] - truth, axis=1)
    assert np.sqrt(np.mean(err ** 2)) < 3.0
