"""The carrier loops' compiled twins (receiver/tracking/loops/compiled.py) against the Python-stepped
loops: the same channel-epoch records (to float rounding) for every variant, on 2.5 s of the reference
recording (hand-over from the built-in pull-in loop at bit sync included)."""
import numpy as np
import pytest

from conftest import TOKYO_REC
from receiver.config import load_receiver_config
from receiver.tracking import kernel as K
from receiver.tracking.carrier import REGISTRY
from receiver.tracking.loops import compiled as LC
from receiver.tracking.scalar import Channel

FS = 2.6e6
SATS = [(23, -1867.2, 476.88), (13, -3515.0, 349.39)]      # strongest and weakest of the recording (44, 34 dB-Hz)
VARIANTS = [v for v in REGISTRY if v != "pll"]


@pytest.fixture(scope="module")
def samples():
    if not TOKYO_REC.exists():
        pytest.skip("../shared/data reference recording absent")
    raw = np.memmap(TOKYO_REC, np.int8, "r")[:int(2 * 2.5 * FS)]
    return (raw[0::2] + 1j * raw[1::2]).astype(np.complex64)


def _track(x, variant, compiled, prn, dop, cp):
    cfg = load_receiver_config(None, [("tracking.carrier.variant", variant)])
    ch = Channel(prn, dop, cp, 0, cfg.tracking, FS, 0.0)
    ch.use_compiled_loop = compiled
    chunk, pad, recs = int(0.5 * FS), int(0.03 * FS), []
    for start in range(0, len(x) - chunk, chunk):
        s = ch.next_sample if start else 0
        recs.append(ch.process(x[s:start + chunk + pad], s))
    return ch, np.concatenate(recs)


def test_every_variant_has_a_compiled_twin():
    assert set(VARIANTS) == set(LC.KINDS)


@pytest.mark.parametrize("variant", VARIANTS)
def test_compiled_loop_equals_the_python_stepped_loop(samples, variant):
    for prn, dop, cp in SATS:
        ch_c, a = _track(samples, variant, True, prn, dop, cp)
        ch_p, b = _track(samples, variant, False, prn, dop, cp)
        assert ch_c._loop_started and ch_p._loop_started          # the variant's loop ran (after bit sync)
        assert ch_c.cfg[K.C_CARRIER_EXTERNAL] == 1.0 and not ch_c.lost          # the loop owns the NCO
        assert len(a) == len(b) > 2000
        assert (a["state"] == b["state"]).all() and (a["sample_index"] == b["sample_index"]).all()
        for name in ("doppler_hz", "carrier_phase_cycles", "code_phase_chips", "code_rate_hz"):
            np.testing.assert_allclose(a[name], b[name], rtol=0, atol=1e-9 * max(1.0, np.abs(b[name]).max()))
        for name in ("prompt_i", "prompt_q", "cn0_dbhz", "pli"):
            np.testing.assert_allclose(a[name], b[name], rtol=1e-5, atol=1e-3)
