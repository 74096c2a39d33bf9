"""IF samples of the simulator against its truth file, with replicas built independently (plain numpy)."""
import math

import h5py
import numpy as np
import pytest

from receiver.gnss.atmosphere import klobuchar_delay_s, saastamoinen_m
from receiver.gnss.ephemeris import earth_rotation, sat_state
from receiver.gnss.lnav import EphemerisEvent, IonoUtcEvent, LnavDecoder, SubframeEvent
from receiver.gnss.geodesy import ecef2lla
from receiver.gnss.signals import C_LIGHT
from receiver.sim.constellation import nominal_ephemerides
from receiver.sim.scenario import REPO_ROOT, NOMINAL_CONSTELLATION
from receiver.sim.simulate import simulate

from test_sim_helpers import period_correlations, read_if, replica

PRN = 11          # high in the sky at the schema's default place and time (embedded constellation)


def _sim(tmp, name, sc, overrides=()):
    paths = simulate(sc, str(tmp / f"{name}.bin"), overrides=overrides, progress=False)
    return paths, h5py.File(paths["truth"], "r")


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    sc = {"time": {"duration_s": 0.3, "seed": 4},
          "constellation": {"prns": [PRN]},
          "clock": {"bias_s": 1.0e-4, "freq_error_ppm": 1.5, "noise": "tcxo"},
          "frontend": {"format": "complex64", "noise": False, "if_hz": -200e3},
          # TCXO white FM moves the phase randomly every 1 ms: the replica needs 1 ms truth
          "output": {"truth_rate_hz": 1000.0}}
    paths, f = _sim(tmp_path_factory.mktemp("clean"), "clean", sc)
    yield paths, f
    f.close()


@pytest.mark.slow
def test_noise_free_correlation_peak_at_truth(clean):
    paths, f = clean
    g = f[f"satellites/G{PRN:02d}"]
    fs, if_hz, sigma = f.attrs["sample_rate_hz"], f.attrs["if_hz"], f.attrs["noise_sigma"]
    x = read_if(paths["if"], "complex64")
    amp = math.sqrt(2.0 * sigma ** 2 * 10 ** (g["cn0_dbhz"][0] / 10) / fs)
    rep, cp = replica(g, fs, x.size, if_hz)
    p, w = period_correlations(x, rep, cp)
    assert p.size >= 280
    # full amplitude in every code period, phase 0 or pi (the data bit)
    assert np.allclose(np.abs(p) / w, amp, rtol=2e-3)
    ang = np.angle(p * np.sign(p.real))
    assert np.max(np.abs(ang)) < 0.01
    signs = np.sign(p.real)
    changes = np.nonzero(np.diff(signs))[0] + 1
    assert changes.size >= 1 and np.all(np.diff(changes) % 20 == 0)   # bits last 20 code periods
    # the peak is at the truth code phase and Doppler
    peak = np.median(np.abs(p) / w)
    for off in (-0.25, 0.25):
        r2, _ = replica(g, fs, x.size, if_hz, code_offset=off)
        p2, _ = period_correlations(x, r2, cp)
        assert np.median(np.abs(p2) / w) < 0.9 * peak
    r3, _ = replica(g, fs, x.size, if_hz, doppler_offset=300.0)
    p3, _ = period_correlations(x, r3, cp)
    assert np.median(np.abs(p3) / w) < 0.9 * peak


@pytest.mark.parametrize("fs,if_hz", [(1.2345e6, 0.0), (4.0e6, 1.25e6)])
def test_correlation_at_other_sample_rates(tmp_path, fs, if_hz):
    """Sample rates that are not a whole number of samples per ms (segment offsets x0 != 0)."""
    sc = {"time": {"duration_s": 0.08, "seed": 4}, "constellation": {"prns": [PRN]},
          "frontend": {"format": "complex64", "noise": False, "sample_rate_hz": fs, "if_hz": if_hz}}
    paths, f = _sim(tmp_path, "odd", sc)
    with f:
        g = f[f"satellites/G{PRN:02d}"]
        x = read_if(paths["if"], "complex64")
        assert x.size == round(0.08 * fs)
        amp = math.sqrt(2.0 * f.attrs["noise_sigma"] ** 2 * 10 ** (g["cn0_dbhz"][0] / 10) / fs)
        rep, cp = replica(g, fs, x.size, if_hz)
        p, w = period_correlations(x, rep, cp)
        assert np.allclose(np.abs(p) / w, amp, rtol=2e-3)


