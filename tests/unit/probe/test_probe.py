"""gnssrx probe: the byte statistics name the sample family of files written in every format, and the short
acquisition names the format, rate, IF and spectrum sign of small synthetic recordings whose truth is known
(tests/synth.py signals quantised by receiver/source/io.py); the hints of a run or acquisition that finds
nothing name the format the bytes contradict."""
import numpy as np
import pytest
from click.testing import CliRunner

from receiver.cli import main
from receiver.probe import hints
from receiver.probe.search import baseband, iq_hint, probe, rate_hints
from receiver.probe.stats import byte_stats
from receiver.source.io import NOISE_SIGMA, quantize
from synth import make_signal

# PRN 13 is in the first pass's subset of PRNs (search.FIRST_PRNS), 3 and 21 are found by the full search of the winner
SATS = [{"prn": 3, "doppler_hz": 1800.0, "code_phase_chips": 100.0, "cn0_dbhz": 50.0},
        {"prn": 13, "doppler_hz": -2600.0, "code_phase_chips": 700.0, "cn0_dbhz": 49.0},
        {"prn": 21, "doppler_hz": 400.0, "code_phase_chips": 333.0, "cn0_dbhz": 48.0}]


def _write(path, x, fmt, **kw):
    q = quantize(x, fmt, NOISE_SIGMA[fmt], **kw)
    q.tofile(path)
    return str(path)


@pytest.fixture(scope="module")
def iq26():
    # 2.6 MS/s is third in the list of rates tried: the wrong ones must be rejected first
    return make_signal(SATS, fs=2.6e6, duration_s=0.26, seed=1)


@pytest.mark.parametrize("fmt,kw,family", [
    ("int8_iq", {}, "int8"), ("uint8_iq", {}, "uint8"), ("int16_iq", {}, "int16"), ("complex64", {}, "float32"),
    ("packed2_iq", {"encoding": "sign_magnitude"}, "packed2"),
    ("packed2_iq", {"encoding": "twos_complement"}, "packed2"),
    ("packed2_real", {"encoding": "offset_binary", "bit_order": "lsb_first"}, "packed2"),
    ("packed4_iq", {}, "packed4"), ("packed1_iq", {}, "packed1"), ("int4_iq", {}, "int4")])
def test_byte_statistics_name_the_family(tmp_path, fmt, kw, family):
    rng = np.random.default_rng(3)
    x = (rng.normal(size=80000) + 1j * rng.normal(size=80000)) / np.sqrt(2)
    st = byte_stats(_write(tmp_path / "f.bin", x, fmt, **kw))
    assert st.family == family, st.evidence
    if "encoding" in kw:
        assert st.candidates[0].encoding == kw["encoding"]
    assert fmt in {c.fmt for c in st.candidates}


def test_two_bit_levels_in_int8_bytes_are_int8():
    """A 2-bit front end stored one value per byte (PocketSDR): int8 with the levels +/-1 +/-3 named."""
    import tempfile
    rng = np.random.default_rng(4)
    v = rng.choice(np.array([-3, -1, 1, 3], np.int8), size=100000, p=[0.17, 0.33, 0.33, 0.17])
    with tempfile.NamedTemporaryFile(suffix=".bin") as fh:
        v.tofile(fh.name)
        st = byte_stats(fh.name)
    assert st.family == "int8" and st.levels == [-3, -1, 1, 3]


def test_imbalanced_int8_iq_is_not_int16(tmp_path):
    """I and Q of different power (6 dB) and a DC on I: still int8 (the run's format warning must not
    misfire on such a front end)."""
    rng = np.random.default_rng(6)
    a = np.empty(200000, np.int8)
    a[0::2] = np.clip(np.rint(rng.normal(3, 8, 100000)), -128, 127)
    a[1::2] = np.clip(np.rint(rng.normal(0, 16, 100000)), -128, 127)
    a.tofile(tmp_path / "imb.bin")
    assert byte_stats(tmp_path / "imb.bin").family == "int8"
    assert hints.format_mismatch(tmp_path / "imb.bin", "int8_iq") is None


