"""Bit detection in the navigation engine: coherent (phase-locked) and differential (frequency-locked,
vector channels) assembly of LNAV bits from prompt correlator records."""
from pathlib import Path

import numpy as np
import pytest

from receiver.nav.engine import BIT_MS, ChannelNav
from receiver.nav.lnav import EphemerisEvent, encode_frames
from receiver.record import EPOCH_DTYPE, STATE_BIT_SYNC
from receiver.sim.constellation import nominal_ephemerides, quantize_ephemeris, quantize_iono

ROOT = Path(__file__).resolve().parents[1]
FS = 2.6e6


def _records(bits, freq_hz, phase0, cn0_dbhz=45.0, seed=0):
    """1-ms prompt records of a BPSK data signal whose carrier phase rotates at freq_hz (a frequency-
    locked channel's residual) - amplitude 1, complex noise for the given C/N0."""
    n = len(bits) * BIT_MS
    k = np.arange(n)
    d = 1.0 - 2.0 * np.repeat(bits.astype(float), BIT_MS)
    rng = np.random.default_rng(seed)
    sig = 1e-3 * 10 ** (cn0_dbhz / 10.0)                   # C/N0 T: SNR of one 1-ms prompt
    noise = (rng.standard_normal(n) + 1j * rng.standard_normal(n)) / np.sqrt(2.0 * sig)
    p = d * np.exp(1j * (2 * np.pi * freq_hz * k * 1e-3 + phase0)) + noise
    rec = np.zeros(n, EPOCH_DTYPE)
    rec["time_s"] = k * 1e-3
    rec["sample_index"] = np.round(k * 1e-3 * FS).astype(np.int64)
    rec["code_period"] = k
    rec["prompt_i"], rec["prompt_q"] = p.real, p.imag
    rec["integration_ms"] = 1
    rec["state"] = STATE_BIT_SYNC
    rec["pll_lock"] = 1
    rec["cn0_dbhz"] = cn0_dbhz
    return rec


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
    b = _records(bits, freq_hz=-9.0, phase0=2.5, seed=2)     # frequency-locked afterwards
    rec = np.concatenate([a[:half], b[half:]])
    ch, events = _decode(rec, noncoherent_from=int(rec["sample_index"][half]))
    sf = [e for e in events if type(e).__name__ == "SubframeEvent"]
    # 2 frames = 10 subframes, every one decoded across the switch
    assert len(sf) == 10 and ch.decoder.parity_failures == 0
    assert ch.decoder.ephemeris.sqrt_a == eph.sqrt_a


def test_differential_detection_at_low_cn0_loses_little(frames):
    """At 30 dB-Hz (Eb/N0 17 dB) differential detection still decodes every subframe."""
    _, bits = frames
    ch, events = _decode(_records(bits, freq_hz=3.0, phase0=0.3, cn0_dbhz=30.0, seed=4), noncoherent_from=0)
    assert sum(type(e).__name__ == "SubframeEvent" for e in events) == 10
