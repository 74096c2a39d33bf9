import numpy as np
import pytest

from receiver.errors import UserError
from receiver.source.io import FORMATS, SampleReader, SampleWriter, bytes_per_sample, is_complex, quantize


@pytest.mark.parametrize("fmt", sorted(f for f in FORMATS if FORMATS[f].kind in ("int", "float")))
def test_round_trip(tmp_path, fmt):
    rng = np.random.default_rng(1)
    x = (rng.normal(size=5000) + 1j * rng.normal(size=5000)) * 20
    path = tmp_path / f"x.{fmt}"
    with SampleWriter(path, fmt) as w:
        w.write(x[:2000])
        w.write(x[2000:])
    assert path.stat().st_size == 5000 * bytes_per_sample(fmt)
    r = SampleReader(path, fmt, 1e6)
    assert r.n_samples == 5000
    y = r.read(0, 5000)
    assert y.dtype == np.complex64
    expect = x if is_complex(fmt) else x.real + 0j
    if fmt.startswith("int8"):
        expect = np.clip(np.round(expect.real), -128, 127) + 1j * np.clip(np.round(expect.imag), -128, 127)
    elif fmt.startswith("int16"):
        expect = np.round(expect.real) + 1j * np.round(expect.imag)
    np.testing.assert_allclose(y, expect, atol=1e-3 * 20)
    # chunks with overlap tile the file
    got = np.concatenate([b[:1000] for _, b in r.chunks(1000, overlap=10)])
    np.testing.assert_array_equal(got, y)


def test_iq_swap_and_span(tmp_path):
    x = np.arange(100) + 1j * (1000 + np.arange(100))
    p = tmp_path / "a.bin"
    quantize(x, "int16_iq").tofile(p)
    r = SampleReader(p, "int16_iq", 10.0, skip_s=1.0, duration_s=2.0, iq_swap=True)
    assert (r.first, r.end) == (10, 30)
    y = r.read(0, 100)                           # clipped to the span
    assert len(y) == 20
    assert y[0] == 1010 + 10j


def test_real_spectral_inversion(tmp_path):
    p = tmp_path / "r.bin"
    quantize(np.array([1, 2, 3, 4]), "int8_real").tofile(p)
    y = SampleReader(p, "int8_real", 4.0, iq_swap=True).read(0, 4)
    np.testing.assert_array_equal(y.real, [1, -2, 3, -4])


def test_truncated_and_missing_files(tmp_path):
    p = tmp_path / "t.bin"
    p.write_bytes(b"\x01\x02\x03")                # 1.5 int8_iq samples
    with pytest.raises(UserError, match="truncated"):
        SampleReader(p, "int8_iq", 1e6)
    with pytest.raises(UserError, match="not found"):
        SampleReader(tmp_path / "nope.bin", "int8_iq", 1e6)
    e = tmp_path / "e.bin"
    e.write_bytes(b"")
    with pytest.raises(UserError, match="empty"):
        SampleReader(e, "int8_iq", 1e6)
    with pytest.raises(UserError, match="unknown input format"):
        SampleReader(p, "int12_iq", 1e6)


def test_memory_does_not_scale_with_file(tmp_path):
    """The reader memory-maps: opening a large file allocates nothing proportional to it."""
    import tracemalloc
    p = tmp_path / "big.bin"
    with open(p, "wb") as fh:
        fh.truncate(200_000_000)                 # sparse 200 MB file
    tracemalloc.start()
    r = SampleReader(p, "int8_iq", 2.6e6)
    blocks = 0
    for _, b in r.chunks(1_300_000):
        blocks += 1
        if blocks == 10:
            break
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 40e6
