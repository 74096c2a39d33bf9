"""SigMF metadata beside a recording: written by the simulator, read by the receiver; a run with no input
keys equals the run with the explicit input section; disagreeing explicit keys are one-line errors."""
import json
from pathlib import Path

import pytest

from receiver.schema import load_receiver_config
from receiver.errors import UserError
from receiver.pipeline import run
from receiver.sim.simulate import simulate
from receiver.source.metadata import read_sigmf

from repo_paths import ROOT
SCENARIO = ROOT / "configs" / "scenarios" / "static_default.yaml"


@pytest.mark.slow
def test_sigmf_run_equals_explicit_config(tmp_path):
    paths = simulate(SCENARIO, tmp_path / "x.sigmf-data",
                     [("time.duration_s", 1.5), ("constellation.prns", [1, 6, 9]),
                      ("frontend.format", "int16_iq"), ("frontend.sample_rate_hz", 2.046e6),
                      ("frontend.if_hz", 1.0e5)], progress=False)
    assert paths["sigmf"] == str(tmp_path / "x.sigmf-meta") and paths["truth"].endswith("x.truth.h5")
    meta = json.loads(Path(paths["sigmf"]).read_text())
    assert meta["global"]["core:datatype"] == "ci16_le" and meta["global"]["core:sample_rate"] == 2.046e6
    assert meta["captures"][0]["core:frequency"] == pytest.approx(1575.42e6 - 1.0e5)
    got = read_sigmf(paths["if"], 1575.42e6)
    import h5py
    with h5py.File(paths["truth"]) as t:
        week, tow = int(t.attrs["gps_week"]), float(t.attrs["start_gps_tow_s"])
    assert got["format"] == "int16_iq" and got["if_hz"] == 1.0e5 and got["start_gps_week"] == week
    assert got["start_gps_tow_s"] == pytest.approx(tow, abs=1e-6)             # UTC datetime + leap seconds
    common = [("navigation.enabled", False), ("acquisition.prns", [1, 6, 9, 12])]
    a = load_receiver_config(None, [("input.path", paths["if"]), ("output.path", str(tmp_path / "a.h5"))]
                             + common)
    b = load_receiver_config(paths["yaml"], [("output.path", str(tmp_path / "b.h5"))] + common)
    run(a, quiet=True, log=lambda *x: None)
    run(b, quiet=True, log=lambda *x: None)
    from receiver.runfile.compare import compare_h5
    diffs = []
    compare_h5(tmp_path / "a.h5", tmp_path / "b.h5", diffs)
    # the stored configs hold the same input section (metadata filled in = the explicit fragment)
    import h5py
    import yaml
    with h5py.File(tmp_path / "a.h5") as fa, h5py.File(tmp_path / "b.h5") as fb:
        ca, cb = yaml.safe_load(fa.attrs["config"]), yaml.safe_load(fb.attrs["config"])
    ca.pop("output"), cb.pop("output")
    assert ca == cb, (ca["input"], cb["input"])
    assert [d for d in diffs if not d.startswith("/@config")] == [], diffs[:5]
    with h5py.File(tmp_path / "a.h5") as f:
        assert set(f["channels"]) == {"G01", "G06", "G09"}


def test_disagreeing_explicit_key_is_an_error(tmp_path):
    paths = simulate(SCENARIO, tmp_path / "y.bin", [("time.duration_s", 0.05), ("constellation.prns", [1]),
                                                    ("frontend.format", "packed2_iq")], progress=False)
    meta = json.loads(Path(paths["sigmf"]).read_text())["global"]
    assert meta["gnssrx:format"] == "packed2_iq" and meta["gnssrx:encoding"] == "sign_magnitude"
    cfg = load_receiver_config(None, [("input.path", paths["if"]), ("input.sample_rate_hz", 4e6),
                                      ("output.path", str(tmp_path / "c.h5"))])
    with pytest.raises(UserError, match="input.sample_rate_hz.*disagrees"):
        run(cfg, quiet=True, log=lambda *x: None)
    assert not (tmp_path / "c.h5").exists()
    cfg = load_receiver_config(None, [("input.path", paths["if"]), ("input.format", "cu8"),
                                      ("output.path", str(tmp_path / "c.h5"))])
    with pytest.raises(UserError, match="input.format"):
        run(cfg, quiet=True, log=lambda *x: None)
    Path(paths["sigmf"]).write_text("{not json")
    with pytest.raises(UserError, match="not valid JSON"):
        read_sigmf(paths["if"], 1575.42e6)


def test_recording_of_another_signal_names_it(tmp_path):
    """A B1I recording (SigMF centre 1561.098 MHz) run with the default GPS signal: one line naming the
    signal whose carrier the band holds; the simulator's input section names its signal, so it runs."""
    paths = simulate(ROOT / "configs" / "scenarios" / "bds_b1i_short.yaml", tmp_path / "b.bin",
                     [("time.duration_s", 0.05)], progress=False)
    assert Path(paths["yaml"]).read_text().count("signal: bds_b1i") == 1
    cfg = load_receiver_config(None, [("input.path", paths["if"]), ("output.path", str(tmp_path / "c.h5"))])
    with pytest.raises(UserError, match=r"1561\.098000 MHz.*set signal: bds_b1i"):
        run(cfg, quiet=True, log=lambda *x: None)
    assert not (tmp_path / "c.h5").exists()
    assert load_receiver_config(paths["yaml"], []).signal == "bds_b1i"
