"""The compiled per-bit prompt sums of ChannelNav.add (receiver.navigation.bits_jit) are bit-identical to the
numpy computation they replaced (np.add.reduceat's pairwise summation included)."""
import numpy as np
import pytest

from receiver.navigation.bits_jit import _segment_sum, bit_segments
from receiver.runfile.record import EPOCH_DTYPE


def _numpy_segments(r, bit_offset, bit_ms, nc_from):
    """The numpy version (as ChannelNav.add computed it before)."""
    bits_idx = (r["code_period"] - bit_offset) // bit_ms
    nc = (np.zeros(len(r), bool) if nc_from is None else r["sample_index"] >= nc_from)
    starts = np.flatnonzero(np.r_[True, bits_idx[1:] != bits_idx[:-1]])
    o = (r["code_period"] - bit_offset) % bit_ms
    late1 = o >= bit_ms // 2
    late2 = 2 * o + r["integration_ms"] >= bit_ms
    p1 = r["prompt1_i"].astype(np.float64) + 1j * r["prompt1_q"].astype(np.float64)
    p2 = r["prompt2_i"].astype(np.float64) + 1j * r["prompt2_q"].astype(np.float64)
    ha = np.where(late1, 0.0, p1) + np.where(late2, 0.0, p2)
    hb = (p1 + p2) - ha

    def csum(x):
        return (np.add.reduceat(x.real, starts) + 1j * np.add.reduceat(x.imag, starts)).tolist()

    return list(zip(bits_idx[starts].tolist(), csum(ha), csum(hb),
                    np.add.reduceat(r["integration_ms"].astype(np.int64), starts).tolist(),
                    (np.add.reduceat(nc.astype(np.int64), starts) > 0).tolist()))


def _records(n, epoch_ms, seed, cp0=0):
    rng = np.random.default_rng(seed)
    r = np.zeros(n, EPOCH_DTYPE)
    r["code_period"] = cp0 + np.arange(n) * epoch_ms
    r["integration_ms"] = epoch_ms
    r["sample_index"] = np.arange(n) * epoch_ms * 4000
    for k in ("prompt1_i", "prompt1_q", "prompt2_i", "prompt2_q"):
        r[k] = rng.normal(0, 1, n) * 10.0 ** rng.uniform(-2, 4, n)
    return r


@pytest.mark.parametrize("epoch_ms,bit_ms,bit_offset", [(1, 20, 7), (1, 20, 0), (5, 20, 3), (10, 20, 13),
                                                         (20, 20, 11), (1, 2, 1), (2, 2, 0)])
def test_bit_segments_equal_numpy(epoch_ms, bit_ms, bit_offset):
    for seed, cp0 in ((1, 0), (2, 1234), (3, 5)):
        r = _records(517, epoch_ms, seed, cp0)
        for nc_from in (None, 0, int(r["sample_index"][200]) + 1):
            ref = _numpy_segments(r, bit_offset, bit_ms, nc_from)
            got = bit_segments(r["code_period"], r["integration_ms"], r["sample_index"], r["prompt1_i"],
                               r["prompt1_q"], r["prompt2_i"], r["prompt2_q"], bit_offset, bit_ms,
                               -1 if nc_from is None else nc_from)
            seg_bit, ar, ai, br, bi, ms, nc = got
            mine = list(zip(seg_bit.tolist(), (ar + 1j * ai).tolist(), (br + 1j * bi).tolist(), ms.tolist(),
                            nc.tolist()))
            assert mine == ref                      # exact, element by element


def test_segment_sum_is_reduceat():
    rng = np.random.default_rng(4)
    for n in (1, 2, 7, 8, 9, 16, 127, 128, 129, 300, 1000):
        x = rng.normal(size=n) * 10.0 ** rng.uniform(-3, 6, n)
        starts = np.unique(np.r_[0, rng.integers(0, n, 3)])
        ends = np.r_[starts[1:], n]
        assert [_segment_sum(x, s, e) for s, e in zip(starts, ends)] == np.add.reduceat(x, starts).tolist()
