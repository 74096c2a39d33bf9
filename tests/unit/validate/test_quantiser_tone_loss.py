"""What a strong CW tone costs in the validation suite's 8-bit AGC'd quantiser (receiver/validate/postprocess.py;
docs/field_robustness.md): the AGC sets the step for the total power, the noise falls to a fraction of a
step and the tone's quantisation error adds to it.  A weak spread-spectrum signal's SNR after an ideal
subtraction of the tone loses ~1 dB at +35 dB and ~2.5 dB at +40 dB (10 log10(1 + (step^2 / 12) / sigma^2))
-- a loss in the recording that no receiver processing gets back."""
import math

import numpy as np
import pytest

from receiver.sim.impairments import _STEP_SIGMA
from receiver.validate.postprocess import _quantize

FS = 2.6e6


def _snr(jnr_db, seed=1, dur=0.1):
    rng = np.random.default_rng(seed)
    n = int(dur * FS)
    k = np.arange(n)
    chips = rng.choice([-1.0, 1.0], size=n // 2 + 2)
    sig = 0.05 * chips[(k * 1.023e6 / FS).astype(int)] * np.exp(2j * np.pi * 1234.5 * k / FS)
    sigma = 1 / math.sqrt(2)
    x = sig + sigma * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    ph = np.exp(2j * np.pi * 120e3 * k / FS)
    if jnr_db is not None:
        x = x + math.sqrt(10 ** (jnr_db / 10)) * ph * np.exp(0.3j)
    q = _quantize(x, "int16_iq", 8, False, sigma)          # 8-bit levels (int16 container: no offset)
    y = q[0::2].astype(float) + 1j * q[1::2].astype(float)
    y = y - (np.vdot(ph, y) / n) * ph                      # the tone subtracted ideally
    g = np.vdot(sig, y) / np.vdot(sig, sig)
    return abs(g) ** 2 / np.mean(np.abs(y - g * sig) ** 2)


@pytest.mark.parametrize("jnr_db, lo, hi", [(30.0, 0.2, 0.8), (35.0, 0.7, 1.4), (40.0, 2.0, 3.0)])
def test_quantiser_tone_loss_matches_the_model(jnr_db, lo, hi):
    loss = 10 * math.log10(_snr(None) / _snr(jnr_db))
    step_over_sigma = _STEP_SIGMA[8] * math.sqrt(0.5 * (1 + 10 ** (jnr_db / 10))) / (1 / math.sqrt(2))
    model = 10 * math.log10(1 + step_over_sigma ** 2 / 12)
    assert lo < loss < hi and abs(loss - model) < 0.5, (loss, model)
