"""Pulsed-interference detection and adaptive blanking (receiver/source/pulses.py, through the conditioning
stage): pulses found and blanked, a weak signal kept, nothing changed on noise alone or by a tone
switching on, output independent of the read split."""
import numpy as np
import pytest

from receiver.source.conditioning import ConditionedReader
from receiver.source.pulses import pulse_test

from test_source_conditioning import FS, _ArrayReader, _cond  # noqa: E402  (the same stand-in reader)


def _noise(n, seed):
    rng = np.random.default_rng(seed)
    return ((rng.standard_normal(n) + 1j * rng.standard_normal(n)) / np.sqrt(2)).astype(np.complex64)


def _pulses(n, jnr_db, period_s=1e-3, duty=0.1, f=300e3, start_s=0.0):
    k = np.arange(n)
    t = k / FS
    on = (t >= start_s) & (np.mod(t - start_s, period_s) < duty * period_s)
    return np.where(on, np.sqrt(10 ** (jnr_db / 10)) * np.exp(2j * np.pi * f / FS * k), 0).astype(np.complex64), on


def _code(n, seed, amp):
    """A stand-in satellite signal: random +/-1 chips at 1 MHz, amplitude amp (per sample)."""
    rng = np.random.default_rng(seed)
    chips = rng.choice([-1.0, 1.0], size=n // 2 + 2)
    return (amp * chips[(np.arange(n) * 1e6 / FS).astype(int)]).astype(np.complex64)


def test_pulse_test_finds_pulse_trains_not_noise_or_a_tone_switching_on():
    """Noise alone (any seed) and a +35 dB tone switching on mid-span are not pulsed; 10 % pulses at +10 and
    +40 dB are, with their share of blocks and the noise floor (1) measured."""
    n = int(0.02 * FS)
    for seed in range(5):
        assert not pulse_test(_noise(n, seed)).pulsed
    k = np.arange(n)
    step = np.where(k > n // 2, np.sqrt(10 ** 3.5) * np.exp(0.3j * k), 0).astype(np.complex64)
    assert not pulse_test(_noise(n, 9) + step).pulsed
    for jnr in (10.0, 40.0):
        p, on = _pulses(n, jnr)
        t = pulse_test(_noise(n, 2) + p)
        assert t.pulsed and t.runs == 20 and abs(t.floor - 1.0) < 0.1
        assert 0.09 < t.fraction < 0.13


def test_blanker_removes_pulses_and_keeps_the_signal():
    """+40 dB pulses (10 % of every ms) on noise and a weak signal: the blanker is on from the start, the
    blanked share is between the duty cycle and duty + 5 %, no pulse power is left (output power <= the
    noise's), and the signal's correlation keeps >= (1 - blanked share) of its amplitude (its SNR falls by
    the blanked share only)."""
    n = int(0.4 * FS)
    sig = _code(n, 1, 0.1)
    p, on = _pulses(n, 40.0)
    x = _noise(n, 3) + sig + p
    r = ConditionedReader(_ArrayReader(x), _cond())
    y = np.concatenate([r.read(s, 100000)[:100000] for s in range(0, n, 100000)])
    assert r.canceller.pulse_on and r.pulse_events[0][1] == "on"
    b = r.blanked_fraction
    assert 0.1 <= b <= 0.15
    assert np.all(y[on] == 0)
    assert np.mean(np.abs(y) ** 2) < 1.0 + 0.01
    a = np.real(np.vdot(sig, y)) / np.real(np.vdot(sig, sig))
    assert 1 - b - 0.03 < a < 1 - b + 0.03
    assert any("pulsed interference" in line for line in r.summary_lines())


@pytest.mark.slow
def test_pulses_starting_mid_stream_switch_the_blanker_on_and_off_again():
    """Pulses from 0.3 s to 0.6 s: the monitor switches blanking on within one check and off after the
    quiet checks; before the pulses the output is exactly the blanker-less stage's."""
    n = int(1.0 * FS)
    p, on = _pulses(n, 30.0, start_s=0.3)
    on &= np.arange(n) / FS < 0.6
    x = _noise(n, 5) + np.where(on, p, 0).astype(np.complex64)
    cfg = _cond(monitor_ms=50.0)
    r = ConditionedReader(_ArrayReader(x), cfg)
    y = np.concatenate([r.read(s, 200000)[:200000] for s in range(0, n, 200000)])
    ev = [(s / FS, w) for s, w, _, _ in r.pulse_events]
    assert [w for _, w in ev] == ["on", "off"]
    span_s = cfg.fft_size * cfg.monitor_segments / FS
    assert 0.3 < ev[0][0] <= 0.3 + 0.05 + span_s + 1e-3
    assert 0.6 < ev[1][0] < 0.6 + 5 * 0.05 + span_s
    pre = int(0.3 * FS)
    ref = ConditionedReader(_ArrayReader(x[:pre]), _cond(monitor_ms=50.0, pulse_detection=False))
    assert np.array_equal(y[:pre], ref.read(0, pre))
    blanked_on = np.mean(y[int(0.4 * FS):int(0.6 * FS)][on[int(0.4 * FS):int(0.6 * FS)]] == 0)
    assert blanked_on == 1.0


def test_noise_alone_is_untouched_by_the_detector():
    """On noise (and a DC offset) the stage's output is bit for bit the one without pulse detection."""
    n = int(0.6 * FS)
    x = _noise(n, 11) + np.complex64(0.3 - 0.1j)
    a = ConditionedReader(_ArrayReader(x), _cond(monitor_ms=50.0))
    b = ConditionedReader(_ArrayReader(x), _cond(monitor_ms=50.0, pulse_detection=False, tf_excision=False))
    ya = np.concatenate([a.read(s, 150000)[:150000] for s in range(0, n, 150000)])
    yb = np.concatenate([b.read(s, 150000)[:150000] for s in range(0, n, 150000)])
    assert np.array_equal(ya, yb) and not a.pulse_events and not a.tf_events


def test_blanked_output_does_not_depend_on_the_read_split():
    """Overlapping chunk reads give, with the blanker on, the samples of one read of the whole span."""
    n = int(0.5 * FS)
    p, _ = _pulses(n, 35.0, period_s=0.7e-3, duty=0.2)
    x = _noise(n, 7) + p
    whole = ConditionedReader(_ArrayReader(x), _cond(monitor_ms=50.0)).read(0, n)
    r = ConditionedReader(_ArrayReader(x), _cond(monitor_ms=50.0))
    parts = []
    for s in range(0, n, 90001):
        parts.append(r.read(s, 90001 + 3333)[:90001])
    assert np.array_equal(np.concatenate(parts)[:n], whole)
