"""Input conditioning (receiver/source/conditioning.py): tone detector, tone canceller, the conditioned reader."""
import numpy as np
import pytest

from receiver.source.conditioning import Canceller, ConditionedReader, detect_tones
from receiver.config import build
from receiver.schema import RECEIVER_SCHEMA
from receiver.gnss.signals import CA_CHIP_RATE, L1_HZ, ca_code, sample_code

from synth import make_signal

FS = 2.6e6
NFFT = 4096
ENBW = 2.0044     # Blackman-Harris, bins


def _tone(n, f, power, phase=0.3, start=0):
    k = np.arange(start, start + n)
    return (np.sqrt(power) * np.exp(1j * (2 * np.pi * f / FS * k + phase))).astype(np.complex64)


def test_detector_finds_tones_10db_above_the_floor_within_one_bin():
    """Tones whose power is 10 dB above the noise floor of one periodogram bin (noise power x ENBW / NFFT),
    at arbitrary (off-bin) frequencies, with a satellite signal present: every one found within one bin,
    nothing else found."""
    rng = np.random.default_rng(3)
    x = make_signal([dict(prn=5, doppler_hz=1234.0, code_phase_chips=100.0, cn0_dbhz=50.0)], FS, 0.1, seed=1)
    freqs = [3000.0, -600e3 + 137.0, 250e3 - 311.0, 777777.7, -1.1e6]
    p_bin = 10 ** (10 / 10) * ENBW / NFFT          # 10 dB over the bin floor (noise power 1)
    for f in freqs:
        x = x + _tone(len(x), f, p_bin, phase=rng.uniform(0, 6))
    d = detect_tones(x, FS, NFFT)
    found = sorted(t.freq_hz for t in d.tones)
    assert len(found) == len(freqs), d.tones
    for f, g in zip(sorted(freqs), found):
        assert abs(g - f) < FS / NFFT
    for t in d.tones:   # the reported power above the bin floor (scalloping < 1 dB, averaging noise)
        assert t.snr_bin_db == pytest.approx(10.0, abs=2.0)


def test_detector_power_and_frequency_of_strong_tones():
    x = make_signal([], FS, 0.1, seed=2)
    for f, p_db in [(3000.0, 30.0), (-600e3, 40.0), (250e3, 20.0)]:
        d = detect_tones(x + _tone(len(x), f, 10 ** (p_db / 10)), FS)
        assert len(d.tones) == 1
        assert d.tones[0].freq_hz == pytest.approx(f, abs=0.05)      # phase-slope refinement
        assert d.tones[0].jnr_db == pytest.approx(p_db, abs=0.3)     # tone over total noise power
        assert d.noise_power == pytest.approx(1.0, rel=0.05)


@pytest.mark.slow
def test_detector_white_noise_false_alarms():
    """Pfa (default 1e-3) bounds the probability of any detection over the whole spectrum: 20 white-noise
    spectra of 100 ms (63 segments) and 20 of 10 ms (6 segments) give none (expected: 0.04)."""
    for seed in range(20):
        assert detect_tones(make_signal([], FS, 0.1, seed=100 + seed), FS).tones == []
        assert detect_tones(make_signal([], FS, 0.01, seed=200 + seed), FS).tones == []


def _components(f_tone, p_db, dur=0.2):
    sats = [dict(prn=5, doppler_hz=3000.0, code_phase_chips=100.0, cn0_dbhz=45.0)]
    sig = make_signal(sats, FS, dur, seed=1) - make_signal([], FS, dur, seed=1)    # signal alone
    noise = make_signal([], FS, dur, seed=2)
    tone = _tone(len(sig), f_tone, 10 ** (p_db / 10))
    return sig, noise, tone


