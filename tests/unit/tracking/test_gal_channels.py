"""Galileo E1 channels of the pipeline (receiver.tracking.gal_channels.GalTrack) on a synthetic E1 signal made
here from the ICD codes: E1-B (BOC(1,1), +/-1 symbols per 4-ms period) and E1-C (BOC(1,1) x CS25, transmitted as
-e_C, ICD Eq. 11) at a known Doppler and code phase, 45 dB-Hz in seeded noise.  The pilot refinement finds the
CS25 phase and the Doppler; the channel's records follow the true code phase and Doppler, carry the E1-B
symbols, are the same whether the samples come in one block or in chunks, and equal the stand-alone
GalChannel's on the interleaved I/Q samples; on a noise-free signal the code settles on the true code phase
(no per-Doppler bias) at the pipeline's DLL bandwidth and a narrow one."""
import types

import numpy as np
import pytest

from receiver.acquisition.galileo import refine_pilot
from receiver.gnss.gal_codes import E1_CHIP_RATE, E1_HZ, boc11, cs25_signs, e1b_code, e1c_code
from receiver.runfile.record import EPOCH_DTYPE, STATE_BIT_SYNC
from receiver.tracking.gal import GalChannel
from receiver.tracking.gal_channels import DLL_BW_HZ, DLL_SPACING, PLL_BW_HZ, GalTrack

pytestmark = pytest.mark.slow          # (numba compiles, seconds of samples)
FS = 4.0e6
PRN, DOP, CP0, OFF = 11, 1234.5, 1000.3, 7
DUR = 0.8
TRK = types.SimpleNamespace(lock_cn0_min_dbhz=25.0, lost_ms=200)


@pytest.fixture(scope="module")
def signal():
    rng = np.random.default_rng(5)
    n = int(DUR * FS)
    t = np.arange(n) / FS
    chips = CP0 + t * E1_CHIP_RATE * (1.0 + DOP / E1_HZ)
    per = np.floor(chips / 4092.0).astype(np.int64)
    half = np.floor(2.0 * chips).astype(np.int64) % 8184
    sym = rng.choice([-1.0, 1.0], size=per[-1] + 1)
    cs = cs25_signs()
    a = np.sqrt(2 * 10 ** 4.5 / FS)          # 45 dB-Hz against unit-variance I and Q noise
    s = a / np.sqrt(2) * (boc11(e1b_code(PRN))[half] * sym[per] - boc11(e1c_code(PRN))[half] * cs[(per + OFF) % 25])
    x = s * np.exp(2j * np.pi * (DOP * t + 0.3)) + rng.standard_normal(n) + 1j * rng.standard_normal(n)
    return x.astype(np.complex64), chips, sym


def test_refine_pilot_finds_cs25_phase_and_doppler(signal):
    x, _, _ = signal
    dop, off = refine_pilot(x, FS, 0.0, PRN, CP0, DOP + 40.0)
    assert off == OFF and abs(dop - DOP) < 2.0


def _track(x, chunks):
    ch = GalTrack(PRN, FS, 0.0, 0, CP0, DOP + 0.5, OFF, TRK)
    out, start = [], 0
    for k in range(chunks):
        end = len(x) if k == chunks - 1 else (k + 1) * len(x) // chunks
        blk = x[start:min(end + 30000, len(x))]          # the chunk plus an overlap, as the pipeline reads
        out.append(ch.process(blk, start))
        start = end
    return np.concatenate(out)


def test_records_follow_the_signal(signal):
    x, chips, sym = signal
    r = _track(x, 1)
    assert r.dtype == EPOCH_DTYPE and len(r) == int(DUR / 4e-3) - 1
    assert np.all(np.diff(r["code_period"]) == 1) and r["code_period"][0] == 1
    assert np.all(r["integration_ms"] == 4)
    late = r[r["state"] == STATE_BIT_SYNC]
    assert len(late) > 100 and np.all(late["pll_lock"] == 1)
    assert abs(np.mean(late["doppler_hz"]) - DOP) < 0.3 and np.max(np.abs(late["doppler_hz"] - DOP)) < 5.0
    # the C/N0 of the whole E1 signal (E1-B + E1-C: 45 dB-Hz), not the pilot's half
    assert abs(np.median(late["cn0_dbhz"]) - 45.0) < 1.0
    # replica code phase against the true one at each epoch's first sample (chips of the 4-ms code)
    true = chips[late["sample_index"]]
    rep = late["code_period"] * 4092.0 + late["code_phase_chips"]
    assert np.max(np.abs(rep - true)) < 0.03
    # E1-B prompts carry the symbols, with one polarity against the pilot-locked carrier
    agree = np.sign(late["prompt1_i"]) * sym[late["code_period"]]
    assert abs(np.mean(agree)) == 1.0


