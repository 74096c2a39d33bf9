"""One run over several signals (issue 21): GPS L1 C/A + BeiDou B1I from one wideband recording (complex, 20 MS/s,
centred between L1 and B1I), satellite keys (BeiDou PRN p -> 400 + p), the config checks."""
import h5py
import pytest

from receiver.schema import load_receiver_config, run_signals, signal_prns
from receiver.errors import UserError
from receiver.gnss.satid import MIXED, parse_label, sat_key, sat_label, sat_system, split_key

from repo_paths import ROOT as REPO


def test_satellite_keys():
    assert sat_key("C", 12) == 412 and sat_key("G", 12) == 12 and sat_key("G", 193) == 193
    assert split_key(412) == ("C", 12) and split_key(5) == ("G", 5) and split_key(195) == ("G", 195)
    assert [sat_label(k, MIXED) for k in (5, 195, 412)] == ["G05", "J03", "C12"]
    assert [sat_system(k, MIXED) for k in (5, 195, 412)] == ["G", "J", "C"]
    assert sat_label(12, "C") == "C12" and parse_label("C12") == ("C", 12)


def test_signals_config():
    cfg = load_receiver_config(REPO / "configs/gps_bds_nav.yaml")
    assert run_signals(cfg) == ["gps_l1ca", "bds_b1i"]
    assert signal_prns(cfg, "gps_l1ca") == list(range(1, 33))
    assert signal_prns(cfg, "bds_b1i") == list(range(1, 64))
    cfg = load_receiver_config(REPO / "configs/gps_bds_nav.yaml", ["acquisition.prns_by_signal={bds_b1i: [6, 7]}"])
    assert signal_prns(cfg, "bds_b1i") == [6, 7]
    assert run_signals(load_receiver_config(None)) == ["gps_l1ca"]          # `signals` empty: `signal`
    assert run_signals(load_receiver_config(REPO / "configs/gps_bds_nav.yaml", ["signals=[gps_l1ca, gal_e1]"])) \
        == ["gps_l1ca", "gal_e1"]
    for bad, msg in ((["signals=[gps_l1ca, gal_e5a]"], "signals"), (["signals=[gps_l1ca, gps_l1ca]"], "twice"),
                     (["acquisition.prns_by_signal={bds_b1i: [64]}"], "prns_by_signal.bds_b1i"),
                     (["acquisition.prns_by_signal={gal_e1: [1]}"], "not one of the run's signals")):
        with pytest.raises(UserError, match=msg):
            load_receiver_config(REPO / "configs/gps_bds_nav.yaml", bad)
    # the vector loops track GPS + BeiDou runs (tests/system/test_vector_gnss.py); a signal they do not know is
    # refused in one line
    assert load_receiver_config(REPO / "configs/gps_bds_nav.yaml", ["vector.enabled=true"]).vector.enabled
    import receiver.tracking.vector.config as C
    known = C.VECTOR_SIGNALS
    try:
        C.VECTOR_SIGNALS = ("gps_l1ca",)
        with pytest.raises(UserError, match="vector.enabled.*not bds_b1i"):
            load_receiver_config(REPO / "configs/gps_bds_nav.yaml", ["vector.enabled=true"])
    finally:
        C.VECTOR_SIGNALS = known
    # and GPS + Galileo + BeiDou ones (Galileo E1: tests/system/test_vector_galileo_run.py)
    assert load_receiver_config(REPO / "configs/gps_gal_bds_nav.yaml", ["vector.enabled=true"]).vector.enabled


@pytest.fixture(scope="module")
def wideband(tmp_path_factory):
    """1.5 s of GPS G11, G24 and BeiDou C04 (GEO, D2), C08 (IGSO, D1) in one 20 MS/s recording, and its run."""
    from receiver.pipeline import run
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("multi")
    out = d / "gb.bin"
    simulate(str(REPO / "configs/scenarios/gps_bds_static_tokyo.yaml"), str(out),
             overrides=["time.duration_s=1.5", "constellation.prns=[11, 24, 404, 408]"], progress=False)
    cfg = load_receiver_config(REPO / "configs/gps_bds_nav.yaml",
                               [f"input.path={out}", f"output.path={d / 'gb.h5'}", "acquisition.prns=[11, 24]",
                                "acquisition.prns_by_signal={bds_b1i: [4, 8]}", "navigation.enabled=false"])
    summary = run(cfg, quiet=True, log=lambda *a: None)
    return d, out, summary


