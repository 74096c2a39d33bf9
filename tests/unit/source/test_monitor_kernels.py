"""The compiled / reordered forms of the input stage's hot paths give numpy's values exactly: the tone
detector's running median, the excision test's per-bin floor, the interleaved-integer reader; the monitor's
screens never skip what the full tests would find."""
import numpy as np
import pytest

from receiver.source import excision, io, tones


def _windows_median(x, w):
    h = w // 2
    return np.median(np.lib.stride_tricks.sliding_window_view(np.concatenate([x[-h:], x, x[:h]]), w), axis=-1)


@pytest.mark.parametrize("n,w", [(4096, 129), (64, 17), (129, 129), (300, 3)])
def test_running_median_equals_numpys_median_of_each_window(n, w):
    rng = np.random.default_rng(n + w)
    for trial in range(6):
        x = rng.exponential(size=n)
        if trial % 2:
            x = np.round(x, 1)                  # ties
        if trial == 4:
            x = np.sort(x)                      # a monotonic spectrum (roll-off)
        np.testing.assert_array_equal(tones.running_median_circular(x, w), _windows_median(x, w))


def test_running_median_of_a_spectrum_with_inf_falls_back_on_numpy():
    x = np.random.default_rng(3).exponential(size=256)
    x[17] = np.inf
    np.testing.assert_array_equal(tones.running_median_circular(x, 33), _windows_median(x, 33))


@pytest.mark.parametrize("shape", [(256, 128), (255, 64), (1, 32), (2, 3)])
def test_bin_floor_is_the_per_bin_median(shape):
    rng = np.random.default_rng(shape[0])
    for dt in (np.float64, np.float32):
        p = rng.exponential(size=shape).astype(dt)
        want = np.maximum(np.median(p, axis=0) / excision.LN2, 1e-30)
        got = excision.bin_floor(p)
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("dtype,offset", [(np.int8, 0.0), (np.uint8, 127.5), (np.int16, 0.0)])
@pytest.mark.parametrize("swap", [False, True])
def test_deinterleave_equals_numpys_strided_assignment(dtype, offset, swap):
    info = np.iinfo(dtype)
    raw = np.random.default_rng(5).integers(info.min, info.max, size=4000, endpoint=True).astype(dtype)
    want = np.empty(2000, np.complex64)
    i, q = (raw[1::2], raw[0::2]) if swap else (raw[0::2], raw[1::2])
    want.real, want.imag = i, q
    if offset:
        want -= np.complex64(offset + 1j * offset)
    got = np.empty(2000, np.complex64)
    io._deinterleave(raw, swap, np.complex64(offset + 1j * offset), got)
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))


@pytest.mark.parametrize("n,fb", [(4096, 129), (512, 129), (256, 65)])
def test_floor_bound_is_below_the_running_median(n, fb):
    rng = np.random.default_rng(n + fb)
    fb = min(fb, n // 4) | 1
    for trial in range(6):
        x = rng.exponential(size=n)
        if trial % 2:
            x = np.round(x, 1)                  # ties
        if trial == 4:
            x = np.sort(x)                      # a roll-off
        if trial == 5:
            x[n // 3] = 1e6                     # a tone
        lb = tones._floor_lower_bound(x, fb)
        assert lb is not None and lb.shape == x.shape
        assert np.all(lb <= tones.running_median_circular(x, fb))


def _noise(rng, n, tone_db=None, f=0.1234):
    x = (rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64)
    if tone_db is not None:
        a = np.complex64(np.sqrt(2 * 10 ** (tone_db / 10)))
        x += a * np.exp(2j * np.pi * f * np.arange(n)).astype(np.complex64)
    return x


def test_screened_tone_detection_finds_what_the_full_detector_finds():
    """Screened, the detector skips the floor only where the full detector finds no tone; with a tone in
    the span it returns the full detector's result (pfa high enough that noise spans cross the screen)."""
    rng = np.random.default_rng(11)
    skipped = 0
    for trial in range(60):
        tone = None if trial % 3 else -25.0 + trial / 6          # weak tones near the threshold too
        x = _noise(rng, 32768, tone)
        for pfa in (1e-6, 0.5):
            full = tones.detect_tones(x, 2.6e6, 4096, pfa, 6.0, 16)
            got = tones.detect_tones(x, 2.6e6, 4096, pfa, 6.0, 16, screen=True)
            if got is None:
                skipped += 1
                assert full.tones == []
            else:
                assert [t.freq_hz for t in got.tones] == [t.freq_hz for t in full.tones]
                assert got.noise_power == full.noise_power
    assert skipped >= 30                                          # the screen does skip clean spans


def test_pulse_screen_never_hides_a_pulsed_span():
    from receiver.source import pulses
    rng = np.random.default_rng(5)
    seen = {True: 0, False: 0}
    for trial in range(80):
        x = _noise(rng, 32768)
        for k in range(trial % 6):                                # 0..5 pulses of 2-40 blocks, 3-9 dB
            a = int(rng.integers(0, 32000))
            x[a:a + int(rng.integers(32, 640))] *= np.float32(10 ** (rng.uniform(3, 9) / 20))
        pt = pulses.pulse_test(x, 6.0, 3)
        screen = pulses.may_be_pulsed(x, 6.0, 3)
        assert screen or not pt.pulsed
        seen[pt.pulsed] += 1
    assert seen[True] > 5 and seen[False] > 5
    assert not pulses.may_be_pulsed(_noise(rng, 32768))           # a clean span is screened out
    assert pulses.may_be_pulsed(np.zeros(32768, np.complex64))    # no floor: the full test decides
