"""Galileo E1 tracking channel (receiver/tracking/gal.py) on a simulated gal_e1 recording: the pilot refinement
finds the Doppler and the CS25 phase, and the channel holds the code (BOC(1,1) main peak) and the carrier
against the truth while the E1-B prompts decode into pages."""
import h5py
import numpy as np
import pytest

from receiver.acquisition.galileo import refine_pilot, search
from receiver.gnss.gal_inav import InavDecoder
from receiver.tracking.gal import GalChannel

FS = 4.0e6
C = 299792458.0


@pytest.mark.slow
def test_channel_tracks_code_and_carrier(tmp_path):
    from receiver.sim.simulate import simulate
    out = tmp_path / "gal.bin"
    simulate(None, out, [("time.gps_week", 2300), ("time.tow_s", 345600.3), ("time.duration_s", 6.0),
                         ("signal", "gal_e1"), ("atmosphere.ionosphere", "none"), ("frontend.sample_rate_hz", FS),
                         ("frontend.if_hz", 0.0), ("frontend.format", "int8_iq"), ("cn0.dbhz", 45.0),
                         ("clock.bias_s", 2.5e-4), ("clock.freq_error_ppm", 0.5), ("clock.noise", "tcxo"),
                         ("receiver.lat_deg", 46.5197), ("receiver.lon_deg", 6.6323),
                         ("constellation.prns", [11])], progress=False)
    with h5py.File(tmp_path / "gal.truth.h5") as f:
        g = f["satellites"]["E11"]
        t, pr, dop = g["time_s"][:], g["pseudorange_m"][:], g["doppler_hz"][:]
        t_ref = float(f.attrs["start_gps_tow_s"])
    raw = np.memmap(out, np.int8, "r")
    blk = raw[:2 * int(0.2 * FS)].astype(np.float32)
    x0 = (blk[0::2] + 1j * blk[1::2]).astype(np.complex64)
    (acq,) = search(x0, 0, FS, 0.0, [11], noncoherent=5, doppler_max_hz=2000.0)
    assert acq.detected
    d, off = refine_pilot(x0, FS, 0.0, 11, acq.code_phase_chips, acq.doppler_hz)
    assert abs(d - dop[0]) < 3.0                                     # 62.5-Hz bin -> a few Hz
    ch = GalChannel(11, FS, 0.0, 0, acq.code_phase_chips, d, off)
    ep = ch.run(raw, 1500)
    assert len(ep.sample) >= 1400
    # the truth's code phase at each epoch's first sample (chips of satellite time since the week start)
    ts = ep.sample / FS
    chips_true = 1.023e6 * ((t_ref + ts) - np.interp(ts, t, pr) / C)
    # CS25 offset: period p of the acquisition block carries chip (p + off) mod 25 = absolute period mod 25
    per_abs = np.round((chips_true - ep.code_phase) / 4092.0).astype(np.int64)
    assert np.all((ep.period + off) % 25 == per_abs % 25)
    err = (chips_true - ep.code_phase + 2046.0) % 4092.0 - 2046.0  # chips
    late = slice(250, None)                                          # after the first second
    assert np.max(np.abs(err[late])) < 0.05                          # 15 m; BOC side peaks are 0.5 chip away
    assert np.sqrt(np.mean(err[late] ** 2)) < 0.02
    assert np.max(np.abs(ep.carr_hz[late] - np.interp(ts[late], t, dop))) < 3.0
    assert np.median(np.abs(ep.prompt_c[late].imag) / np.abs(ep.prompt_c[late].real)) < 0.2   # phase lock
    dec = InavDecoder(11)
    dec.feed(ep.prompt_b.real, 0)
    assert dec.pages_ok >= 2 and dec.crc_failures == 0
