"""Interference monitor of the input conditioning (receiver/source/conditioning.py): tones that appear or
vanish mid-stream get a notch added / removed; chunked reads give the samples of one read."""
import numpy as np

from receiver.source.conditioning import ConditionedReader

from test_source_conditioning import FS, _ArrayReader, _cond  # noqa: E402  (the same stand-in reader)


def _noise(n, seed):
    rng = np.random.default_rng(seed)
    return ((rng.standard_normal(n) + 1j * rng.standard_normal(n)) / np.sqrt(2)).astype(np.complex64)


def _late_tone(n, f, jnr_db, on_s, off_s=None):
    k = np.arange(n)
    t = k / FS
    on = (t >= on_s) & (t < (off_s if off_s is not None else np.inf))
    return np.where(on, np.sqrt(10 ** (jnr_db / 10)) * np.exp(1j * (2 * np.pi * f / FS * k + 0.7)), 0) \
        .astype(np.complex64)


def _residual_db(y, f, sl):
    """Power of the tone's frequency left in y over the slice, dB re the noise power (1)."""
    k = np.arange(len(y))[sl]
    return 10 * np.log10(np.abs(np.mean(y[sl] * np.exp(-2j * np.pi * f / FS * k))) ** 2 + 1e-30)


def test_tone_switching_on_mid_stream_gets_a_notch_and_off_removes_it():
    """A 35 dB tone switching on at 0.3 s (after the start-up detection span) is notched from the first
    monitor check whose span holds it on (<= monitor_ms + span later); after it switches off at 0.9 s the
    notch is removed.  Between, the tone's line in the output is > 30 dB below its input level."""
    n = int(1.4 * FS)
    f = 312.5e3
    x = _noise(n, 1) + _late_tone(n, f, 35.0, 0.3, 0.9)
    cfg = _cond(monitor_ms=50.0)
    r = ConditionedReader(_ArrayReader(x), cfg)
    assert [t for t in r.detection.tones if t.cancelled] == []        # nothing in the first 100 ms
    y = np.concatenate([r.read(s, 200000)[:200000] for s in range(0, n, 200000)])
    ev = r.tone_events
    added = [e for e in ev if e[1] == "added"]
    removed = [e for e in ev if e[1] == "removed"]
    assert len(added) == 1 and abs(added[0][2] - f) < 5.0
    span_s = cfg.fft_size * cfg.monitor_segments / FS
    assert 0.3 < added[0][0] / FS <= 0.3 + 0.05 + span_s + 1e-3
    assert abs(added[0][3] - 35.0) < 2.0
    assert len(removed) == 1 and 0.9 < removed[0][0] / FS < 0.9 + 4 * (0.05 + span_s)
    on = slice(int(0.45 * FS), int(0.85 * FS))
    assert _residual_db(y, f, on) < 35.0 - 30.0
    # before the tone the output is the input (only the DC canceller runs: a ~0.01 offset estimate)
    pre = slice(int(0.12 * FS), int(0.28 * FS))
    assert np.max(np.abs(y[pre] - x[pre])) < 0.05
    post = slice(int(1.2 * FS), None)
    assert 10 * np.log10(np.mean(np.abs(y[post]) ** 2)) < 0.1


def test_monitor_output_does_not_depend_on_the_read_split():
    """Overlapping chunk reads (as the pipeline's) and reads that restart elsewhere in between give, where
    the chunk stream continues, the samples of one read of the whole span."""
    n = int(0.8 * FS)
    x = _noise(n, 2) + _late_tone(n, -455e3, 30.0, 0.25)
    whole = ConditionedReader(_ArrayReader(x), _cond(monitor_ms=40.0)).read(0, n)
    r = ConditionedReader(_ArrayReader(x), _cond(monitor_ms=40.0))
    chunk, ov = 130000, 7800
    for s in range(0, n, chunk):
        b = r.read(s, chunk + ov)
        assert np.array_equal(b, whole[s:s + chunk + ov])
    assert any(e[1] == "added" and abs(e[2] + 455e3) < 5 for e in r.tone_events)


def test_white_noise_gets_no_notch():
    n = int(1.0 * FS)
    r = ConditionedReader(_ArrayReader(_noise(n, 3)), _cond(monitor_ms=20.0))
    for s in range(0, n, 100000):
        r.read(s, 100000)
    assert r.checks > 30
    assert [e for e in r.tone_events if e[1] == "added"] == []


def test_monitor_false_alarms_are_a_rate_per_unit_time():
    """1000 monitor checks of white noise (2 ms apart, small spectra, the 6-dB floor rule off): with the
    detection span's pfa (2 %) per check about 20 would add a false notch; the monitor's per-check
    probability comes from monitor_false_per_hour (0.1 per hour of stream) and adds none."""
    n = int(2.0 * FS)
    cfg = _cond(monitor_ms=2.0, fft_size=256, pfa=0.02, min_db=0.0, pulse_detection=False,
                tf_excision=False, detect_ms=2.0)
    r = ConditionedReader(_ArrayReader(_noise(n, 5)), cfg)
    for s in range(0, n, 260000):
        r.read(s, 260000)
    assert r.checks >= 900
    assert [e for e in r.tone_events if e[1] == "added"] == []


def _swept(n, f0, span, period, jnr_db, on_s):
    t = np.arange(n) / FS
    tri = 2 * np.abs(2 * np.mod(t / period, 1.0) - 1.0) - 1.0
    ph = 2 * np.pi * np.cumsum(f0 + span * tri) / FS
    return np.where(t >= on_s, np.sqrt(10 ** (jnr_db / 10)) * np.exp(1j * ph), 0).astype(np.complex64)


def test_swept_tone_is_followed_by_the_tracking_notch():
    """A tone swept +/- 50 kHz in 0.5 s (400 kHz/s), 40 dB over the noise, switching on mid-stream: the
    notch's frequency-tracking loop follows it (output within 0.2 dB of the noise power, one notch); with
    fixed notch frequencies (notch_track_hz 0) it passes 40 dB strong."""
    n = int(1.5 * FS)
    x = _noise(n, 4) + _swept(n, -500e3, 50e3, 0.5, 40.0, 0.3)
    out = {}
    for trk in (3000.0, 0.0):
        r = ConditionedReader(_ArrayReader(x), _cond(notch_track_hz=trk))
        y = np.concatenate([r.read(s, 200000)[:200000] for s in range(0, n, 200000)])
        out[trk] = 10 * np.log10(np.mean(np.abs(y[int(0.5 * FS):]) ** 2))
        if trk:
            assert len([e for e in r.tone_events if e[1] == "added"]) == 1
    assert out[3000.0] < 0.2
    assert out[0.0] > 30.0