def test_doppler_sign_and_oscillator_error(clean):
    """exp(+j 2 pi f_D t) for an approaching satellite; the oscillator error shifts all carriers by
    -eps f_L1 and the truth Doppler includes it."""
    _, f = clean
    g = f[f"satellites/G{PRN:02d}"]
    rr = g["range_rate_mps"][:]
    dop = g["doppler_hz"][:]
    eps = f["receiver/clock_drift_mps"][:] / C_LIGHT
    sat_clk_rate = np.gradient(g["sat_clock_s"][:], g["time_s"][:])
    expected = -(rr / C_LIGHT + eps - sat_clk_rate) * 1575.42e6      # first order
    assert np.max(np.abs(dop - expected)) < 0.5
    assert np.all(np.abs(eps.mean() - 1.5e-6) < 2e-8)
    # carrier phase derivative = Doppler (TCXO noise makes the 10 ms difference differ a little)
    d = np.diff(g["carrier_phase_cycles"][:]) / np.diff(g["time_s"][:])
    assert np.max(np.abs(d - dop[:-1])) < 1e-3


def test_truth_internal_consistency(clean):
    _, f = clean
    g = f[f"satellites/G{PRN:02d}"]
    rx = f["receiver"]
    t0 = f.attrs["start_gps_tow_s"]
    ts = rx["time_s"][:]
    # gps_tow = clock reading - bias
    assert np.allclose(rx["gps_tow"][:], t0 + ts - rx["clock_bias_m"][:] / C_LIGHT, atol=1e-9, rtol=0)
    assert np.allclose(g["gps_tow"][:], rx["gps_tow"][:], atol=1e-12, rtol=0)
    # code phase = 1.023e6 (clock reading - pseudorange / c) mod 1023
    frac = t0 - math.floor(t0 * 1000.0) / 1000.0
    cp = np.mod((frac + ts - g["pseudorange_m"][:] / C_LIGHT) * 1.023e6, 1023.0)
    dcp = (cp - g["code_phase_chips"][:] + 511.5) % 1023.0 - 511.5
    assert np.max(np.abs(dcp)) < 1e-4
    # pseudorange = range + c (b - dt_sv) + I + T
    pr = (g["range_m"][:] + rx["clock_bias_m"][:] - C_LIGHT * g["sat_clock_s"][:] + g["iono_delay_m"][:]
          + g["tropo_delay_m"][:])
    assert np.max(np.abs(pr - g["pseudorange_m"][:])) < 1e-6
    # range rate = d range / d(true time)
    rr = np.gradient(g["range_m"][:], rx["gps_tow"][:])
    assert np.max(np.abs(rr[1:-1] - g["range_rate_mps"][1:-1])) < 1e-3
    # the clock bias integrates the drift (bias in seconds: db/dT = y / (1 + y))
    y = rx["clock_drift_mps"][:] / C_LIGHT
    db = np.diff(rx["clock_bias_m"][:]) / C_LIGHT
    assert np.max(np.abs(db - np.diff(ts) * y[:-1])) < 3e-11          # TCXO noise within 10 ms


def _independent_pseudoranges(f, prn, rows):
    """Pseudoranges recomputed from the broadcast ephemeris with a plain light-time loop."""
    g = f[f"satellites/G{prn:02d}"]
    rx = f["receiver"]
    ephs, iono = nominal_ephemerides(REPO_ROOT / NOMINAL_CONSTELLATION, int(f.attrs["gps_week"]),
                                     float(f.attrs["start_gps_tow_s"]))
    eph = ephs[prn]
    for k in rows:
        pos = rx["ecef"][k]
        lat, lon, h = (float(v) for v in ecef2lla(pos))
        sl, cl = math.sin(math.radians(lat)), math.cos(math.radians(lat))
        so, co = math.sin(math.radians(lon)), math.cos(math.radians(lon))
        t = rx["gps_tow"][k]
        tau, clk = 0.07, 0.0
        for _ in range(6):
            sp, _, clk, _ = sat_state(eph, t - tau + clk)
            d = earth_rotation(sp, tau) - pos
            rho = float(np.linalg.norm(d))
            e, n = -so * d[0] + co * d[1], -sl * co * d[0] - sl * so * d[1] + cl * d[2]
            u = cl * co * d[0] + cl * so * d[1] + sl * d[2]
            el, az = math.atan2(u, math.hypot(e, n)), math.atan2(e, n) % (2 * math.pi)
            i_m = C_LIGHT * float(klobuchar_delay_s(iono, math.radians(lat), math.radians(lon), az, el, t))
            t_m = float(saastamoinen_m(math.radians(lat), h, el))
            tau = (rho + i_m + t_m) / C_LIGHT
        pr = rho + rx["clock_bias_m"][k] - C_LIGHT * float(clk) + i_m + t_m
        yield pr, g["pseudorange_m"][k], math.degrees(el), g["elevation_deg"][k]