@pytest.mark.parametrize("f_tone,p_db", [(3000.0, 40.0), (250e3, 30.0), (-600e3, 40.0), (0.0, 20.0)])
def test_notch_removes_tone_30db_with_small_cn0_loss(f_tone, p_db):
    """The canceller is linear for given tone frequencies, so the tone, the signal and the noise can be
    passed separately: tone suppressed by >= 30 dB; the signal's correlation power over the noise power
    (C/N0) changes by < 0.5 dB -- even with the tone on the satellite's own carrier (+3 kHz)."""
    sig, noise, tone = _components(f_tone, p_db)
    d = detect_tones(sig + noise + tone, FS)
    assert len(d.tones) == 1
    f = [t.freq_hz for t in d.tones]

    def through(v):
        return Canceller(f, FS, 100.0, 100.0).process(v)

    sl = slice(int(0.02 * FS), None)                          # after the 1.6 ms (1/mu) convergence
    supp = 10 * np.log10(np.mean(np.abs(tone[sl]) ** 2) / np.mean(np.abs(through(tone)[sl]) ** 2))
    assert supp >= 30.0
    n = np.arange(len(sig))
    rep = sample_code(ca_code(5), CA_CHIP_RATE * (1 + 3000 / L1_HZ), FS, len(sig), 100.0) \
        * np.exp(2j * np.pi * 3000 * n / FS)
    s_ratio = abs(np.vdot(rep[sl], through(sig)[sl])) ** 2 / abs(np.vdot(rep[sl], sig[sl])) ** 2
    n_ratio = np.mean(np.abs(through(noise)[sl]) ** 2) / np.mean(np.abs(noise[sl]) ** 2)
    loss = -10 * np.log10(s_ratio / n_ratio)
    assert abs(loss) < 0.5


class _ArrayReader:
    """The part of SampleReader the conditioned reader uses."""

    def __init__(self, x):
        self.x, self.fs, self.first, self.end = x, FS, 0, len(x)

    def read(self, start, n):
        return self.x[max(start, 0):min(start + n, self.end)].copy()


def _cond(**kw):
    return build(RECEIVER_SCHEMA, {"input": {"conditioning": kw}}).input.conditioning


def test_conditioned_reader_overlapping_chunks_are_one_continuous_filter():
    """Chunk reads overlapping as the pipeline's (chunk + overlap, step chunk) give exactly the samples of
    one read of the whole span: no block-edge discontinuity.  The tone is gone from the output."""
    sig, noise, tone = _components(250e3, 30.0, dur=0.3)
    x = sig + noise + tone + np.complex64(0.5 - 0.2j)
    whole = ConditionedReader(_ArrayReader(x), _cond()).read(0, len(x))
    r = ConditionedReader(_ArrayReader(x), _cond())
    chunk, ov = 100000, 7800
    parts = []
    for s in range(0, len(x), chunk):
        b = r.read(s, chunk + ov)
        parts.append(b[:chunk])
        assert np.array_equal(b, whole[s:s + chunk + ov])
    assert np.array_equal(np.concatenate(parts), whole)
    # the DC offset is seen as a 0 Hz line too; the DC canceller, not a notch, takes it
    assert [round(t.freq_hz) for t in r.detection.tones if t.cancelled] == [250000]
    assert all(abs(t.freq_hz) < FS / NFFT for t in r.detection.tones if not t.cancelled)
    assert abs(r.detection.dc - (0.5 - 0.2j)) < 0.05
    sl = slice(int(0.02 * FS), None)
    k = np.arange(len(x))[sl]
    resid = np.abs(np.mean(whole[sl] * np.exp(-2j * np.pi * 250e3 / FS * k))) ** 2
    assert 10 * np.log10(resid / 1000.0) < -40
    assert abs(np.mean(whole[sl])) < 0.01


def test_pulse_blanking_zeroes_pulses_only():
    x = make_signal([], FS, 0.2, seed=5)
    pulses = np.zeros(len(x), np.complex64)
    for s in range(20000, len(x), 52000):          # 20 us pulses, 30 dB above the noise
        pulses[s:s + 52] = 31.6
    r = ConditionedReader(_ArrayReader(x + pulses), _cond(pulse_blanking=True, blank_sigma=5.0))
    y = r.read(0, len(x))
    hit = pulses != 0
    assert np.all(y[hit] == 0)
    assert np.count_nonzero(y[~hit] == 0) < 1e-4 * len(x)
    assert any("pulse blanking" in line for line in r.summary_lines())


