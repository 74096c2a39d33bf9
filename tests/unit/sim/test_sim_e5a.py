"""Galileo E1 + E5a recordings on one clock (receiver.sim.multiband, e5a.enabled) against their truth, the ICD's
E5a-Q / CS100 signal and the BGD(E1,E5a) that the E1 file's I/NAV carries."""
import math

import h5py
import numpy as np
import pytest
import yaml

from receiver.gnss.signals import C_LIGHT
from receiver.gnss.signals_gal_e5a import GAL_E5A
from receiver.sim.multiband import GAMMA_E1E5A, e5a_clock_offset_s
from receiver.sim.simulate import _Simulator, simulate
from receiver.sim.scenario import load_scenario

PRN = 2                 # BGD(E1,E5a) 3.5 ns in data/gal_nominal_constellation.yaml
ALPHA = [1.1176e-08, 7.4506e-09, -5.9605e-08, -5.9605e-08]
BETA = [90112.0, 16384.0, -196610.0, -65536.0]


def _scenario(**extra):
    sc = {"signal": "gal_e1", "time": {"gps_week": 2300, "tow_s": 345619.5, "duration_s": 0.25, "seed": 3},
          "constellation": {"prns": [PRN, 3, 11]}, "receiver": {"lat_deg": 46.5, "lon_deg": 6.6, "height_m": 400.0},
          "clock": {"bias_s": 1.0e-4, "freq_error_ppm": 0.8, "noise": "none"},
          "atmosphere": {"ionosphere": "klobuchar", "klobuchar_alpha": ALPHA, "klobuchar_beta": BETA,
                         "iono_scale": 1.5},
          "frontend": {"format": "complex64", "noise": False, "sample_rate_hz": 4.0e6},
          "output": {"truth_rate_hz": 1000.0},
          "e5a": {"enabled": True, "sample_rate_hz": 10.5e6, "format": "complex64", "if_hz": 1.0e5}}
    for k, v in extra.items():
        sc.setdefault(k, {}).update(v)
    return sc


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("e1e5a")
    return simulate(_scenario(), str(d / "x.bin"), progress=False)


def test_files_and_fragment(pair):
    frag = yaml.safe_load(open(pair["yaml"]))
    assert frag["signals"] == ["gal_e1", "gal_e5a"]
    assert frag["input"]["signal_files"]["gal_e5a"] == {"path": "x_e5a.bin", "format": "complex64",
                                                        "sample_rate_hz": 10.5e6, "if_hz": 1.0e5}
    assert np.fromfile(pair["e5a_if"], np.complex64).size == round(0.25 * 10.5e6)


def test_ionosphere_and_group_delay_of_the_broadcast_bgd(pair):
    """E5a ionosphere gamma x the E1 one (1.5 x the Klobuchar model); the E5a pseudorange longer than E1's by
    that and by c (gamma - 1) BGD(E1,E5a) of the satellite's I/NAV ephemeris; geometry, receiver clock the same."""
    bgd = {p: e.bgd_e1e5a for p, e in _Simulator(load_scenario(_scenario())).ephs.items()}
    assert bgd[PRN] == pytest.approx(3.5e-9, abs=2.4e-10)        # (the 2^-32 s LSB)
    with h5py.File(pair["truth"]) as t1, h5py.File(pair["e5a_truth"]) as t5:
        assert t5.attrs["signals"] == "gal_e5a"
        assert np.array_equal(t1["receiver/clock_bias_m"][:], t5["receiver/clock_bias_m"][:])
        for p in (PRN, 3, 11):
            a, b = t1[f"satellites/E{p:02d}"], t5[f"satellites/E{p:02d}"]
            i1, i5 = a["iono_delay_m"][:], b["iono_delay_m"][:]
            assert np.all(i1 > 1.0) and np.allclose(i5, GAMMA_E1E5A * i1, rtol=1e-9)
            assert np.allclose(b["sat_clock_s"][:] - a["sat_clock_s"][:], e5a_clock_offset_s(bgd[p]), atol=1e-15)
            dpr = b["pseudorange_m"][:] - a["pseudorange_m"][:]
            assert np.allclose(dpr, i5 - i1 + C_LIGHT * (GAMMA_E1E5A - 1.0) * bgd[p], atol=2e-3)
            assert np.allclose(b["range_m"][:], a["range_m"][:])


def test_e5a_samples_carry_e5a_q_under_cs100(pair):
    """Correlate the E5a file with the E5a-Q replica of the truth: full amplitude in every 1-ms period and the
    sign of CS100_PRN at the satellite's millisecond (modulo 100) -- the pilot wiped, one sign throughout."""
    x = np.fromfile(pair["e5a_if"], np.complex64)
    with h5py.File(pair["e5a_truth"]) as f:
        g = f[f"satellites/E{PRN:02d}"]
        fs, if_hz, sigma = f.attrs["sample_rate_hz"], f.attrs["if_hz"], f.attrs["noise_sigma"]
        ts, cp, ph = g["time_s"][:], g["code_phase_chips"][:], g["carrier_phase_cycles"][:]
        pr, cn0 = g["pseudorange_m"][:], g["cn0_dbhz"][0]
        tow0 = f.attrs["start_gps_tow_s"]
    t = np.arange(x.size) / fs
    step = 10230.0 + (np.diff(cp) + 5115.0) % 10230.0 - 5115.0
    chips = np.interp(t, ts, cp[0] + np.concatenate(([0.0], np.cumsum(step))))
    rep = GAL_E5A.code(PRN)[np.floor(chips).astype(np.int64) % 10230] * \
        np.exp(2j * np.pi * (if_hz * t + np.interp(t, ts, ph)))
    edges = np.searchsorted(chips, 10230.0 * np.arange(math.ceil(chips[0] / 10230), int(chips[-1] // 10230) + 1))
    c = np.concatenate(([0], np.cumsum(x * np.conj(rep))))
    p, w = c[edges[1:]] - c[edges[:-1]], np.diff(edges)
    amp = math.sqrt(2.0 * sigma ** 2 * 10 ** (cn0 / 10) / fs)
    assert p.size >= 240 and np.allclose(np.abs(p) / w, amp, rtol=6e-2)
    t_mid = t[(edges[1:] + edges[:-1]) // 2]
    ms = np.floor((tow0 + t_mid - np.interp(t_mid, ts, pr) / C_LIGHT) * 1e3).astype(np.int64)
    s = np.sign(p.real) * GAL_E5A.secondary(PRN)[ms % 100]
    assert np.all(s == s[0])
    # E5a-I a quarter cycle ahead at the same power, CS20 under 20-ms symbols
    rep_i = GAL_E5A.data_code(PRN)[np.floor(chips).astype(np.int64) % 10230] * \
        np.exp(2j * np.pi * (if_hz * t + np.interp(t, ts, ph) + 0.25))
    c = np.concatenate(([0], np.cumsum(x * np.conj(rep_i))))
    pi = c[edges[1:]] - c[edges[:-1]]
    assert np.allclose(np.abs(pi) / w, amp, rtol=6e-2)
    sym = np.sign(pi.real) * GAL_E5A.data_secondary(PRN)[ms % 20]
    for k in np.unique(ms // 20):
        assert np.all(sym[ms // 20 == k] == sym[ms // 20 == k][0])
