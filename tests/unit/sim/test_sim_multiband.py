"""L1 + L5 recordings on one clock (receiver.sim.multiband) against their truth and the IS-GPS-705 signal."""
import math

import h5py
import numpy as np
import pytest
import yaml

from receiver.gnss.l5_codes import NH10, NH20, l5_code
from receiver.sim.multiband import GAMMA_15
from receiver.sim.simulate import simulate

PRN = 11


def _scenario(**extra):
    sc = {"time": {"duration_s": 0.1, "seed": 3}, "constellation": {"prns": [PRN, 24]},
          "clock": {"bias_s": 1.0e-4, "freq_error_ppm": 0.8, "noise": "none"},
          "frontend": {"format": "complex64", "noise": False, "sample_rate_hz": 2.046e6},
          "output": {"truth_rate_hz": 1000.0},
          "l5": {"enabled": True, "sample_rate_hz": 10.23e6, "format": "complex64", "if_hz": 1.0e5}}
    for k, v in extra.items():
        sc.setdefault(k, {}).update(v)
    return sc


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("l1l5")
    paths = simulate(_scenario(atmosphere={"iono_scale": 1.5}), str(d / "x.bin"), progress=False)
    base = simulate(_scenario(l5={"enabled": False}), str(d / "b.bin"), progress=False)
    return paths, base


def test_files_and_fragment(pair):
    paths, _ = pair
    frag = yaml.safe_load(open(paths["yaml"]))
    assert frag["signals"] == ["gps_l1ca", "gps_l5"]
    l5 = frag["input"]["signal_files"]["gps_l5"]
    assert l5 == {"path": "x_l5.bin", "format": "complex64", "sample_rate_hz": 10.23e6, "if_hz": 1.0e5}
    # one clock: the same duration in samples of each rate
    assert np.fromfile(paths["if"], np.complex64).size == round(0.1 * 2.046e6)
    assert np.fromfile(paths["l5_if"], np.complex64).size == round(0.1 * 10.23e6)


def test_truth_ionosphere_and_clock(pair):
    paths, base = pair
    with h5py.File(paths["truth"]) as t1, h5py.File(paths["l5_truth"]) as t5, h5py.File(base["truth"]) as tb:
        assert t5.attrs["signals"] == "gps_l5" and t5.attrs["sample_rate_hz"] == 10.23e6
        assert np.array_equal(t1["receiver/clock_bias_m"][:], t5["receiver/clock_bias_m"][:])
        for key in (f"G{PRN:02d}", "G24"):
            a, b, c = t1[f"satellites/{key}"], t5[f"satellites/{key}"], tb[f"satellites/{key}"]
            i1, i5, ib = a["iono_delay_m"][:], b["iono_delay_m"][:], c["iono_delay_m"][:]
            assert np.all(ib > 1.0) and np.allclose(i1, 1.5 * ib, rtol=1e-9)     # 1.5 x the broadcast model
            assert np.allclose(i5, GAMMA_15 * i1, rtol=1e-9)
            # code delayed, carrier advanced by the band's ionosphere; geometry and clocks the same
            dpr = b["pseudorange_m"][:] - a["pseudorange_m"][:]
            assert np.allclose(dpr, i5 - i1, atol=2e-3)
            assert np.allclose(b["range_m"][:], a["range_m"][:])
            ratio = b["doppler_hz"][:] / a["doppler_hz"][:]
            assert np.allclose(ratio, 1176.45 / 1575.42, rtol=1e-5)


def test_l5_samples_carry_q5_and_i5(pair):
    """Correlate the L5 file with Q5 and I5 replicas built from its truth (1-ms rows): full amplitude in every
    period, the NH20 sign pattern at the satellite's 20-ms epochs on Q5, NH10 under 10-ms symbols on I5."""
    paths, _ = pair
    x = np.fromfile(paths["l5_if"], np.complex64)
    with h5py.File(paths["l5_truth"]) as f:
        g = f[f"satellites/G{PRN:02d}"]
        fs, if_hz, sigma = f.attrs["sample_rate_hz"], f.attrs["if_hz"], f.attrs["noise_sigma"]
        ts, cp, ph = g["time_s"][:], g["code_phase_chips"][:], g["carrier_phase_cycles"][:]
        pr, cn0 = g["pseudorange_m"][:], g["cn0_dbhz"][0]
        tow0 = f.attrs["start_gps_tow_s"]
    t = np.arange(x.size) / fs
    # one code period per 1-ms row, plus the (small) change of the phase within the period
    step = 10230.0 + (np.diff(cp) + 5115.0) % 10230.0 - 5115.0
    chips = np.interp(t, ts, cp[0] + np.concatenate(([0.0], np.cumsum(step))))
    rep = l5_code(PRN, "Q")[np.floor(chips).astype(np.int64) % 10230] * \
        np.exp(2j * np.pi * (if_hz * t + np.interp(t, ts, ph)))
    # windows between code-period starts (chip count multiple of 10230)
    edges = np.searchsorted(chips, 10230.0 * np.arange(math.ceil(chips[0] / 10230),
                                                       int(chips[-1] // 10230) + 1))
    c = np.concatenate(([0], np.cumsum(x * np.conj(rep))))
    p, w = c[edges[1:]] - c[edges[:-1]], np.diff(edges)
    amp = math.sqrt(2.0 * sigma ** 2 * 10 ** (cn0 / 10) / fs)
    # (+ the other satellite: cross-correlation of the code family below 0.05, and noise)
    assert p.size >= 95 and np.allclose(np.abs(p) / w, amp, rtol=6e-2)
    # the satellite-time ms of each window: transmit time = receive time - pseudorange / c
    t_mid = t[(edges[1:] + edges[:-1]) // 2]
    ms = np.floor((tow0 + t_mid - np.interp(t_mid, ts, pr) / 299792458.0) * 1e3).astype(np.int64)
    nh = 1 - 2 * np.array(NH20)[ms % 20]
    s = np.sign(p.real) * nh
    assert np.all(s == s[0])
    # I5, a quarter cycle ahead, the same power: NH10 x a symbol constant over each 10 ms
    rep_i = l5_code(PRN, "I")[np.floor(chips).astype(np.int64) % 10230] * \
        np.exp(2j * np.pi * (if_hz * t + np.interp(t, ts, ph) + 0.25))
    c = np.concatenate(([0], np.cumsum(x * np.conj(rep_i))))
    pi = c[edges[1:]] - c[edges[:-1]]
    assert np.allclose(np.abs(pi) / w, amp, rtol=5e-2)    # (+ the Q5 and PRN 24 cross-correlations)
    sym = np.sign(pi.real) * (1 - 2 * np.array(NH10)[ms % 10])
    for k in np.unique(ms // 10):
        assert np.all(sym[ms // 10 == k] == sym[ms // 10 == k][0])


def test_l1_file_unchanged_by_the_l5_file(pair, tmp_path):
    """The L1 recording of an L1 + L5 scenario is the L1-only recording (iono_scale 1: bit-identical)."""
    _, base = pair
    p = simulate(_scenario(), str(tmp_path / "y.bin"), progress=False)
    assert open(p["if"], "rb").read() == open(base["if"], "rb").read()