@pytest.mark.parametrize("cn0", [38.0, 33.0])
def test_cn0_is_the_total_e1_signal(cn0):
    """The reported C/N0 is the total of E1-B and E1-C (the simulator's and the ICD's convention) within 1 dB,
    at the weak end too; the pilot with a phase-jittered carrier does not bias it (moments estimator)."""
    rng = np.random.default_rng(int(cn0))
    n = int(1.6 * FS)
    t = np.arange(n) / FS
    chips = CP0 + t * E1_CHIP_RATE * (1.0 + DOP / E1_HZ)
    per = np.floor(chips / 4092.0).astype(np.int64)
    half = np.floor(2.0 * chips).astype(np.int64) % 8184
    sym = rng.choice([-1.0, 1.0], size=per[-1] + 1)
    a = np.sqrt(2 * 10 ** (cn0 / 10) / FS)
    s = a / np.sqrt(2) * (boc11(e1b_code(PRN))[half] * sym[per]
                          - boc11(e1c_code(PRN))[half] * cs25_signs()[(per + OFF) % 25])
    x = (s * np.exp(2j * np.pi * (DOP * t + 0.3)) + rng.standard_normal(n) + 1j * rng.standard_normal(n))
    r = GalTrack(PRN, FS, 0.0, 0, CP0, DOP + 0.5, OFF, TRK).process(x.astype(np.complex64), 0)
    late = r[(r["state"] == STATE_BIT_SYNC) & (r["pll_lock"] == 1)]
    assert len(late) > 200
    assert abs(np.median(late["cn0_dbhz"]) - cn0) < 1.0


def test_chunked_equals_one_block_and_the_standalone_channel(signal):
    x, _, _ = signal
    one = _track(x, 1)
    np.testing.assert_array_equal(one, _track(x, 3))
    iq = np.empty(2 * len(x), np.float32)
    iq[0::2], iq[1::2] = x.real, x.imag
    ep = GalChannel(PRN, FS, 0.0, 0, CP0, DOP + 0.5, OFF, pll_bw_hz=PLL_BW_HZ, dll_bw_hz=DLL_BW_HZ,
                    dll_spacing=DLL_SPACING).run(iq, 10 ** 6)
    np.testing.assert_array_equal(ep.sample, one["sample_index"])
    np.testing.assert_array_equal(ep.prompt_c.real.astype(np.float32), one["prompt_i"])
    np.testing.assert_array_equal(ep.prompt_b.real.astype(np.float32), one["prompt1_i"])


def test_channel_declares_loss_when_the_signal_goes(signal):
    x, _, _ = signal
    y = x.copy()
    y[int(0.4 * FS):] = (np.random.default_rng(9).standard_normal(len(y) - int(0.4 * FS)) * (1 + 1j)) \
        .astype(np.complex64)
    ch = GalTrack(PRN, FS, 0.0, 0, CP0, DOP + 0.5, OFF, TRK)
    r = ch.process(y, 0)
    assert ch.lost and r["state"][-1] == 3
    assert r["time_s"][-1] < 0.4 + 0.2 + 0.15            # lost_ms after the signal went, plus the detector lag
    assert len(ch.process(y, 0)) == 0


def _clean_signal(dop, dur):
    """A noise-free E1 signal (E1-B with seeded symbols, E1-C with CS25) at Doppler dop: (samples, true chips)."""
    rng = np.random.default_rng(6)
    t = np.arange(int(dur * FS)) / FS
    chips = CP0 + t * E1_CHIP_RATE * (1.0 + dop / E1_HZ)
    per = np.floor(chips / 4092.0).astype(np.int64)
    half = np.floor(2.0 * chips).astype(np.int64) % 8184
    sym = rng.choice([-1.0, 1.0], size=per[-1] + 1)
    s = boc11(e1b_code(PRN))[half] * sym[per] - boc11(e1c_code(PRN))[half] * cs25_signs()[(per + OFF) % 25]
    return (s * np.exp(2j * np.pi * (dop * t + 0.3))).astype(np.complex64), chips


@pytest.mark.parametrize("dop", [-3110.0, 2071.0, 3500.0])
def test_code_has_no_bias_of_its_own(dop):
    """The carrier-aided DLL settles on the true code phase at any Doppler: mean error over the last 0.75 s of a
    noise-free signal within 0.1 m, with the pipeline's 8-Hz DLL and a 2-Hz one.  (Regression: a float32 CS25
    sign made the code rate float32 -- rounded to 1/16 chip/s --, which the first-order DLL followed with a lag
    of its own per Doppler: 0.25-0.52 m at 8 Hz, 1.4-3.1 m at 2 Hz at these Dopplers.)"""
    x, chips = _clean_signal(dop, 1.5)
    m_per_chip = 299792458.0 / E1_CHIP_RATE
    r = GalTrack(PRN, FS, 0.0, 0, CP0, dop + 0.5, OFF, TRK).process(x, 0)
    iq = np.empty(2 * len(x), np.float32)
    iq[0::2], iq[1::2] = x.real, x.imag
    ep = GalChannel(PRN, FS, 0.0, 0, CP0, dop + 0.5, OFF, dll_bw_hz=2.0).run(iq, 10 ** 6)
    for sample, period, phase in ((r["sample_index"], r["code_period"], r["code_phase_chips"]),
                                  (ep.sample, ep.period, ep.code_phase)):
        late = sample >= 0.75 * FS
        err = period[late] * 4092.0 + phase[late] - chips[sample[late]]
        assert len(err) > 150
        assert abs(np.mean(err)) * m_per_chip < 0.1
        assert np.max(np.abs(err)) * m_per_chip < 0.6
