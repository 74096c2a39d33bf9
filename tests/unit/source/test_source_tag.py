"""PocketSDR ``.tag`` metadata beside a recording (receiver/source/metadata.py): parsing fixed tag texts,
the simulator writing one, a run with no input keys equal to the explicit one, and INT8X2's opposite Q
sign undone by iq_swap (the satellites are found at their Doppler)."""
import os
from pathlib import Path

import numpy as np
import pytest

from receiver.schema import load_receiver_config
from receiver.errors import UserError
from receiver.source.metadata import read_metadata, read_tag

from repo_paths import ROOT
SCENARIO = ROOT / "configs" / "scenarios" / "static_default.yaml"
L1 = 1575.42e6


def _tag(tmp_path, text, name="r.bin"):
    p = tmp_path / name
    p.write_bytes(b"\0" * 64)
    (tmp_path / (name + ".tag")).write_text(text)
    return p


def test_read_fixed_tags(tmp_path):
    p = _tag(tmp_path, "PROG = pocket_dump\nTIME = 2022/01/01 00:00:18.000\nFMT  = INT8\nF_S  = 12\n"
                       "F_LO = 1572.42\nIQ   = 1\nBITS = 2\n")
    t = read_tag(p)
    assert t["format"] == "int8_real" and t["sample_rate_hz"] == 12e6 and t["iq_swap"] is False
    assert t["start_gps_week"] == 2190 and t["start_gps_tow_s"] == pytest.approx(6 * 86400 + 18.0)
    meta, src = read_metadata(p, L1)
    assert meta["if_hz"] == pytest.approx(3.0e6) and src["if_hz"].endswith("r.bin.tag")
    q = _tag(tmp_path, "FMT  = INT8X2\nF_S  = 24.0\nF_LO = 1575.42\nIQ   = 2\nBITS = 2\n", "q.bin")
    m, _ = read_metadata(q, L1)
    assert m["format"] == "int8_iq" and m["iq_swap"] is True and m["if_hz"] == 0.0
    assert read_tag(_tag(tmp_path, "FMT = CS16\nF_S = 5\nIQ = 2\n", "c.bin"))["format"] == "int16_iq"
    with pytest.raises(UserError, match="multi-channel"):
        read_tag(_tag(tmp_path, "FMT  = RAW8\nF_S  = 24\n", "raw.bin"))
    with pytest.raises(UserError, match="not one of"):
        read_tag(_tag(tmp_path, "FMT  = FLOAT\n", "bad.bin"))


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("tag")
    paths = simulate(SCENARIO, d / "x.bin", [("time.duration_s", 1.0), ("constellation.prns", [1, 6, 9]),
                                             ("clock.noise", "none"), ("frontend.format", "int8_iq"),
                                             ("frontend.if_hz", 2.5e5)], progress=False)
    return d, paths


@pytest.mark.slow
def test_simulator_writes_the_tag_and_run_equals_explicit(rec):
    import h5py
    d, paths = rec
    tag = Path(paths["tag"]).read_text()
    assert "FMT  = CS8" in tag and "F_S  = 2.6" in tag and "IQ   = 2" in tag
    os.remove(paths["sigmf"])                             # the tag alone describes the file
    t = read_tag(paths["if"])
    with h5py.File(paths["truth"]) as f:
        tow = float(f.attrs["start_gps_tow_s"])
    assert t["start_gps_tow_s"] == pytest.approx(tow, abs=1e-3)
    common = [("navigation.enabled", False), ("acquisition.prns", [1, 6, 9, 12])]
    a = load_receiver_config(None, [("input.path", paths["if"]), ("output.path", str(d / "a.h5"))] + common)
    b = load_receiver_config(paths["yaml"], [("output.path", str(d / "b.h5"))] + common)
    from receiver.pipeline import run
    run(a, quiet=True, log=lambda *x: None)
    run(b, quiet=True, log=lambda *x: None)
    assert a.input.if_hz == 2.5e5 and a.input.format == "int8_iq"
    from receiver.runfile.compare import compare_h5
    diffs = []
    compare_h5(d / "a.h5", d / "b.h5", diffs)
    assert [x for x in diffs if not x.startswith("/@config")] == [], diffs[:5]
    bad = load_receiver_config(None, [("input.path", paths["if"]), ("input.sample_rate_hz", 4e6)] + common)
    with pytest.raises(UserError, match="disagrees with .*x.bin.tag"):
        from receiver.pipeline import open_input
        open_input(bad)


def test_int8x2_q_sign_is_undone(rec):
    """A PocketSDR INT8X2 file stores -Q: with its tag the receiver swaps I and Q (a spectral inversion
    back, up to a constant phase) and finds the satellites at the Doppler of the original file."""
    from receiver.acquisition.stage import acquire
    from receiver.pipeline import open_input
    d, paths = rec
    raw = np.fromfile(paths["if"], np.int8).copy()
    raw[1::2] = -np.maximum(raw[1::2], -127)
    q = d / "q.bin"
    raw.tofile(q)
    (d / "q.bin.tag").write_text(f"FMT  = INT8X2\nF_S  = 2.6\nF_LO = {(L1 - 2.5e5) / 1e6:.9f}\nIQ   = 2\n")
    res = {}
    for name, path in (("orig", paths["if"]), ("x2", str(q))):
        cfg = load_receiver_config(None, [("input.path", path), ("acquisition.prns", [1, 6, 9, 12]),
                                          ("input.conditioning.tone_detection", False)]
                                   + ([("input.format", "int8_iq"), ("input.if_hz", 2.5e5)] if name == "orig"
                                      else []))
        reader = open_input(cfg)
        assert cfg.input.iq_swap is (name == "x2")
        res[name] = {r.prn: r.doppler_hz for r in acquire(cfg, reader, reader.first, [1, 6, 9, 12]) if r.detected}
    assert set(res["orig"]) == set(res["x2"]) == {1, 6, 9}
    for prn in res["orig"]:
        assert abs(res["orig"][prn] - res["x2"][prn]) < 30.0