@pytest.mark.slow
def test_pseudorange_independent_geometry(clean):
    _, f = clean
    for pr, truth, el, el_truth in _independent_pseudoranges(f, PRN, (0, 130, 290)):
        assert abs(pr - truth) < 2e-3
        assert abs(el - el_truth) < 1e-6


def test_moving_receiver_truth(tmp_path):
    sc = {"time": {"duration_s": 2.0, "seed": 6}, "constellation": {"prns": [PRN]},
          "receiver": {"trajectory": "figure8", "figure8": {"size_m": 30.0, "peak_speed_mps": 20.0}},
          "frontend": {"format": "int8_iq", "sample_rate_hz": 1.0e6}}
    _, f = _sim(tmp_path, "moving", sc)
    with f:
        rx = f["receiver"]
        t = rx["gps_tow"][:]
        v = rx["velocity_ecef"][:]
        assert np.max(np.linalg.norm(v, axis=1)) == pytest.approx(20.0, abs=0.01)
        assert np.max(np.abs(np.gradient(rx["ecef"][:], t, axis=0)[1:-1] - v[1:-1])) < 0.02
        assert np.max(np.abs(np.gradient(v, t, axis=0)[1:-1] - rx["accel_ecef"][1:-1])) < 0.05
        for pr, truth, el, el_truth in _independent_pseudoranges(f, PRN, (0, 57, 133, 199)):
            assert abs(pr - truth) < 2e-3
        g = f[f"satellites/G{PRN:02d}"]
        rr = np.gradient(g["range_m"][:], t)
        assert np.max(np.abs(rr[1:-1] - g["range_rate_mps"][1:-1])) < 0.02
        # the receiver's motion is in the Doppler: Doppler = -range rate / lambda + (clock terms)
        dop = g["doppler_hz"][:]
        rest = dop + g["range_rate_mps"][:] * 1575.42e6 / C_LIGHT
        assert np.std(dop) > 5.0 and np.std(rest) < 0.05


def test_cn0_models_in_truth(tmp_path):
    base = {"time": {"duration_s": 1.0}, "constellation": {"prns": [PRN, 24, 7]},
            "frontend": {"sample_rate_hz": 2.0e5}}
    _, f = _sim(tmp_path, "elev", {**base, "cn0": {"mode": "elevation", "dbhz": 48.0, "horizon_dbhz": 30.0}})
    with f:
        for k in f["satellites"]:
            g = f["satellites"][k]
            el = np.clip(g["elevation_deg"][:], 0, 90)
            assert np.allclose(g["cn0_dbhz"][:], 30.0 + 18.0 * el / 90.0, atol=1e-3)
    sched = {"mode": "schedule", "schedule": [{"prns": [24], "t_s": [0.0, 1.0], "dbhz": [40.0, 30.0]},
                                              {"t_s": [0.5], "dbhz": [37.0]}]}
    _, f = _sim(tmp_path, "sched", {**base, "cn0": sched})
    with f:
        g = f["satellites/G24"]
        assert np.allclose(g["cn0_dbhz"][:], 40.0 - 10.0 * g["time_s"][:])
        assert np.allclose(f[f"satellites/G{PRN:02d}"]["cn0_dbhz"][:], 37.0)


