import numpy as np
import pytest

from receiver.tracking.correlator import correlate, correlate_reference, extend_code
from receiver.gnss.signals import ca_code


@pytest.mark.parametrize("code_phase,code_step,carr_phase,carr_step,n", [
    (0.0, 1.023 / 2.6, 0.0, 0.0, 2600),
    (0.37, 1.023e6 * (1 + 1e-6) / 2.6e6, 0.25, 1500.0 / 2.6e6, 2601),
    (0.9, 1.023e6 / 4.0e6, -3.4, -4200.0 / 4.0e6, 20460),
    (12.5, 1.023e6 / 2.046e6, 0.8, 300.0 / 2.046e6, 999),
])
def test_fast_correlator_matches_numpy_reference(code_phase, code_step, carr_phase, carr_step, n):
    rng = np.random.default_rng(3)
    x = (rng.normal(size=n + 50) + 1j * rng.normal(size=n + 50)).astype(np.complex64) * 5
    # add a correlated component so the comparison is not only noise
    k = np.arange(n + 50)
    code = ca_code(7)
    x += (3 * code[np.floor(code_phase + (k - 10) * code_step).astype(int) % 1023]
          * np.exp(2j * np.pi * (carr_phase + (k - 10) * carr_step))).astype(np.complex64)
    ext = extend_code(code, 20)
    fast = correlate(x, 10, n, ext, code_phase, code_step, 0.25, carr_phase, carr_step)
    ref = correlate_reference(x, 10, n, code, code_phase, code_step, 0.25, carr_phase, carr_step)
    scale = abs(ref[1])
    assert scale > 2 * n     # the prompt sees the signal
    for f, r in zip(fast, ref):
        # float32 carrier table (the old 1024-entry phase table: <= pi/1024 rad per sample); a sample at a chip
        # boundary may fall on the other chip (32.32 fixed-point code NCO against float64 floor)
        assert abs(f - r) <= 4e-3 * scale + 1e-3 * np.sqrt(n) * 5


def test_early_late_symmetry_on_aligned_signal():
    n = 26000
    fs = 2.6e6
    k = np.arange(n)
    code = ca_code(3)
    step = 1.023e6 / fs
    x = code[np.floor(0.3 + k * step).astype(int) % 1023].astype(np.complex64)
    e, p, l, p1, p2 = correlate(x, 0, n, extend_code(code, 20), 0.3, step, 0.25, 0.0, 0.0)
    assert abs(e) == pytest.approx(abs(l), rel=0.02)
    assert abs(e) / abs(p) == pytest.approx(0.75, abs=0.03)      # triangle at +/- 0.25 chip
    assert abs(p1 + p2 - p) < 1e-3 * abs(p)


def test_carrier_wipe_off_stays_coherent_over_a_20_ms_epoch():
    """A noise-free signal matching the NCOs: the prompt of a 20-ms epoch (52000 samples, 102 correlation
    blocks) is the sample count, real, in both halves (the blockwise float32 carrier table and the float64
    block phasors keep the phase to ~1e-7 rad; the former 1024-entry phase table left a 1.5e-5 rad bias)."""
    fs = 2.6e6
    n = 52000
    step = 1.023e6 / fs * (1 + 2e-6)
    carr = 4321.7 / fs
    k = np.arange(n + 10)
    code = ca_code(5)
    x = (code[np.floor(0.2 + (k - 5) * step).astype(int) % 1023]
         * np.exp(2j * np.pi * (0.3 + (k - 5) * carr))).astype(np.complex64)
    e, p, l, p1, p2 = correlate(x, 5, n, extend_code(code, 20), 0.2, step, 0.25, 0.3, carr)
    assert abs(p) / n == pytest.approx(1.0, abs=1e-6)
    for v in (p, p1, p2):
        assert abs(np.angle(v)) < 1e-6
    assert abs(p1) == pytest.approx(n // 2, rel=1e-6)
    assert abs(e) / n == pytest.approx(0.75, abs=0.01) and abs(l) / n == pytest.approx(0.75, abs=0.01)


def test_signed_index_block_sums_equal_the_unsigned_fast_path():
    """The block sums with unsigned code indices (the fast path) and with signed ones (the fallback for a
    code phase outside the extended code; the same function compiled for int64) are the same arithmetic:
    equal to the last bit."""
    from receiver.tracking.correlator import _block_sums
    rng = np.random.default_rng(5)
    m = 512
    xs = (rng.normal(size=m) + 1j * rng.normal(size=m)).astype(np.complex64)
    ph = 2 * np.pi * 1234.5 / 2.6e6 * np.arange(m)
    rr, ri = np.cos(-ph).astype(np.float32), np.sin(-ph).astype(np.float32)
    ext = extend_code(ca_code(9), 20)
    cp, dcp, hel = int(37.3 * 2 ** 32), int(1.023 / 2.6 * 2 ** 32), 2 ** 30
    a = _block_sums(xs, rr, ri, ext, np.uint64(cp), np.uint64(dcp), np.uint64(hel), np.uint64(32), m)
    b = _block_sums(xs, rr, ri, ext, np.int64(cp), np.int64(dcp), np.int64(hel), np.int64(32), m)
    assert a == b and abs(a[2]) > 0
