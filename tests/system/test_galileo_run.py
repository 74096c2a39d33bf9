"""Galileo E1 through ``gnssrx run`` (issue 33) on the project's simulator: a Galileo-only recording is acquired,
tracked (E1-C pilot, E1-B symbols), decoded (I/NAV) and positioned by the receiver pipeline -- the decoded
ephemerides equal the simulated ones within one LSB, the fixes are within a bound of the truth --; a GPS +
Galileo recording gives combined fixes with more satellites and a lower PDOP than GPS alone, and still fixes
with only three GPS satellites in the sky.

The scenarios start 0.5 s before GST second 20 of a 30-s I/NAV sub-frame: words 1, 3, 5 arrive first, words 2
and 4 at the next sub-frame's seconds 1-4, so a Galileo ephemeris is complete ~15.5 s after the first sample.
"""
import numpy as np
import pytest

from receiver.gnss.gal_inav import EPH_LSB
from receiver.gnss.satid import sat_key
from receiver.runfile.reader import RunFile
from receiver.runfile.truth import TruthFile

from clirun import cli
from repo_paths import ROOT

pytestmark = pytest.mark.slow
TOW0 = 345619.5
WEEK = 2300


def _simulate(tmp_path, scenario, duration, extra=()):
    from receiver.sim.simulate import simulate
    out = tmp_path / "rec.bin"
    simulate(ROOT / "configs" / "scenarios" / scenario, out,
             [("time.tow_s", TOW0), ("time.duration_s", duration), *extra], progress=False)
    return out


def _truth_ecef(rec):
    with TruthFile(str(rec)[:-4] + ".truth.h5") as tf:
        return np.asarray(tf.receiver(("ecef",))["ecef"], float).mean(axis=0)


def test_galileo_only_run_decodes_and_fixes(tmp_path):
    rec = _simulate(tmp_path, "static_galileo.yaml", 21.0)
    out = tmp_path / "gal.h5"
    code, stdout, stderr = cli(["run", ROOT / "configs" / "gal_e1_nav.yaml", "--input", rec, "-o", out, "-q",
                                "--set", "acquisition.prns=[1, 2, 3, 5, 11, 12, 18, 19, 20]"])
    assert code == 0, stderr
    assert "E11(" in stdout
    with RunFile(out) as r:
        assert r.system == "E"
        names = r.channel_names()
        assert {"E01", "E02", "E03", "E11", "E12", "E18", "E19", "E20"} <= set(names) and "E05" not in names
        ch = r.channel("E11")
        assert np.all(np.diff(ch["code_period"]) == 1) and np.all(ch["integration_ms"] == 4)
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
    err = np.linalg.norm(fixes["ecef"] - _truth_ecef(rec), axis=1)
    assert np.sqrt(np.mean(err ** 2)) < 3.0 and np.max(err) < 6.0
    assert np.all(fixes["n_sats"] >= 6)
    assert set(np.unique(obs["prn"]).tolist()) <= {1, 2, 3, 11, 12, 18, 19, 20}


@pytest.fixture(scope="module")
def gps_gal(tmp_path_factory):
    """configs/scenarios/gps_gal_static.yaml, 32 s from 1 s before a 30-s boundary (LNAV ephemerides after
    ~19 s, I/NAV ones after ~28 s), and the truth position."""
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("gps_gal")
    rec = d / "rec.bin"
    simulate(ROOT / "configs" / "scenarios" / "gps_gal_static.yaml", rec, [("time.duration_s", 32.0)],
             progress=False)
    return rec, _truth_ecef(rec)


def _run_mixed(rec, out, extra=()):
    code, _, stderr = cli(["run", ROOT / "configs" / "gps_gal_bds_nav.yaml", "--input", rec, "-q", "-o", out,
                           "--set", "input.sample_rate_hz=4000000", "--set", "input.if_hz=0", *extra])
    assert code == 0, stderr
    with RunFile(out) as r:
        return r.system, r.channel_names(), r.fixes(), r.observables(), r.ephemerides()


def test_gps_galileo_run_combines_the_systems(gps_gal, tmp_path):
    rec, truth = gps_gal
    system, names, mixed, obs, ephs = _run_mixed(rec, tmp_path / "mixed.h5", ["--set", "signals=[gps_l1ca, gal_e1]"])
    assert system == "M"
    assert any(n.startswith("E") for n in names) and any(n.startswith("G") for n in names)
    assert any(getattr(e, "system", "G") == "E" for e in ephs)
    used = obs[obs["used_in_fix"] == 1]
    gal = used["prn"] > sat_key("E", 0)
    assert gal.any() and (~gal).any()                     # both systems in the fixes
    both = mixed[mixed["time_s"] >= float(np.min(used["time_s"][gal]))]
    assert len(both) >= 10
    err = np.linalg.norm(both["ecef"] - truth, axis=1)
    assert np.sqrt(np.mean(err ** 2)) < 2.0
    # the same recording, GPS alone: fewer satellites, a larger PDOP at the same epochs
    _, _, gps, _, _ = _run_mixed(rec, tmp_path / "gps.h5", ["--set", "signals=[]", "--set", "signal=gps_l1ca",
                                                         "--set", "acquisition.prns_by_signal={}"])
    t = np.intersect1d(np.round(both["gps_tow"], 2), np.round(gps["gps_tow"], 2))
    assert len(t) >= 5
    m = both[np.isin(np.round(both["gps_tow"], 2), t)]
    g = gps[np.isin(np.round(gps["gps_tow"], 2), t)]
    assert np.all(m["n_sats"] > g["n_sats"]) and np.all(m["pdop"] < g["pdop"])


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