@pytest.mark.slow
@pytest.mark.parametrize("fmt,if_hz", [("int8_iq", 0.0), ("int16_real", 650e3)])
def test_cn0_with_noise(tmp_path, fmt, if_hz):
    prns = [PRN, 24]
    cn0 = {PRN: 35.0, 24: 50.0}
    sc = {"time": {"duration_s": 0.4, "seed": 11}, "constellation": {"prns": prns},
          "cn0": {"per_prn": cn0}, "frontend": {"format": fmt, "if_hz": if_hz}}
    paths, f = _sim(tmp_path, "noisy", sc)
    with f:
        fs, sigma = f.attrs["sample_rate_hz"], f.attrs["noise_sigma"]
        x = read_if(paths["if"], fmt)
        k = 2.0 if fmt.endswith("_iq") else 4.0                # A^2 = k sigma^2 C/N0 / fs
        var = sigma ** 2 + sum(k * sigma ** 2 * 10 ** (c / 10) / fs / 2 for c in cn0.values())
        assert abs(np.std(x.real) / math.sqrt(var) - 1.0) < 0.01
        for prn in prns:
            g = f[f"satellites/G{prn:02d}"]
            assert g["cn0_dbhz"][0] == cn0[prn]
            rep, cp = replica(g, fs, x.size, if_hz)
            p, w = period_correlations(x, rep, cp)
            n = np.mean(w)
            if fmt.endswith("_iq"):            # complex: E|P|^2 = A^2 N^2 + 2 sigma^2 N, C/N0 = A^2 fs / 2 sigma^2
                a2 = (np.mean(np.abs(p) ** 2) - 2 * sigma ** 2 * n) / n ** 2
                est = 10 * np.log10(a2 * fs / (2 * sigma ** 2))
            else:                              # real: E|P|^2 = (A/2)^2 N^2 + sigma^2 N, C/N0 = A^2 fs / 4 sigma^2
                a2 = 4 * (np.mean(np.abs(p) ** 2) - sigma ** 2 * n) / n ** 2
                est = 10 * np.log10(a2 * fs / (4 * sigma ** 2))
            assert abs(est - cn0[prn]) < 0.5, (prn, est)


@pytest.mark.slow
def test_nav_bits_decode_to_the_broadcast_ephemeris(tmp_path):
    """Subframes 1-4 decoded from the IF samples: ephemeris and iono/UTC as broadcast, TOW aligned."""
    tow0 = 345600.0 - 0.3                     # a frame starts 0.3 s (+ travel time) after the first sample
    sc = {"time": {"gps_week": 2300, "tow_s": tow0, "duration_s": 24.7, "seed": 1},
          "receiver": {"lat_deg": 46.5, "lon_deg": 6.6, "height_m": 400.0},
          "constellation": {"prns": [12]}, "cn0": {"dbhz": 60.0},
          "frontend": {"format": "int8_iq", "noise": False, "sample_rate_hz": 1.0e6}}
    paths, f = _sim(tmp_path, "nav", sc)
    with f:
        g = f["satellites/G12"]
        assert g["visible"][:].all()
        fs = f.attrs["sample_rate_hz"]
        x = read_if(paths["if"], "int8_iq")
        rep, cp = replica(g, fs, x.size)
        # satellite time of every sample: receiver clock reading - pseudorange / c
        t = np.arange(x.size) / fs
        t_sv = tow0 + t - np.interp(t, g["time_s"][:], g["pseudorange_m"][:]) / C_LIGHT
        bit = np.floor(t_sv / 0.02 + 1e-9).astype(np.int64)
        soft = np.bincount(bit - bit[0], weights=(x * np.conj(rep)).real)
        soft, first = soft[1:-1], int(bit[0]) + 1              # drop the partial first and last bits
    dec = LnavDecoder(prn=12, week_hint=2300)
    events = dec.feed(soft, first)
    subframes = [e for e in events if isinstance(e, SubframeEvent)]
    assert len(subframes) >= 4 and dec.parity_failures == 0
    for e in subframes:        # the subframe whose TOW is tau starts at satellite time tau
        assert e.bit_index * 0.02 == pytest.approx(e.tow_s, abs=1e-6)
    ephs, iono = nominal_ephemerides(REPO_ROOT / NOMINAL_CONSTELLATION, 2300, tow0)
    got = [e.ephemeris for e in events if isinstance(e, EphemerisEvent)]
    assert got and got[0] == ephs[12]
    io = [e.iono_utc for e in events if isinstance(e, IonoUtcEvent)]
    assert io and io[0].alpha == iono.alpha and io[0].beta == iono.beta


