"""E5a-Q pilot tracking in the scalar channel (receiver.tracking.scalar with GAL_E5A): the CS100 secondary code
is synchronised by the sign-change histogram over 100 code periods (as NH20 is on GPS L5 Q5, over 20) and then
wiped: on a synthetic E5a-Q x CS100 signal the channel finds the period where CS100 chip 0 falls, for any start
phase of the secondary code, and the wiped prompt keeps its sign."""
import numpy as np
import pytest

from receiver.gnss.signals_gal_e5a import GAL_E5A
from receiver.schema import load_receiver_config
from receiver.tracking import kernel as K
from receiver.tracking.scalar import Channel

FS = 10.5e6
DOPPLER = 350.0
PRN = 11


def _block(n0, n, k0, cn0_dbhz, rng):
    """Samples n0 .. n0 + n - 1 of E5a-Q x CS100 (chip ``k0`` of CS100 in the code period that starts at sample
    0), Doppler DOPPLER, complex noise of unit variance per component (C/N0 = A^2 fs / 2)."""
    t = (n0 + np.arange(n)) / FS
    chips = t * GAL_E5A.chip_rate * (1.0 + DOPPLER / GAL_E5A.carrier_hz)
    per = np.floor(chips / GAL_E5A.code_len).astype(np.int64)
    code = GAL_E5A.code(PRN)[np.floor(chips).astype(np.int64) % GAL_E5A.code_len]
    sec = GAL_E5A.secondary(PRN)[(k0 + per) % 100]
    amp = np.sqrt(2.0 * 10.0 ** (cn0_dbhz / 10.0) / FS)
    x = amp * code * sec * np.exp(2j * np.pi * (DOPPLER * t + 0.1))
    return (x + rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64)


def _track(k0, seconds=0.75, cn0_dbhz=45.0, seed=0):
    rng = np.random.default_rng(seed)
    trk = load_receiver_config(None).tracking
    ch = Channel(PRN, DOPPLER, 0.0, 0, trk, FS, 0.0, signal=GAL_E5A)
    recs, n_blk = [], int(0.1 * FS)
    while ch.next_sample + n_blk < seconds * FS:
        s0 = ch.next_sample
        recs.append(ch.process(_block(s0, n_blk, k0, cn0_dbhz, rng), s0))
    return ch, np.concatenate(recs)


@pytest.mark.parametrize("k0", [0, 37, 99])
def test_cs100_synchronised_and_wiped(k0):
    ch, r = _track(k0)
    assert not ch.lost and int(ch.st[K.S_MODE]) == K.MODE_BIT_SYNC
    off = ch.bit_offset
    assert 0 <= off < 100
    # the signal's code period of each record (code phase 0 at sample 0) and the CS100 chip it carries
    step = GAL_E5A.chip_rate * (1.0 + DOPPLER / GAL_E5A.carrier_hz) / FS
    per = np.round(r["sample_index"] * step / GAL_E5A.code_len).astype(np.int64)
    chip = (k0 + per) % 100
    synced = r["state"] == K.MODE_BIT_SYNC
    assert synced.sum() > 200
    # CS100 chip 0 is where the channel puts its secondary-code epoch
    assert np.all(chip[synced] == (r["code_period"][synced] - off) % 100)
    # wiped: the prompt keeps one sign (the pilot carries no data) once the loops have settled
    late = synced & (r["time_s"] > r["time_s"][synced][0] + 0.1)
    s = np.sign(r["prompt_i"][late])
    assert abs(s.sum()) == len(s)
