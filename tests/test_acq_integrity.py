"""Acquisition integrity (issue 31): a verification dwell that survives a front end's dropped samples, the
search fitted to a short file, and the real recordings of ../shared/data/real: everything in the sky found,
nothing declared that is not."""
import os
from pathlib import Path

import numpy as np
import pytest

from receiver.acquisition import search, verify
from receiver.config import load_receiver_config
from receiver.pipeline import acquire, fit_dwell, open_input

from conftest import SHARED
from synth import make_signal

FS = 4e6
REAL = Path(os.environ.get("GNSSRX_REAL_DATA", SHARED / "real"))


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


# file: (input keys, in the sky, may be found) -- ../shared/data/real/README.md (another analysis of each file)
REAL_FILES = {
    "pocketsdr_L1_20211202_084700_4MHz_IQ.bin": (dict(format="int8_iq", sample_rate_hz=4e6, if_hz=0.0,
                                                      iq_swap=True), {4, 16, 18, 25, 26, 29, 31, 32}, set()),
    "pocketsdr_L1_20211125_004000_12MHz_I.bin": (dict(format="int8_real", sample_rate_hz=12e6, if_hz=3e6),
                                                 {2, 5, 11, 13, 15, 18, 20, 29, 30}, {24, 28}),
    "pocketsdr_L1_20211201_054600_24MHz_I.bin": (dict(format="int8_real", sample_rate_hz=24e6, if_hz=6e6),
                                                 {10, 12, 23, 24, 25, 29, 31, 32}, set()),
    "pysdr_GPS_L1_recording_10ms_4MHz_cf32.iq": (dict(format="complex64", sample_rate_hz=4e6, if_hz=0.0),
                                                 {11, 12, 22, 25, 31, 32}, {2}),
    "peregrine_test_samples.dat": (dict(format="int8_real", sample_rate_hz=16.368e6, if_hz=4.092e6),
                                   {2, 9, 15, 24}, {29}),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(REAL_FILES))
def test_real_recordings_acquisition_integrity(name):
    path = REAL / name
    if not path.is_file():
        pytest.skip(f"real recording {path} absent")
    keys, sky, may = REAL_FILES[name]
    cfg = load_receiver_config(None, [("input.path", str(path))] + [(f"input.{k}", v) for k, v in keys.items()])
    reader = open_input(cfg)
    res = acquire(cfg, reader, reader.first, cfg.acquisition.prns, widen=True, notes=[])
    found = {r.prn for r in res if r.detected}
    assert found - sky - may == set(), "declared but not in the sky"
    assert sky - found == set(), "in the sky but not found"


@pytest.mark.slow
@pytest.mark.parametrize("extra", [117, 1500])
def test_file_ending_just_past_a_chunk_boundary(tmp_path, extra):
    """A file 1.0 s + a few samples long (the tracking chunks are 0.5 s): the channels have been offered
    its end in the second chunk and lag the third chunk's start -- before, 'channel is behind the block
    start' (a traceback) at the end of a 60-s GPS-SDR-SIM recording of 122 880 117 samples."""
    from receiver.pipeline import run
    fs = 2.048e6
    sats = [dict(prn=p, doppler_hz=d, code_phase_chips=c, cn0_dbhz=45.0)
            for p, d, c in ((3, 1200.0, 100.3), (8, -2500.0, 611.0), (19, 400.0, 901.7))]
    x = make_signal(sats, fs, (2048000 + extra) / fs, seed=2, noise_sigma=8.0)
    path = tmp_path / "eof.bin"
    q = np.empty(2 * x.size, np.int8)
    q[0::2] = np.clip(np.rint(x.real), -127, 127)
    q[1::2] = np.clip(np.rint(x.imag), -127, 127)
    q.tofile(path)
    cfg = load_receiver_config(None, [("input.path", str(path)), ("input.format", "int8_iq"),
                                      ("input.sample_rate_hz", fs), ("output.path", str(tmp_path / "eof.h5"))])
    s = run(cfg, quiet=True)
    assert s.tracked == [3, 8, 19]