def test_scintillation_applied_to_signal(tmp_path):
    sc = {"time": {"duration_s": 1.0, "seed": 9}, "constellation": {"prns": [PRN]},
          "scintillation": {"enabled": True, "s4": 0.6, "sigma_phi_rad": 0.5, "tau0_s": 0.1},
          "frontend": {"format": "complex64", "noise": False, "sample_rate_hz": 1.0e6}}
    paths, f = _sim(tmp_path, "scint", sc)
    with f:
        g = f[f"satellites/G{PRN:02d}"]
        fs, sigma = f.attrs["sample_rate_hz"], f.attrs["noise_sigma"]
        x = read_if(paths["if"], "complex64")
        amp0 = math.sqrt(2.0 * sigma ** 2 * 10 ** (g["cn0_dbhz"][0] / 10) / fs)
        rep, cp = replica(g, fs, x.size)      # carrier_phase_cycles includes the scintillation phase
        p, w = period_correlations(x, rep, cp)
        tp = np.arange(p.size) * 1e-3 + 0.0005
        s_amp = np.interp(tp, g["time_s"][:], g["scint_amplitude"][:])
        assert np.std(g["scint_amplitude"][:]) > 0.1 and np.std(g["scint_phase_rad"][:]) > 0.1
        assert np.max(np.abs(np.abs(p) / w / amp0 - s_amp)) < 0.03
        assert np.max(np.abs(np.angle(p * np.sign(p.real)))) < 0.05


def test_blockage_and_visible_count(tmp_path):
    sc = {"time": {"duration_s": 0.6, "seed": 2}, "constellation": {"prns": [11, 24, 29, 7]},
          "blockage": {"outages": [{"prn": 24, "start_s": 0.1, "end_s": 0.3}],
                       "visible_count": [[0.0, 4], [0.4, 2]]},
          "frontend": {"format": "complex64", "noise": False, "sample_rate_hz": 1.0e6}}
    paths, f = _sim(tmp_path, "block", sc)
    with f:
        ts = f["receiver/time_s"][:]
        vis = {int(k[1:]): f["satellites"][k]["visible"][:] for k in f["satellites"]}
        el = {p: f["satellites"][f"G{p:02d}"]["elevation_deg"][:] for p in vis}
        out24 = (ts >= 0.1) & (ts < 0.3)
        assert not vis[24][out24].any() and vis[24][ts < 0.1].all()
        late = ts >= 0.4
        assert all(int(sum(vis[p][k] for p in vis)) == 2 for k in np.nonzero(late)[0])
        top2 = sorted(el, key=lambda p: -el[p][-1])[:2]
        assert all(vis[p][-1] for p in top2)
        # no signal at all from a blocked satellite: correlate over the outage
        x = read_if(paths["if"], "complex64")
        fs = f.attrs["sample_rate_hz"]
        g = f["satellites/G24"]
        rep, cp = replica(g, fs, x.size)
        p, w = period_correlations(x, rep, cp)
        tp = np.arange(p.size) * 1e-3
        inside = (tp > 0.12) & (tp < 0.28)
        before = tp < 0.08
        # (what remains is the cross-correlation with the other satellites)
        assert np.max(np.abs(p[inside]) / w[inside]) < 0.15 * np.median(np.abs(p[before]) / w[before])


def test_node_interpolation_matches_full_geometry(tmp_path):
    """Geometry at 10 ms nodes + Hermite interpolation == geometry at every 1 ms grid point."""
    sc = {"time": {"duration_s": 0.25, "seed": 3}, "constellation": {"prns": [PRN, 24]},
          "receiver": {"trajectory": "figure8", "figure8": {"size_m": 40.0, "peak_speed_mps": 25.0}},
          "clock": {"noise": "tcxo", "freq_error_ppm": -1.2},
          "frontend": {"format": "complex64", "noise": False, "sample_rate_hz": 1.0e6}}
    a, fa = _sim(tmp_path, "full", sc, ["output.truth_rate_hz=1000"])
    b, fb = _sim(tmp_path, "nodes", sc)
    with fa, fb:
        xa, xb = read_if(a["if"], "complex64"), read_if(b["if"], "complex64")
        assert np.max(np.abs(xa - xb)) < 1e-4 * np.max(np.abs(xa))
        ga, gb = fa[f"satellites/G{PRN:02d}"], fb[f"satellites/G{PRN:02d}"]
        assert np.allclose(ga["pseudorange_m"][::10], gb["pseudorange_m"][:], atol=1e-6, rtol=0)
        assert np.allclose(ga["doppler_hz"][::10], gb["doppler_hz"][:], atol=1e-6, rtol=0)