def test_one_run_tracks_both_systems(wideband):
    d, out, summary = wideband
    assert summary.tracked == [11, 24, 404, 408] and summary.system == MIXED
    assert "G11(" in summary.text() and "C04(" in summary.text()
    with h5py.File(d / "gb.h5", "r") as f, h5py.File(str(out)[:-4] + ".truth.h5", "r") as t:
        assert f.attrs["system"] == "M" and f.attrs["signals"] == "gps_l1ca,bds_b1i"
        assert sorted(f["channels"]) == ["C04", "C08", "G11", "G24"]
        assert sorted(set(f["acquisition"]["prn"][:].tolist())) == [11, 24, 404, 408]
        for name, t_int in (("G11", 5), ("G24", 5), ("C04", 2), ("C08", 5)):
            g = f["channels"][name]
            assert g.attrs["prn"] == parse_label(name)[1] + (400 if name[0] == "C" else 0)
            assert g["integration_ms"][-1] == t_int            # GPS / D1 (NH wiped): 5 ms; D2: 2 ms symbols
            assert g["cn0_dbhz"][-1] > 41.0                    # 45 dB-Hz simulated
            # each signal's channels see their own IF: the Doppler is the truth's (GPS at +7.161 MHz,
            # BeiDou at -7.161 MHz in the file)
            assert abs(g["doppler_hz"][-1] - t["satellites"][name]["doppler_hz"][-1]) < 5.0


def test_mixed_run_file_ephemerides(tmp_path):
    """A run over several signals stores GPS and BeiDou ephemerides in two tables and reads them back with their
    classes; their satellite keys are the observables' ones; the RINEX navigation file names both systems."""
    from receiver.gnss.bds_ephemeris import BdsEphemeris
    from receiver.gnss.ephemeris import Ephemeris
    from receiver.gnss.rinex import write_rinex_nav
    from receiver.runfile.reader import load_run
    from receiver.runfile.writer import RunWriter
    from receiver.sim.bds_constellation import bds_nominal_ephemerides
    from receiver.sim.constellation import load_constellation
    gps = load_constellation("embedded", None, str(REPO / "data/gps_nominal_constellation.yaml"), 2300, 345600.0,
                             345620.0).ephemerides
    bds, _ = bds_nominal_ephemerides(str(REPO / "data/bds_nominal_constellation.yaml"), 2300, 345600.0)
    ephs = {5: gps[5], 12: gps[12], 405: bds[5], 412: bds[12]}
    w = RunWriter(tmp_path / "m.h5", "{}", {"sample_rate_hz": 8e6, "system": MIXED})
    w.write_ephemerides(ephs)
    w.close()
    with h5py.File(tmp_path / "m.h5", "r") as f:
        assert list(f["ephemeris/prn"][:]) == [5, 12] and list(f["ephemeris_bds/prn"][:]) == [5, 12]
    run = load_run(tmp_path / "m.h5")
    got = {run.eph_key(e): e for e in run.ephemerides}
    assert sorted(got) == [5, 12, 405, 412]
    assert type(got[405]) is BdsEphemeris and type(got[5]) is Ephemeris
    for k in ephs:
        assert got[k].sqrt_a == pytest.approx(ephs[k].sqrt_a, rel=1e-12) and got[k].toe == ephs[k].toe
    write_rinex_nav(tmp_path / "m.nav", run.ephemerides, system=run.system)
    labels = sorted({ln[:3] for ln in open(tmp_path / "m.nav") if ln[:1] in "GC" and ln[1:3].isdigit()})
    assert labels == ["C05", "C12", "G05", "G12"] and "M: MIXED" in open(tmp_path / "m.nav").readline()


