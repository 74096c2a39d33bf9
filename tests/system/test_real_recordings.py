"""The real antenna recordings of ../shared/data/real (issue 31): the default acquisition finds every
satellite their README lists as in the sky and declares none that is not (the 'may' ones may be found)."""
import os
from pathlib import Path

import pytest

from receiver.acquisition.stage import acquire
from receiver.schema import load_receiver_config
from receiver.pipeline import open_input

from repo_paths import REAL_DATA

REAL = Path(os.environ.get("GNSSRX_REAL_DATA", REAL_DATA))   # the real recordings' directory


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
