"""Bit detection in the navigation engine: coherent (phase-locked) and differential (frequency-locked,
vector channels) assembly of LNAV bits from prompt correlator records."""

import numpy as np
import pytest

from receiver.navigation.channel import BIT_MS, ChannelNav
from receiver.gnss.lnav import EphemerisEvent, encode_frames
from receiver.runfile.record import EPOCH_DTYPE, STATE_BIT_SYNC
from receiver.sim.constellation import nominal_ephemerides, quantize_ephemeris, quantize_iono

from repo_paths import ROOT
FS = 2.6e6


def _records(bits, freq_hz, phase0, cn0_dbhz=45.0, seed=0):
    """1-ms prompt records (and their half-ms halves) of a BPSK data signal whose carrier phase rotates
    at freq_hz (a frequency-locked channel's residual) - amplitude 1, complex noise for the C/N0."""
    n = len(bits) * BIT_MS
    k = np.arange(2 * n)                                   # half-ms steps
    d = 1.0 - 2.0 * np.repeat(bits.astype(float), 2 * BIT_MS)
    rng = np.random.default_rng(seed)
    sig = 0.5e-3 * 10 ** (cn0_dbhz / 10.0)                 # C/N0 T of a half-ms prompt (amplitude 1/2)
    noise = 0.5 * (rng.standard_normal(2 * n) + 1j * rng.standard_normal(2 * n)) / np.sqrt(2.0 * sig)
    h = 0.5 * d * np.exp(1j * (2 * np.pi * freq_hz * (k + 0.5) * 0.5e-3 + phase0)) + noise
    p1, p2 = h[0::2], h[1::2]
    p = p1 + p2
    rec = np.zeros(n, EPOCH_DTYPE)
    rec["time_s"] = np.arange(n) * 1e-3
    rec["sample_index"] = np.round(np.arange(n) * 1e-3 * FS).astype(np.int64)
    rec["code_period"] = np.arange(n)
    rec["prompt_i"], rec["prompt_q"] = p.real, p.imag
    rec["prompt1_i"], rec["prompt1_q"] = p1.real, p1.imag
    rec["prompt2_i"], rec["prompt2_q"] = p2.real, p2.imag
    rec["integration_ms"] = 1
    rec["state"] = STATE_BIT_SYNC
    rec["pll_lock"] = 1
    rec["cn0_dbhz"] = cn0_dbhz
    return rec


