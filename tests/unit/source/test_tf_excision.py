"""Time-frequency excision of moving narrowband interference (receiver/source/excision.py, through the
conditioning stage): a fast sweep found and removed with the signal kept, a stationary tone left to the
notch, noise untouched, output independent of the read split."""
import numpy as np

from receiver.source.conditioning import ConditionedReader
from receiver.source.excision import frame_size, tf_excise, tf_test

from test_source_conditioning import FS, _ArrayReader, _cond  # noqa: E402  (the same stand-in reader)
from test_pulse_blanking import _code, _noise  # noqa: E402


def _sweep(n, jnr_db, span_hz=800e3, period_s=0.01, start_s=0.0):
    """A triangle sweep +/- span_hz every period_s (320 MHz/s for the defaults), phase continuous."""
    t = np.arange(n) / FS
    tri = 2.0 * np.abs(2.0 * np.mod(t / period_s, 1.0) - 1.0) - 1.0
    ph = np.cumsum(span_hz * tri) / FS
    on = t >= start_s
    return np.where(on, np.sqrt(10 ** (jnr_db / 10)) * np.exp(2j * np.pi * ph), 0).astype(np.complex64)


def test_tf_test_finds_a_sweep_but_not_noise_or_a_stationary_tone():
    """A +30 dB sweep is moving interference; noise, a +35 dB tone and that tone switching on mid-span are not."""
    n = int(0.0126 * FS)
    N = frame_size(FS)
    assert N == 128
    for seed in range(4):
        assert not tf_test(_noise(n, seed), N).moving
    k = np.arange(n)
    cw = (np.sqrt(10 ** 3.5) * np.exp(2j * np.pi * 120e3 / FS * k)).astype(np.complex64)
    assert not tf_test(_noise(n, 5) + cw, N).moving
    late = np.where(k > n // 3, cw, 0).astype(np.complex64)      # a tone switching on inside the span
    assert not tf_test(_noise(n, 7) + late, N).moving
    assert tf_test(_noise(n, 6) + _sweep(n, 30.0), N).moving


def test_excision_with_nothing_to_excise_reconstructs_the_input():
    x = _noise(40000, 2)
    N = 128
    floor = np.full(N, N * 0.375)          # noise power x sum(w^2) per bin
    y, hits, frames = tf_excise(lambda s, k: x[s:s + k], 0, 1000, 30000, N, floor, 12.0)
    assert np.max(np.abs(y - x[1000:31000])) < 1e-5
    assert hits < 0.01 * frames


def test_sweep_is_excised_and_the_signal_kept():
    """A +30 dB sweep of +/-800 kHz every 10 ms over noise and a weak signal: excision on from the start,
    the output's power within 0.5 dB of the noise's, and the signal's correlation amplitude >= 0.9 of its
    value on the interference-free input."""
    n = int(0.3 * FS)
    sig = _code(n, 4, 0.1)
    x = _noise(n, 8) + sig + _sweep(n, 30.0)
    r = ConditionedReader(_ArrayReader(x), _cond())
    y = np.concatenate([r.read(s, 100000)[:100000] for s in range(0, n, 100000)])
    assert r.tf_events and r.tf_events[0][1] == "on" and r.tf_events[0][0] == 0
    assert 10 * np.log10(np.mean(np.abs(y[20000:]) ** 2) / 1.01) < 0.5
    a = np.real(np.vdot(sig, y)) / np.real(np.vdot(sig, sig))
    assert a > 0.9
    assert not [t for t in r.detection.tones if t.cancelled]     # the sweep's turning points are no tones


def test_sweep_switching_on_mid_stream_and_split_independence():
    """A sweep from 0.3 s: the monitor switches excision on within one check (output before it untouched:
    the stage without excision gives the same samples); chunked reads give the samples of one read."""
    n = int(0.6 * FS)
    x = _noise(n, 9) + _sweep(n, 30.0, start_s=0.3)
    cfg = _cond(monitor_ms=50.0)
    whole = ConditionedReader(_ArrayReader(x), cfg).read(0, n)
    r = ConditionedReader(_ArrayReader(x), cfg)
    parts = [r.read(s, 80001 + 4000)[:80001] for s in range(0, n, 80001)]
    y = np.concatenate(parts)[:n]
    assert np.array_equal(y, whole)
    on = r.tf_events[0][0] / FS
    span_s = cfg.fft_size * cfg.monitor_segments / FS
    assert 0.3 < on <= 0.3 + 0.05 + span_s + 1e-3
    ref = ConditionedReader(_ArrayReader(x), _cond(monitor_ms=50.0, tf_excision=False)).read(0, n)
    assert np.array_equal(y[:int(0.3 * FS)], ref[:int(0.3 * FS)])
    late = slice(int(on * FS) + 10000, None)
    assert 10 * np.log10(np.mean(np.abs(y[late]) ** 2)) < 0.6