def test_static_pulse_blanking_without_any_canceller():
    """The static blanker alone (no DC removal, no tone found): its level comes from the raw span."""
    x = make_signal([], FS, 0.2, seed=6)
    pulses = np.zeros(len(x), np.complex64)
    for s in range(20000, len(x), 52000):
        pulses[s:s + 52] = 31.6
    r = ConditionedReader(_ArrayReader(x + pulses), _cond(pulse_blanking=True, blank_sigma=5.0, dc_removal=False))
    y = r.read(0, len(x))
    assert np.all(y[pulses != 0] == 0)
    assert np.count_nonzero(y[pulses == 0] == 0) < 1e-4 * len(x)


@pytest.mark.parametrize("fmt, if_hz", [("packed2_real", 4.1304e6), ("int8_iq", 0.0)])
def test_dc_removal_runs_only_where_the_front_ends_dc_is_at_0_hz(tmp_path, fmt, if_hz):
    """A decimating input stage that mixes a nonzero IF down moves the front end's DC offset to -IF: the
    stage skips the DC canceller there (the stream passes unchanged, /conditioning says where the DC is).
    A zero-IF I/Q input keeps its DC at 0 Hz through the stage, and DC removal takes it out."""
    from receiver import pipeline
    from receiver.schema import load_receiver_config
    from receiver.source.io import quantize
    fs = 16.368e6
    rng = np.random.default_rng(7)
    n = int(0.12 * fs)
    x = rng.normal(0, 1, n) + (0.0 if fmt.endswith("real") else 1j * rng.normal(0, 1, n)) + (0.4 + 0.3j)
    if fmt.endswith("real"):
        x = x.real + 0.4
    p = tmp_path / "x.bin"
    quantize(np.asarray(x, np.complex64) * (1.5 if fmt.endswith("real") else 20.0), fmt).tofile(p)
    cfg = load_receiver_config(None, [f"input.path={p}", f"input.format={fmt}", f"input.sample_rate_hz={fs}",
                                      f"input.if_hz={if_hz}"])
    r = pipeline.open_input(cfg)
    assert isinstance(r, ConditionedReader)
    y = r.read(r.first, 200_000)
    if if_hz:
        assert not r.dc_removal and r.dc_hz == -if_hz and not r.active
        assert np.array_equal(y, r._reader.read(r.first, 200_000))          # passed through unchanged
        assert any("no DC removal" in ln for ln in r.summary_lines())
    else:
        assert r.dc_removal and r.dc_hz == 0.0
        raw = r._reader.read(r.first, 200_000)
        assert abs(np.mean(raw)) > 5 * abs(np.mean(y[20_000:]))            # the DC is removed


@pytest.mark.parametrize("fmt", ["int8_iq", "uint8_iq", "int16_iq"])
@pytest.mark.parametrize("swap", [False, True])
@pytest.mark.parametrize("kw", [{}, {"pulse_blanking": True, "blank_sigma": 3.0}])
def test_dc_removal_on_the_files_integers_equals_converting_first(tmp_path, fmt, swap, kw):
    """The DC removal converts interleaved 8/16-bit I/Q as it goes (SampleReader.interleaved); its chunk
    reads, a restart elsewhere and a read continuing it equal those of the same stage over the converted
    samples, bit for bit."""
    from receiver.source.io import SampleReader, quantize
    rng = np.random.default_rng(len(fmt) + swap)
    n = 300_000
    x = (rng.normal(0, 1, n) + 1j * rng.normal(0, 1, n) + (0.4 - 0.3j)).astype(np.complex64)
    p = tmp_path / "x.bin"
    quantize(x * (3000.0 if fmt == "int16_iq" else 20.0), fmt).tofile(p)
    fr = SampleReader(p, fmt, FS, iq_swap=swap)
    assert fr.interleaved(0, 10) is not None
    direct = ConditionedReader(fr, _cond(**kw))
    converted = ConditionedReader(_ArrayReader(fr.read(0, n)), _cond(**kw))
    for s, m in [(0, 100_000), (90_000, 110_000), (250_000, 20_000), (260_000, 60_000), (5_000, 1_000)]:
        a, b = direct.read(s, m), converted.read(s, m)
        assert np.array_equal(a.view(np.uint32), b.view(np.uint32))
    assert direct.blanked == converted.blanked and direct.checks == converted.checks