def test_signal_outside_the_band_is_refused(tmp_path):
    """A second signal that falls outside the recording's band (narrowband L1 file, B1I 14.3 MHz below): one
    clear error, no run file."""
    from receiver.pipeline import run
    (tmp_path / "l1.bin").write_bytes(bytes(2 * 5000 * 20))          # 20 ms of int8 I/Q at 5 MS/s
    cfg = load_receiver_config(None, [f"input.path={tmp_path / 'l1.bin'}", "input.sample_rate_hz=5e6",
                                      f"output.path={tmp_path / 'r.h5'}", "signals=[gps_l1ca, bds_b1i]"])
    with pytest.raises(UserError, match="bds_b1i would sit at IF -14.322 MHz"):
        run(cfg, quiet=True, log=lambda *a: None)
    assert not list(tmp_path.glob("r.h5*"))


def test_one_file_per_signal(tmp_path):
    """GPS and BeiDou recorded into two files at the same instant (same clock, 5 MS/s complex baseband each):
    input.signal_files gives the B1I file; both systems are tracked in one run at their own Dopplers."""
    from receiver.pipeline import run
    from receiver.sim.simulate import simulate
    common = ["time.duration_s=1.5", "frontend.sample_rate_hz=5e6", "frontend.if_hz=0.0"]
    simulate(str(REPO / "configs/scenarios/gps_bds_static_tokyo.yaml"), str(tmp_path / "l1.bin"),
             overrides=common + ["signals=[]", "constellation.prns=[11, 24]"], progress=False)
    simulate(str(REPO / "configs/scenarios/bds_static_tokyo.yaml"), str(tmp_path / "b1.bin"),
             overrides=common + ["constellation.prns=[4, 8]"], progress=False)
    cfg = load_receiver_config(REPO / "configs/gps_bds_nav.yaml", [
        f"input.path={tmp_path / 'l1.bin'}", "input.sample_rate_hz=5e6", "input.if_hz=0.0",
        f"input.signal_files={{bds_b1i: {{path: {tmp_path / 'b1.bin'}, if_hz: 0.0}}}}",
        f"output.path={tmp_path / 'r.h5'}", "acquisition.prns=[11, 24]", "acquisition.prns_by_signal={bds_b1i: [4, 8]}",
        "navigation.enabled=false"])
    summary = run(cfg, quiet=True, log=lambda *a: None)
    assert summary.tracked == [11, 24, 404, 408]
    with h5py.File(tmp_path / "r.h5", "r") as f:
        for name, truth in (("G11", "l1"), ("G24", "l1"), ("C04", "b1"), ("C08", "b1")):
            with h5py.File(tmp_path / f"{truth}.truth.h5", "r") as t:
                g = f["channels"][name]
                assert g["cn0_dbhz"][-1] > 41.0
                assert abs(g["doppler_hz"][-1] - t["satellites"][name]["doppler_hz"][-1]) < 5.0
    with pytest.raises(UserError, match="signal_files"):
        load_receiver_config(REPO / "configs/gps_bds_nav.yaml", ["input.signal_files={gps_l1ca: {path: x}}"])


def test_common_slope_ignores_a_cross_correlation_lock():
    """The carrier smoothing's common code-minus-carrier drift: a channel locked on a cross-correlation (its own
    drift -67 m/s, as B1I C08 at the GEO Doppler in the 40-s GPS+BeiDou recording) must not move it."""
    from receiver.navigation.channel import common_slope
    good = [(0.02 * k - 0.1, 50.0 + k) for k in range(10)]
    ref = sum(s * w for s, w in good) / sum(w for _, w in good)
    assert common_slope(good) == pytest.approx(ref, abs=1e-12)
    assert common_slope(good + [(-67.0, 120.0)]) == pytest.approx(ref, abs=1e-12)     # (a plain mean: -11 m/s)
    assert common_slope([(0.5, 1.0), (0.7, 2.0)]) == pytest.approx((0.5 + 1.4) / 3.0)   # two: no median test
    assert common_slope([]) is None
