"""The input reader hands the mapped file pages behind its read position back to the kernel
(SampleReader.release_before): resident memory stays flat along a long file, and a read of a released span
gives the same samples again."""
import numpy as np
import pytest

from receiver.source import io as sio


def _rss_kb() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("RssFile:"):
                return int(line.split()[1])
    pytest.skip("no RssFile in /proc/self/status")


def _read_through(path, fs):
    r = sio.SampleReader(path, "int8_iq", fs)
    chunk = int(0.5 * fs)
    before = _rss_kb()
    peak = 0
    for start in range(r.first, r.end, chunk):
        r.read(start, chunk)
        peak = max(peak, _rss_kb() - before)
    return r, peak


@pytest.fixture(scope="module")
def long_file(tmp_path_factory):
    fs = 2.0e6
    rng = np.random.default_rng(4)
    path = tmp_path_factory.mktemp("release") / "x.bin"
    rng.integers(-60, 60, int(2 * fs * 40), dtype=np.int8).tofile(path)       # 40 s, 160 MB
    return path, fs


def test_resident_file_pages_stay_bounded(long_file, monkeypatch):
    path, fs = long_file
    _, peak = _read_through(path, fs)
    margin_kb = (sio.RELEASE_MARGIN_S * fs * 2 + 2 * sio.RELEASE_STEP_BYTES) / 1024
    assert peak < margin_kb + 8 * 1024, peak                          # ~ margin + two steps, not 160 MB
    monkeypatch.setattr(sio, "RELEASE_STEP_BYTES", 1 << 62)           # releasing off: the whole file stays
    _, peak_off = _read_through(path, fs)
    assert peak_off > 100 * 1024, peak_off


def test_a_released_span_reads_the_same_samples(long_file):
    path, fs = long_file
    r = sio.SampleReader(path, "int8_iq", fs)
    first = r.read(r.first, 1000).copy()
    r.release_before(int(30 * fs))                                    # the start of the file released
    assert r._released > 0
    np.testing.assert_array_equal(r.read(r.first, 1000), first)
    raw = np.fromfile(path, np.int8, count=2000)
    np.testing.assert_array_equal(first, (raw[0::2] + 1j * raw[1::2]).astype(np.complex64))
