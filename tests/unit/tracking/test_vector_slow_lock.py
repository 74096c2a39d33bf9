"""The vector loop's slow lock detector for weak GPS L1 C/A channels (receiver.tracking.vector.loop._slow_lock):
M2M4 over bit-aligned 20-ms sums of the 1-ms prompts tells a 27-29 dB-Hz signal from noise, which the 200-ms
window of 1-ms prompts cannot."""
import numpy as np
import pytest

from receiver.tracking import kernel as K
from receiver.tracking.vector import loop as L

BIT_OFFSET = 7          # code_period % 20 at a bit edge


def _prompts(cn0_dbhz, n_ms, rng, freq_hz=3.0, offset=BIT_OFFSET):
    """1-ms prompt sums (complex): unit complex noise, a signal of the C/N0 with random 20-ms data bits whose
    edges fall on code periods = offset (mod 20), a small residual frequency; None: noise alone."""
    z = (rng.standard_normal(n_ms) + 1j * rng.standard_normal(n_ms)) * np.sqrt(0.5)
    if cn0_dbhz is not None:
        a = np.sqrt(10 ** (cn0_dbhz / 10) * 1e-3)
        k = np.arange(n_ms)
        bits = rng.choice([-1.0, 1.0], n_ms // 20 + 2)[(k - offset) // 20 + 1]
        z += a * bits * np.exp(1j * (2 * np.pi * freq_hz * k * 1e-3 + rng.uniform(0, 2 * np.pi)))
    return z


def _run(z, nbits=50, offset=BIT_OFFSET, absent_from=None, wk=None, trace=None):
    """The detector over the prompts; returns its C/N0 after every window and the final state.  wk: the
    initial state (default: fresh); trace: a list that receives the detector's C/N0 after every prompt."""
    st = np.zeros(K.N_STATE)
    st[K.S_BIT_OFFSET] = offset
    if wk is None:
        wk = np.zeros(L.N_WK)
        wk[L.WK_MS] = -1.0
    o = np.zeros(K.N_OUT)
    o[K.O_INT_MS] = 1.0
    out = []
    for k, p in enumerate(z):
        if absent_from is not None and k >= absent_from:
            st[K.S_ABSENT_MS] = 20.0
        o[K.O_PERIOD] = 1000 + k          # the channel's code period count (offset is taken mod 20)
        o[K.O_PI] = p.real
        o[K.O_PQ] = p.imag
        n_before = wk[L.WK_N]
        L._slow_lock(wk, st, o, nbits)
        if wk[L.WK_N] == 0 and n_before == nbits - 1:
            out.append(wk[L.WK_CN0])
        if trace is not None:
            trace.append(wk[L.WK_CN0])
    return np.array(out), wk


def test_noise_alone_stays_below_the_threshold():
    rng = np.random.default_rng(11)
    cn0, _ = _run(_prompts(None, 300_000, rng))          # 300 windows of 1 s
    assert len(cn0) == 299                                # the first 7 ms wait for a bit edge
    assert cn0.max() < 24.0                               # vector.weak_lock_cn0_dbhz default


@pytest.mark.parametrize("true_cn0", [27.0, 29.0])
def test_a_weak_signal_reads_its_cn0_and_passes(true_cn0):
    rng = np.random.default_rng(int(true_cn0))
    cn0, _ = _run(_prompts(true_cn0, 100_000, rng))
    assert abs(np.median(cn0) - true_cn0) < 0.7
    assert np.mean(cn0 >= 24.0) >= 0.95


def test_misaligned_bits_lose_and_absence_resets():
    rng = np.random.default_rng(5)
    z = _prompts(29.0, 60_000, rng)
    aligned, _ = _run(z)
    wrong, _ = _run(z, offset=BIT_OFFSET + 10)            # sums straddle every data-bit edge
    assert np.median(wrong) < np.median(aligned) - 1.0
    _, wk = _run(z, absent_from=30_000)
    assert wk[L.WK_CN0] == 0.0 and wk[L.WK_N] == 0.0


def test_vector_locked_needs_presence_and_the_slow_signal_flag():
    st = np.zeros(K.N_STATE)
    wk = np.zeros(L.N_WK)
    sig = np.zeros(L.N_SIG)
    prm = np.zeros(L.N_PRM)
    prm[L.P_LOCK_CN0] = 32.0
    prm[L.P_SLOW_CN0] = 24.0
    st[K.S_CN0] = 28.0
    wk[L.WK_CN0] = 27.0
    assert not L.vector_locked(st, wk, sig, prm)          # not a GPS-like signal: the 200-ms C/N0 alone
    sig[L.SIG_SLOW] = 1.0
    assert L.vector_locked(st, wk, sig, prm)
    st[K.S_ABSENT_MS] = 20.0
    assert not L.vector_locked(st, wk, sig, prm)
    st[K.S_ABSENT_MS] = 0.0
    prm[L.P_SLOW_CN0] = 0.0                               # off
    assert not L.vector_locked(st, wk, sig, prm)
    st[K.S_CN0] = 33.0
    assert L.vector_locked(st, wk, sig, prm)


def test_a_handed_over_channel_keeps_its_scalar_cn0_until_the_first_window():
    """At the scalar-to-vector handover a channel the scalar lock detectors hold locked starts the slow
    detector with its C/N0 (VectorTracker._promote): it counts as carrying signal during the first window
    instead of coasting for it; the window's own estimate then replaces that value, and an absent signal
    clears it at once."""
    from receiver.tracking.vector.tracker import _slow_lock_reset
    rng = np.random.default_rng(3)
    z = _prompts(28.0, 3_000, rng)
    fresh, handed = [], []
    _run(z, trace=fresh)
    cn0, _ = _run(z, wk=_slow_lock_reset(29.5), trace=handed)
    fresh, handed = np.array(fresh), np.array(handed)
    first = int(np.argmax(handed != 29.5))                # the first window's end (50 bits, ~1 s)
    assert 990 <= first <= 1010
    assert np.all(fresh[:first] == 0.0)                   # a fresh detector: no signal for the first window
    assert handed[first] == cn0[0] and abs(cn0[0] - 28.0) < 2.0
    np.testing.assert_array_equal(handed[first:], fresh[first:])    # from then on the same detector
    _, wk = _run(z, wk=_slow_lock_reset(29.5), absent_from=100)
    assert wk[L.WK_CN0] == 0.0