def test_baseband_moves_the_if_to_zero():
    fs, f0 = 10.4e6, 2.6e6 + 1234.0
    n = np.arange(int(fs * 0.01))
    tone = np.cos(2 * np.pi * f0 / fs * n)
    y = baseband(tone.astype(np.complex64), fs, 2.6e6, real=True, blank=False)
    spec = np.abs(np.fft.fft(y))
    f = np.fft.fftfreq(len(y), 1 / 2.048e6)
    assert abs(f[np.argmax(spec)] - 1234.0) <= 100.0      # one bin of a 10-ms block
    assert len(y) == 20480
    # a CW tone 20 dB over the noise is blanked, the noise (where the GPS signals are) kept
    noise = np.random.default_rng(0).normal(size=len(n))
    y = baseband((noise + 10 * tone).astype(np.complex64), fs, 2.6e6, real=True)
    spec = np.abs(np.fft.fft(y)) ** 2
    near = np.abs(f - 1234.0) < 300.0
    assert spec[near].max() < 10 * np.median(spec) and np.count_nonzero(spec == 0) < 0.01 * len(spec)


def test_name_hints():
    assert rate_hints("pocketsdr_L1_20211125_004000_12MHz_I.bin") == [12e6]
    assert rate_hints("capture_2012_07_26_4Msps_4ms.dat") == [4e6]
    assert rate_hints("recording_10ms.iq") == []
    assert iq_hint("x_4MHz_IQ.bin") == "iq" and iq_hint("x_12MHz_I.bin") == "real"


def _found(r):
    return {s.prn for s in r.best.found}


def test_probe_int8_iq(tmp_path, iq26):
    r = probe(_write(tmp_path / "a.bin", iq26, "int8_iq"))
    assert r.config() == {"format": "int8_iq", "sample_rate_hz": 2.6e6, "if_hz": 0.0}
    assert _found(r) == {3, 13, 21}
    dop = {s.prn: s.doppler_hz for s in r.best.found}
    assert all(abs(dop[s["prn"]] - s["doppler_hz"]) <= 125.0 for s in SATS)     # half a 250-Hz bin
    assert r.iq_swap is False


def test_probe_swapped_iq(tmp_path, iq26):
    r = probe(_write(tmp_path / "s.bin", iq26.imag + 1j * iq26.real, "uint8_iq"))
    cfg = r.config()
    assert cfg["format"] == "uint8_iq" and cfg["sample_rate_hz"] == 2.6e6 and cfg.get("iq_swap") is True
    assert _found(r) == {3, 13, 21}


@pytest.mark.slow
def test_probe_real_if_packed(tmp_path):
    fs = 8.0e6
    x = make_signal(SATS, fs=fs, duration_s=0.03, seed=2, if_hz=fs / 4, real=True)
    # white noise says nothing about I/Q vs real (a front end's filter would): the name says real
    r = probe(_write(tmp_path / "r_I.bin", x, "packed2_real", encoding="twos_complement"))
    assert r.config() == {"format": "packed2_real", "bit_order": "msb_first", "encoding": "twos_complement",
                          "sample_rate_hz": fs, "if_hz": fs / 4}
    assert _found(r) == {3, 13, 21}


def test_probe_cli(tmp_path, iq26):
    path = _write(tmp_path / "a_2.6MHz.bin", iq26, "int8_iq")
    res = CliRunner().invoke(main, ["probe", path])
    assert res.exit_code == 0, res.output
    assert "  format: int8_iq" in res.output and "  sample_rate_hz: 2600000" in res.output
    assert "--set input.format=int8_iq" in res.output
    assert "too short to decode a broadcast ephemeris" in res.output


def test_probe_cli_noise_and_bad_input(tmp_path):
    rng = np.random.default_rng(5)
    noise = (rng.normal(size=60000) + 1j * rng.normal(size=60000)).astype(np.complex64)
    path = _write(tmp_path / "n.bin", noise, "int8_iq")
    res = CliRunner().invoke(main, ["probe", path, "--rate", "2.6e6"])
    assert res.exit_code == 1 and "no reading of the file found a satellite" in res.output
    cfg = tmp_path / "c.yaml"
    cfg.write_text("input:\n  format: int8_iq\n")
    for args in (["probe", str(tmp_path / "missing.bin")], ["probe", path, "--rate", "12"], ["probe", str(cfg)]):
        res = CliRunner().invoke(main, args)
        assert res.exit_code == 2 and res.output.count("\n") == 1 and "Traceback" not in res.output, res.output


def test_hints_name_the_contradicted_format(tmp_path, iq26):
    from receiver.schema import load_receiver_config
    path = _write(tmp_path / "a.bin", iq26, "int8_iq")
    m = hints.format_mismatch(path, "uint8_iq")
    assert m is not None and "centred on 0" in m and "int8_iq" in m
    assert hints.format_mismatch(path, "int8_iq") is None
    cfg = load_receiver_config(None, [("input.path", path), ("input.format", "int16_iq")])
    lines = hints.no_satellite_lines(cfg)
    assert any("does not fit the file's bytes" in ln for ln in lines) and any("gnssrx probe" in ln for ln in lines)
