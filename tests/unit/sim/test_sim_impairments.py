"""Simulator front-end impairments (receiver/sim/impairments.py, scenario section `impairments`)."""
import numpy as np
import pytest

from receiver.source.conditioning import detect_tones
from receiver.errors import UserError
from receiver.source.io import SampleReader
from receiver.sim.simulate import simulate

FS = 2.6e6


def _sim(tmp_path, impairments, fmt="int16_iq", sigma=50.0, dur=0.1, **extra):
    sc = {"time": {"duration_s": dur, "seed": 3}, "frontend": {"format": fmt, "noise_sigma": sigma},
          "impairments": impairments, **extra}
    p = simulate(sc, tmp_path / "imp.bin", progress=False)
    return SampleReader(p["if"], fmt, FS).read(0, int(dur * FS))


def test_cw_tones_have_the_set_power_and_frequency(tmp_path):
    # satellites off: ten 45 dB-Hz signals would add 12 % to the in-band power the detector measures
    x = _sim(tmp_path, {"tones": [{"freq_hz": 250e3, "power_db": 30.0}, {"freq_hz": -3000.0, "power_db": 20.0}]},
             cn0={"dbhz": -20.0})
    d = detect_tones(x, FS)
    got = sorted((round(t.freq_hz, 1), t.jnr_db) for t in d.tones)
    assert [g[0] for g in got] == [-3000.0, 250000.0]
    assert got[0][1] == pytest.approx(20.0, abs=0.3) and got[1][1] == pytest.approx(30.0, abs=0.3)
    assert d.noise_power == pytest.approx(2 * 50.0 ** 2, rel=0.03)


def test_dc_offset_and_band_limiting_filter(tmp_path):
    x = _sim(tmp_path, {"dc_offset": [2.0, -1.0], "filter": {"bandwidth_hz": 1.0e6, "order": 6}})
    assert x.mean() == pytest.approx(complex(100.0, -50.0), abs=3.0)
    spec = np.fft.fftshift(np.mean(np.abs(np.fft.fft((x - x.mean())[:256 * 1000].reshape(1000, 256),
                                                     axis=1)) ** 2, axis=0))
    f = (np.arange(256) - 128) * FS / 256
    inside = spec[np.abs(f) < 0.3e6].mean()
    outside = spec[np.abs(f) > 0.9e6].mean()
    assert 10 * np.log10(inside / outside) > 20.0


@pytest.mark.parametrize("bits", [1, 2, 3, 8])
def test_quantisation_levels_with_agc(tmp_path, bits):
    """Levels +/-1, +/-3, ... (b <= 7) or -128..127 (8 bits), with the AGC's step at the MSE-optimal
    fraction of the RMS: for 2 bits P(|level| = 3) = 2 Q(0.9957) = 0.319."""
    x = _sim(tmp_path, {"quantization": {"bits": bits}}, fmt="int8_iq", sigma=8.0)
    v = np.concatenate([x.real, x.imag])
    levels = set(np.unique(v).astype(int))
    if bits < 8:
        assert levels <= set(range(-(2 ** bits - 1), 2 ** bits, 2))
        assert len(levels) == 2 ** bits
    else:
        assert min(levels) >= -128 and max(levels) <= 127 and len(levels) > 100
    if bits == 2:
        assert np.mean(np.abs(v) == 3) == pytest.approx(0.319, abs=0.01)


def test_bad_impairments_are_one_line_errors(tmp_path):
    with pytest.raises(UserError, match="impairments.tones"):
        _sim(tmp_path, {"tones": [{"freq_hz": 2e6, "power_db": 10.0}]})
    with pytest.raises(UserError, match="impairments.tones\\[0\\]"):
        _sim(tmp_path, {"tones": [{"freq": 1e3}]})
    with pytest.raises(UserError, match="impairments.quantization.bits"):
        _sim(tmp_path, {"quantization": {"bits": 9}})
    assert not (tmp_path / "imp.bin").exists()
