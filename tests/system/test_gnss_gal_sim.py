"""The simulator's Galileo E1 signal (scenario signal: gal_e1): E1-B with genuine I/NAV pages and E1-C with
CS25, BOC(1,1), on the orbits of the nominal Galileo constellation.  A truth-aided demodulator (code and carrier
from the truth file, no receiver loops) correlates the recording with the ICD codes: the pilot carries CS25
aligned with the 4-ms periods of GST, and the E1-B symbols decode (page sync, Viterbi, CRC) into the pages the
satellite broadcast at the right times."""
import numpy as np
import pytest

from receiver.errors import UserError
from receiver.gnss import gal_codes as G
from receiver.gnss import gal_inav as I

C = 299792458.0
FS = 4.092e6
TOW0 = 345600.3


def _scenario(tmp_path, duration, extra=()):
    from receiver.sim.simulate import simulate
    sets = [("time.gps_week", 2300), ("time.tow_s", TOW0), ("time.duration_s", duration), ("signal", "gal_e1"),
            ("atmosphere.ionosphere", "none"), ("frontend.sample_rate_hz", FS), ("frontend.if_hz", 0.0),
            ("frontend.format", "int8_iq"), ("cn0.dbhz", 45.0), ("clock.bias_s", 2.5e-4),
            ("clock.freq_error_ppm", 0.5), ("constellation.prns", [11]), *extra]
    out = tmp_path / "gal.bin"
    simulate(None, out, sets, progress=False)
    return out


def _prompts(path, truth, prn):
    """Per 4-ms code period (absolute period index of the GPS week): E1-B and E1-C prompt correlations with the
    truth's code phase and carrier phase wiped off."""
    import h5py
    with h5py.File(truth) as f:
        g = f["satellites"][f"E{prn:02d}"]
        t, car, pr = g["time_s"][:], g["carrier_phase_cycles"][:], g["pseudorange_m"][:]
        code_phase = g["code_phase_chips"][:]
        t_ref = float(f.attrs["start_gps_tow_s"])
    # chips of satellite time since the start of the GPS week: 1.023e6 (receiver clock reading - pseudorange/c)
    chips = 1.023e6 * ((t_ref + t) - pr / C)
    assert np.allclose(np.mod(chips, 4092.0), code_phase, atol=1e-4)
    raw = np.fromfile(path, np.int8)
    n_all = raw.size // 2
    rb, rc = G.boc11(G.e1b_code(prn)), G.boc11(G.e1c_code(prn))
    sums = {}
    step = int(FS)
    for s0 in range(0, n_all, step):
        n = np.arange(s0, min(s0 + step, n_all))
        x = raw[2 * n[0]:2 * (n[-1] + 1)].astype(np.float32)
        y = (x[0::2] + 1j * x[1::2]) * np.exp(-2j * np.pi * np.interp(n / FS, t, car))
        ch = np.interp(n / FS, t, chips)
        per = np.floor(ch / 4092.0).astype(np.int64)
        half = np.floor(2.0 * ch).astype(np.int64) % 8184
        for name, rep in (("B", rb), ("C", rc)):
            v = y * rep[half]
            u, inv = np.unique(per, return_inverse=True)
            acc = np.bincount(inv, v.real) + 1j * np.bincount(inv, v.imag)
            cnt = np.bincount(inv)
            for k, a, c in zip(u, acc, cnt):
                d = sums.setdefault((name, int(k)), [0j, 0])
                d[0] += a
                d[1] += c
    full = FS * 4e-3 - 2                                            # a whole period (the ends are partial)
    ks = sorted(k for (nm, k), (_, c) in sums.items() if nm == "B" and c >= full)
    return np.array(ks), np.array([sums[("B", k)][0] for k in ks]), np.array([sums[("C", k)][0] for k in ks])


@pytest.mark.slow
def test_simulated_galileo_signal_carries_cs25_and_inav(tmp_path):
    out = _scenario(tmp_path, 8.0)
    per, pb, pc = _prompts(out, tmp_path / "gal.truth.h5", 11)
    assert len(per) > 1900
    # both components in phase with the carrier (real prompts), equal power; E1-C transmitted as -e_C (ICD
    # Eq. 11) with CS25 on its 4-ms periods, aligned with GST (period k carries CS25 chip k mod 25)
    assert np.median(np.abs(pb.imag) / np.abs(pb.real)) < 0.2
    assert np.median(np.abs(pc.real)) == pytest.approx(np.median(np.abs(pb.real)), rel=0.05)
    assert np.all(np.sign(pc.real) == -G.cs25_signs()[per % 25])
    # the E1-B symbols decode into the broadcast pages, each at its GST second
    dec = I.InavDecoder(11)
    events = dec.feed(pb.real, 0)
    assert dec.synced and dec.crc_failures == 0 and dec.pages_ok >= 3
    assert events, "word 6 (T0 = 5) carries the TOW"
    for ev in events:
        t_page = (per[0] + ev.bit_index) * 4e-3                  # GPS (= GST) time of the page's first symbol
        assert ev.tow_s == pytest.approx(t_page, abs=1e-9)
        assert ev.subframe_id == I.subframe_word(round(t_page))


def test_gal_e1_scenario_needs_no_klobuchar(tmp_path):
    with pytest.raises(UserError, match="ionosphere must be none"):
        _scenario(tmp_path, 0.01, [("atmosphere.ionosphere", "klobuchar")])