def _merge_bits(rec):
    """20-ms records (one per bit, as a phase-locked channel after bit sync) from 1-ms records."""
    n = len(rec) // BIT_MS
    out = rec[::BIT_MS][:n].copy()
    for c in ("prompt_i", "prompt_q"):
        out[c] = rec[c][:n * BIT_MS].reshape(n, BIT_MS).sum(axis=1)
    for c, src in (("prompt1_i", "prompt_i"), ("prompt1_q", "prompt_q")):
        out[c] = rec[src][:n * BIT_MS].reshape(n, BIT_MS)[:, :BIT_MS // 2].sum(axis=1)
    for c, src in (("prompt2_i", "prompt_i"), ("prompt2_q", "prompt_q")):
        out[c] = rec[src][:n * BIT_MS].reshape(n, BIT_MS)[:, BIT_MS // 2:].sum(axis=1)
    out["integration_ms"] = BIT_MS
    return out


def _decode(rec, noncoherent_from=None, chunk=487):          # chunks end inside bits
    ch = ChannelNav(5, 2300, 0.0, FS)
    ch.set_noncoherent(noncoherent_from)
    events = []
    orig = ch.decoder.feed

    def feed(bits, first):
        ev = orig(bits, first)
        events.extend(ev)
        return ev
    ch.decoder.feed = feed
    for a in range(0, len(rec), chunk):
        ch.add(rec[a:a + chunk], 0)
    return ch, events


@pytest.fixture(scope="module")
def frames():
    ephs, iono = nominal_ephemerides(ROOT / "data" / "gps_nominal_constellation.yaml", 2300, 345600.0)
    eph = quantize_ephemeris(ephs[5])
    bits = encode_frames(eph, quantize_iono(iono), 345600.0, 2300, 2)
    # a few bits more: a bit is complete when the next one starts
    return eph, np.concatenate([bits, np.array([1, 0, 0, 1], np.uint8)])


def test_differential_detection_decodes_a_frequency_locked_channel(frames):
    eph, bits = frames
    rec = _records(bits, freq_hz=6.0, phase0=1.0)           # 6 Hz residual: the prompt phase wanders
    ch, events = _decode(rec, noncoherent_from=0)
    assert ch.decoder.ephemeris is not None and any(isinstance(e, EphemerisEvent) for e in events)
    assert ch.decoder.ephemeris.sqrt_a == eph.sqrt_a and ch.decoder.ephemeris.m0 == eph.m0
    assert ch.decoder.parity_failures == 0
    assert ch.has_time
    # the in-phase sum of the same records (coherent detection) cannot decode them
    ch2, _ = _decode(rec, noncoherent_from=None)
    assert ch2.decoder.ephemeris is None and not ch2.has_time


def test_handover_from_phase_lock_to_frequency_lock_keeps_the_bit_stream(frames):
    eph, bits = frames
    n_bits = len(bits)
    half = (n_bits // 2) * BIT_MS + 7                       # the switch in the middle of a bit
    a = _records(bits, freq_hz=0.0, phase0=0.0, seed=1)      # phase-locked: I carries the bits
    # frequency-locked afterwards: the NCO keeps its phase at the switch, the residual starts there
    b = _records(bits, freq_hz=-9.0, phase0=2 * np.pi * 9.0 * half * 1e-3, seed=2)
    rec = np.concatenate([a[:half], b[half:]])
    ch, events = _decode(rec, noncoherent_from=int(rec["sample_index"][half]))
    sf = [e for e in events if type(e).__name__ == "SubframeEvent"]
    # 2 frames = 10 subframes, every one decoded across the switch
    assert len(sf) == 10 and ch.decoder.parity_failures == 0
    assert ch.decoder.ephemeris.sqrt_a == eph.sqrt_a


@pytest.mark.parametrize("freq_hz", [-20.0, 30.0, 45.0])
def test_differential_detection_tolerates_large_frequency_residuals(frames, freq_hz):
    """Adjacent half-bits (10 ms apart) with the rotation measured inside the bits: residuals beyond the
    +/-12.5 Hz that a plain bit-to-bit comparison (20 ms) tolerates still decode."""
    _, bits = frames
    ch, events = _decode(_records(bits, freq_hz=freq_hz, phase0=0.7, seed=5), noncoherent_from=0)
    assert sum(type(e).__name__ == "SubframeEvent" for e in events) == 10
    assert ch.decoder.parity_failures == 0


def test_twenty_ms_phase_locked_epochs_then_vector_epochs(frames):
    """A phase-locked channel's 20-ms epochs (halves in prompt1/prompt2), then 1-ms vector epochs."""
    eph, bits = frames
    half = (len(bits) // 2) * BIT_MS
    a = _merge_bits(_records(bits, freq_hz=0.0, phase0=0.0, seed=6)[:half])
    b = _records(bits, freq_hz=15.0, phase0=-2 * np.pi * 15.0 * half * 1e-3, seed=7)[half:]
    rec = np.concatenate([a, b])
    ch, events = _decode(rec, noncoherent_from=int(b["sample_index"][0]), chunk=40)
    assert sum(type(e).__name__ == "SubframeEvent" for e in events) == 10
    assert ch.decoder.parity_failures == 0 and ch.decoder.ephemeris.sqrt_a == eph.sqrt_a


def test_differential_detection_at_low_cn0_loses_little(frames):
    """At 30 dB-Hz (Eb/N0 17 dB) differential detection still decodes every subframe."""
    _, bits = frames
    ch, events = _decode(_records(bits, freq_hz=3.0, phase0=0.3, cn0_dbhz=30.0, seed=4), noncoherent_from=0)
    assert sum(type(e).__name__ == "SubframeEvent" for e in events) == 10


def test_lock_guard_is_shorter_for_channels_the_presence_test_judges():
    """A measurement needs lock at its epoch and a guard time later (the lock detectors lag a vanished
    signal): 0.1 s, but 0.04 s for a channel strong enough for the signal-presence test (C/N0 >= the
    engine's presence_cn0), whose lock flag goes within ~35 ms."""
    fs = 1e5
    ch = ChannelNav(5, 2300, 0.0, fs)
    rec = np.zeros(100, EPOCH_DTYPE)                 # 20-ms epochs, lock lost at 1.0 s
    rec["sample_index"] = np.arange(100) * 0.02 * fs
    rec["time_s"] = rec["sample_index"] / fs
    rec["pll_lock"] = rec["time_s"] < 1.0
    rec["cn0_dbhz"] = np.where(rec["pll_lock"], 45.0, 0.0)
    rec["state"] = STATE_BIT_SYNC
    ch.recent.append(rec)
    s = 0.94 * fs                                     # 60 ms before the loss
    assert not ch.locked_at(s)
    assert ch.locked_at(s, presence_cn0=33.0)
    assert not ch.locked_at(0.98 * fs, presence_cn0=33.0)     # 20 ms before: still excluded
    rec["cn0_dbhz"][rec["pll_lock"] > 0] = 30.0          # too weak for the presence test: the long guard
    assert not ch.locked_at(s, presence_cn0=33.0)


def test_frequency_locked_epochs_without_signal_are_a_gap_not_bits(frames):
    """A vector channel coasting through a total outage keeps producing prompts - noise, its C/N0 zeroed by
    the presence test.  Demodulated, about half of the random words pass parity with single-bit correction
    (issue 14, seed 2: a subframe 2 whose IODE word came before the outage gave a set 82 000 km off).  Those
    epochs are a gap in the bit stream: no word is decoded from them; the subframes around decode."""
    eph, bits = frames
    rec = _records(bits, freq_hz=4.0, phase0=0.5, seed=8)
    a, b = (1500 + 300 + 90) * BIT_MS, (1500 + 600) * BIT_MS        # frame 2, subframe 2 words 4-10
    rng = np.random.default_rng(9)
    for c in ("prompt1_i", "prompt1_q", "prompt2_i", "prompt2_q"):
        rec[c][a:b] = 0.1 * rng.standard_normal(b - a)
    rec["prompt_i"][a:b] = rec["prompt1_i"][a:b] + rec["prompt2_i"][a:b]
    rec["prompt_q"][a:b] = rec["prompt1_q"][a:b] + rec["prompt2_q"][a:b]
    rec["cn0_dbhz"][a:b] = 0.0
    rec["pll_lock"][a:b] = 0
    ch, events = _decode(rec, noncoherent_from=0)
    assert ch.decoder.parity_failures == 0 and ch.decoder.words_corrected == 0
    sf = [e.subframe_id for e in events if type(e).__name__ == "SubframeEvent"]
    assert sf == [1, 2, 3, 4, 5, 1, 3, 4, 5]                    # all but the one with the gap
    assert ch.decoder.ephemeris.sqrt_a == eph.sqrt_a and ch.decoder.ephemeris.crs == eph.crs
