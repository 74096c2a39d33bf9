"""input.signal_files with a file of its own format and rate (gps_l5) and the run's band signal checks."""
import numpy as np
import pytest

from receiver.errors import UserError
from receiver.dualband import band_signal, core_signals, open_band_input
from receiver.schema import load_receiver_config


def _cfg(tmp_path, **files):
    (tmp_path / "l1.bin").write_bytes(np.zeros(4000, np.int8).tobytes())
    (tmp_path / "l5.bin").write_bytes(np.arange(40000, dtype=np.int64).astype(np.int8).tobytes())
    sets = [("input.path", str(tmp_path / "l1.bin")), ("input.sample_rate_hz", 2.0e6),
            ("signals", ["gps_l1ca", "gps_l5"])]
    if files:
        sets.append(("input.signal_files", files))
    return load_receiver_config(None, sets)


def test_band_file_with_its_own_format_and_rate(tmp_path):
    cfg = _cfg(tmp_path, gps_l5={"path": str(tmp_path / "l5.bin"), "format": "int8_iq",
                                 "sample_rate_hz": 20.0e6, "if_hz": 1.0e6})
    assert core_signals(cfg) == ["gps_l1ca"] and band_signal(cfg) == "gps_l5"
    r = open_band_input(cfg, "gps_l5")
    assert r.fs == 20.0e6 and r.if_hz == 1.0e6 and r.n_samples == 20000
    x = r.read(10, 3)
    assert np.array_equal(x, np.array([20 + 21j, 22 + 23j, 24 + 25j], np.complex64))


@pytest.mark.parametrize("entry,match", [
    ({"path": "x", "if_hz": 11.0e6, "sample_rate_hz": 20.0e6}, "if_hz"),
    ({"path": "x", "rate": 20.0e6}, "must be"),
    ({"path": "x", "format": "no_such_format"}, "must be"),
])
def test_bad_entries(tmp_path, entry, match):
    with pytest.raises(UserError, match=match):
        _cfg(tmp_path, gps_l5=entry)


def test_own_rate_only_for_band_signals(tmp_path):
    (tmp_path / "l1.bin").write_bytes(np.zeros(4000, np.int8).tobytes())
    with pytest.raises(UserError, match="same format and sample_rate_hz"):
        load_receiver_config(None, [("input.path", str(tmp_path / "l1.bin")), ("signals", ["gps_l1ca", "bds_b1i"]),
                                    ("input.signal_files", {"bds_b1i": {"path": "b.bin", "sample_rate_hz": 8e6}})])


def test_band_signal_needs_l1_first_and_its_file(tmp_path):
    for sigs in (["gps_l5"], ["gps_l5", "gps_l1ca"], ["bds_b1i", "gps_l5"], ["gal_e1", "gps_l5"],
                 ["gal_e5a", "gal_e1"], ["gps_l1ca", "gal_e5a"]):
        with pytest.raises(UserError, match="second band of (gps_l1ca|gal_e1)"):
            load_receiver_config(None, [("signals", sigs)])
    cfg = _cfg(tmp_path)
    with pytest.raises(UserError, match="input.signal_files.gps_l5"):
        open_band_input(cfg, "gps_l5")
