"""Acquisition integrity (issue 31): a verification dwell that survives a front end's dropped samples and
the search fitted to a short file."""
import numpy as np

from receiver.acquisition import search, verify
from receiver.acquisition.stage import acquire, fit_dwell
from receiver.schema import load_receiver_config
from receiver.pipeline import open_input

from synth import make_signal

FS = 4e6


def test_fit_dwell():
    assert fit_dwell(4, 10, 200.0) == (4, 10, True)          # room for both: unchanged
    assert fit_dwell(4, 10, 50.0) == (4, 6, True)            # fewer sums first
    assert fit_dwell(4, 10, 10.0) == (4, 1, True)
    assert fit_dwell(4, 10, 6.0) == (3, 1, True)             # then a shorter block
    assert fit_dwell(4, 10, 3.0) == (1, 1, True)
    assert fit_dwell(4, 10, 1.5) == (1, 1, False)            # no room for the dwell: the search alone
    assert fit_dwell(4, 10, 0.5) == (0, 0, False)
    assert fit_dwell(4, 10, 30.0, verify=False) == (4, 7, False)


def test_verification_survives_dropped_samples():
    """A front end drops 3434 samples (a USB overrun, as in the 24 MS/s PocketSDR file) between the search
    block and the dwell: every code phase moves, the Doppler stays.  The dwell still passes (the whole code
    period of the three Doppler rows, at the Pfa of that many cells); a PRN that is absent still fails."""
    sat = dict(prn=23, doppler_hz=-3291.0, code_phase_chips=234.8, cn0_dbhz=40.0)
    x = make_signal([sat], FS, 0.1, seed=5)
    dwell = int(0.04 * FS)
    drop = 3434
    y = np.concatenate([x[:dwell], x[dwell + drop:]])
    r = search(y[:dwell], 0, FS, 0.0, [23, 7], 4, 10)
    assert r[0].detected and not r[1].detected
    assert verify(y[dwell:2 * dwell], dwell, FS, 0.0, r[0], 4, 10)          # phase moved by 3434 samples
    assert verify(x[dwell:2 * dwell], dwell, FS, 0.0, r[0], 4, 10)          # no drop: the window test
    fake = type(r[0])(**{**r[0].__dict__, "prn": 7})
    assert not verify(y[dwell:2 * dwell], dwell, FS, 0.0, fake, 4, 10)


def test_short_file_searched_with_a_fitted_dwell(tmp_path):
    """A 10-ms file (shorter than the default 4 ms x 10): the search and its dwell fit 4 ms x 1 each (before:
    'input too short'); the satellites are found, the absent PRNs are not."""
    sats = [dict(prn=11, doppler_hz=2264.0, code_phase_chips=100.0, cn0_dbhz=47.0),
            dict(prn=31, doppler_hz=4992.0, code_phase_chips=600.0, cn0_dbhz=47.0)]
    x = make_signal(sats, FS, 0.010, seed=9, noise_sigma=8.0)
    path = tmp_path / "short.bin"
    q = np.empty(2 * x.size, np.int8)
    q[0::2] = np.clip(np.rint(x.real), -127, 127)
    q[1::2] = np.clip(np.rint(x.imag), -127, 127)
    q.tofile(path)
    cfg = load_receiver_config(None, [("input.path", str(path)), ("input.format", "int8_iq"),
                                      ("input.sample_rate_hz", FS), ("input.conditioning.tone_detection", False)])
    reader = open_input(cfg)
    notes = []
    res = acquire(cfg, reader, reader.first, cfg.acquisition.prns, widen=True, notes=notes)
    assert sorted(r.prn for r in res if r.detected) == [11, 31]
    assert any("4 ms x 1 with a verification dwell" in n for n in notes)
