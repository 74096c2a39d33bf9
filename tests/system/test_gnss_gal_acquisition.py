"""Galileo E1 acquisition (receiver/acquisition/galileo.py) on a simulated gal_e1 recording: every satellite above
the horizon is found at its true code phase (within 0.07 chip: the BOC(1,1) main peak, not a side peak)
and Doppler (within half a 125-Hz bin), satellites below the horizon or absent are not, and a candidate on a
BOC side peak (+/- 1/2 chip) is moved back to the main peak."""
import h5py
import numpy as np
import pytest

from receiver.acquisition.galileo import resolve_side_peak, search

FS = 4.0e6                 # not a multiple of the chip rate (docs/galileo.md)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("galacq")
    out = d / "gal.bin"
    simulate(None, out, [("time.gps_week", 2300), ("time.tow_s", 345600.3), ("time.duration_s", 0.05),
                         ("signal", "gal_e1"), ("atmosphere.ionosphere", "none"), ("frontend.sample_rate_hz", FS),
                         ("frontend.if_hz", 0.0), ("frontend.format", "int8_iq"), ("cn0.dbhz", 45.0),
                         ("clock.bias_s", 2.5e-4), ("clock.freq_error_ppm", 0.5), ("receiver.lat_deg", 46.5197),
                         ("receiver.lon_deg", 6.6323), ("receiver.height_m", 400.0),
                         ("constellation.prns", [2, 11, 13, 19])], progress=False)
    raw = np.fromfile(out, np.int8).astype(np.float32)
    x = (raw[0::2] + 1j * raw[1::2]).astype(np.complex64)
    with h5py.File(d / "gal.truth.h5") as f:
        truth = {int(k[1:]): (float(g["code_phase_chips"][0]), float(g["doppler_hz"][0]), bool(g["visible"][0]))
                 for k, g in f["satellites"].items()}
    return x, truth


@pytest.mark.slow
def test_acquisition_finds_the_visible_satellites(recording):
    x, truth = recording
    assert not truth[13][2] and truth[2][2] and truth[11][2] and truth[19][2]     # 13 is below the horizon
    res = {r.prn: r for r in search(x, 0, FS, 0.0, [2, 11, 13, 19, 40], noncoherent=5, doppler_max_hz=4000.0)}
    for prn in (2, 11, 19):
        r = res[prn]
        cp, dop, _ = truth[prn]
        assert r.detected, prn
        err = (r.code_phase_chips - cp + 2046.0) % 4092.0 - 2046.0
        assert abs(err) < 0.07, (prn, err)                    # the 1/16-chip refinement
        assert abs(r.doppler_hz - dop) <= 62.5 + 1.0, prn
        assert 40.0 < r.cn0_dbhz_est < 46.0                    # 45 dB-Hz, less the straddle loss
    assert not res[13].detected and not res[40].detected


@pytest.mark.slow
def test_side_peak_is_resolved(recording):
    x, truth = recording
    cp, dop, _ = truth[11]
    for side in (-0.5, 0.5):
        got, moved = resolve_side_peak(x, FS, 0.0, 11, (cp + side) % 4092.0, dop, 5)
        assert moved
        assert abs((got - cp + 2046.0) % 4092.0 - 2046.0) < 0.13
    got, moved = resolve_side_peak(x, FS, 0.0, 11, cp, dop, 5)
    assert not moved and abs(got - cp) < 0.07
