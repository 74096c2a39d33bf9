"""The compiled / reordered forms of the input stage's hot paths give numpy's values exactly: the tone
detector's running median, the excision test's per-bin floor, the interleaved-integer reader."""
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
