"""Vector loops over channels of any system: QZSS on L1 C/A, BeiDou B1I alone, GPS + BeiDou in one filter.

Short simulated recordings, assisted mode (the simulator's ephemerides as RINEX: scalar fixes from ~1.3 s),
vector handover at 3.5 s; errors against the simulator's truth.
  * QZSS: a GPS + QZSS L1 C/A recording (QZSS orbits are IGSO/GEO, 120-140 ms away: the assisted first fix
    searches a second travel time for them); the QZSS channels join the vector loop and share GPS's clock,
    as in the navigation solution.
  * BeiDou B1I (GEO D2 and IGSO/MEO D1 + NH channels) in the vector loop: its own chip rate, code and
    carrier, transmit time in BDT.
  * GPS (3 satellites) + BeiDou from two files recorded at the same instant (input.signal_files), the B1I
    front end 30 ns late: one filter with an inter-system bias (9 m); GPS alone could not fix at all.
"""
import logging
import os

import h5py
import numpy as np
import pytest

from receiver.schema import load_receiver_config
from receiver.gnss.signals import C_LIGHT
from receiver.pipeline import run

from repo_paths import ROOT as REPO
FS = 5e6
START = 3.5


def _simulate(d, name, text):
    from receiver.batch.tasks import write_nav_for_scenario
    from receiver.sim.simulate import simulate
    sc = d / f"{name}.yaml"
    sc.write_text(text)
    (d / "sim").mkdir(exist_ok=True)
    simulate(str(sc), str(d / "sim" / f"{name}.bin"), progress=False)
    write_nav_for_scenario(str(sc), str(d / f"{name}.nav"))
    return d / "sim" / f"{name}.bin", d / f"{name}.nav", d / "sim" / f"{name}.truth.h5"


BIAS_S = 2.5e-4
ISB_S = 3.0e-8
COMMON = """time: {gps_week: 2300, tow_s: 345600.0, duration_s: 7.0, seed: 7}
receiver: {trajectory: static, lat_deg: 35.681298, lon_deg: 139.766247, height_m: 10.0}
clock: {bias_s: 0.00025, freq_error_ppm: 0.5, noise: tcxo}
cn0: {mode: constant, dbhz: 45.0}
frontend: {sample_rate_hz: 5000000.0, if_hz: 0.0, format: int8_iq}
"""
GPS_PRNS = [7, 11, 24]
BDS_PRNS = [1, 3, 6, 9, 20, 24, 25]          # GEO (D2) C01 C03, IGSO C06 C09, MEO C20 C24 C25
BDS_SEARCHED = [1, 6, 9, 20, 25]             # the combined run: C03 and C24 opened from the vector prediction


class _Messages(logging.Handler):
    """The vector handover's log lines (receiver.tracking.vector's logger, on when a run is not quiet)."""

    def __init__(self):
        super().__init__(logging.INFO)
        self.lines = []

    def emit(self, record):
        self.lines.append(record.getMessage())

    def __enter__(self):
        lg = logging.getLogger("receiver.tracking.vector")
        self._level = lg.level
        lg.setLevel(logging.INFO)
        lg.addHandler(self)
        return self.lines

    def __exit__(self, *exc):
        lg = logging.getLogger("receiver.tracking.vector")
        lg.removeHandler(self)
        lg.setLevel(self._level)


def _run(d, name, sets):
    out = d / f"{name}.h5"
    cfg = load_receiver_config(REPO / "configs/gps_bds_nav.yaml", [
        ("input.sample_rate_hz", FS), ("input.if_hz", 0.0), ("input.start_gps_week", 2300),
        ("input.start_gps_tow_s", 345600.0), ("output.path", str(out)), ("vector.enabled", True),
        ("vector.start_s", START), ("vector.integration_ms", 5), *sets])
    cwd = os.getcwd()
    try:
        os.chdir(d)
        with _Messages() as messages:
            summary = run(cfg, quiet=False, log=lambda *a: None)
    finally:
        os.chdir(cwd)
    return out, summary, messages


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    d = tmp_path_factory.mktemp("vgnss")
    gps = _simulate(d, "l1", COMMON + f"constellation: {{source: embedded, prns: {GPS_PRNS}}}\n")
    # the B1I front end 30 ns later than the L1 one (an inter-system bias of 8.99 m in the combined run)
    late = COMMON.replace(f"bias_s: {BIAS_S}", f"bias_s: {BIAS_S + ISB_S}")
    bds = _simulate(d, "b1", "signal: bds_b1i\n" + late + f"constellation: {{source: bds_nominal, prns: {BDS_PRNS}}}\n")
    return d, gps, bds


@pytest.fixture(scope="module")
def bds_run(recordings):
    d, _, (b1, nav, truth) = recordings
    out, summary, messages = _run(d, "bds", [("signals", []), ("signal", "bds_b1i"), ("input.path", str(b1)),
                                             ("navigation.ephemeris", str(nav)), ("acquisition.prns", BDS_PRNS)])
    return out, truth, summary, messages


@pytest.fixture(scope="module")
def mixed_run(recordings):
    d, (l1, _, _), (b1, _, truth) = recordings
    from receiver.gnss.rinex import read_rinex_nav, write_rinex_nav
    # a mixed RINEX 3 navigation file (GPS + BeiDou records), as RTKLIB or an IGS BRDM file would give
    g, iono = read_rinex_nav(str(d / "l1.nav"))
    b, _ = read_rinex_nav(str(d / "b1.nav"), systems=("C",))
    write_rinex_nav(str(d / "mixed.nav"), [e for lst in (*g.values(), *b.values()) for e in lst], iono)
    out, summary, messages = _run(d, "mixed", [
        ("input.path", str(l1)), ("navigation.ephemeris", str(d / "mixed.nav")),
        ("input.signal_files", {"bds_b1i": {"path": str(b1), "if_hz": 0.0}}),
        ("acquisition.prns", GPS_PRNS), ("acquisition.prns_by_signal", {"bds_b1i": BDS_SEARCHED})])
    return out, truth, summary, messages


def _errors(out, truth):
    with h5py.File(out, "r") as f, h5py.File(truth, "r") as t:
        g = f["navigation"]
        ts, mode = g["time_s"][:], g["mode"][:]
        tt, te = t["receiver"]["time_s"][:], t["receiver"]["ecef"][:]
        ref = np.stack([np.interp(ts, tt, te[:, a]) for a in range(3)], axis=1)
        err = np.linalg.norm(g["ecef"][:] - ref, axis=1)
        return ts, mode, err, g["n_sats"][:], g["velocity_ecef"][:]


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def _locked_to_the_end(out, names, cn0=45.0):
    """Every named channel tracked in vector lock over the last second, C/N0 read near the simulated one."""
    with h5py.File(out, "r") as f:
        for name in names:
            c = f["channels"][name]
            late = c["time_s"][:] > c["time_s"][-1] - 1.0
            assert c["pll_lock"][:][late].all(), name
            assert abs(float(np.mean(c["cn0_dbhz"][:][late])) - cn0) < 3.0, name


def test_beidou_channels_in_the_vector_loop(bds_run):
    out, truth, summary, messages = bds_run
    assert summary.tracked == BDS_PRNS
    hand = [m for m in messages if "vector: handover" in m]
    assert len(hand) == 1 and all(f"C{p:02d}" in hand[0] for p in BDS_PRNS)      # every channel, GEO too
    ts, mode, err, nsat, vel = _errors(out, truth)
    vec, sca = mode == 1, mode == 0
    assert vec.sum() >= 30 and np.all(mode[ts > START + 0.2] == 1) and np.all(nsat[vec] == len(BDS_PRNS))
    # measured: vector 1.08 m (max 2.3 m); the scalar fixes before the handover 3.9 m, a scalar-only run over
    # the same span 1.76 m (its carrier smoothing still converging)
    assert _rms(err[vec]) < 1.5 and _rms(err[vec]) < _rms(err[sca])
    assert _rms(np.linalg.norm(vel[vec], axis=1)) < 3.0                                  # static
    _locked_to_the_end(out, [f"C{p:02d}" for p in BDS_PRNS])
    with h5py.File(out, "r") as f:
        # vector epochs of 5 ms: the D1 channels (NH wiped off) integrate 5 ms inside their 20-ms bits, the D2
        # GEO ones their 2-ms symbols -- no correlation epoch spans a symbol edge (the frequency
        # discriminator compares the halves of one epoch)
        assert np.all(np.isnan(f["vector"]["isb_m"][:]))     # one system: one clock, no bias state
        for name, top in (("C01", 2), ("C03", 2), ("C06", 5), ("C20", 5)):
            c = f["channels"][name]
            im = c["integration_ms"][:][c["time_s"][:] > START + 0.5]
            assert im.max() == top and np.mean(im == top) > 0.95, name


def test_mixed_gps_beidou_vector_run(mixed_run):
    out, truth, summary, messages = mixed_run
    from receiver.gnss.satid import sat_key
    assert summary.tracked == GPS_PRNS + [sat_key("C", p) for p in BDS_PRNS]
    hand = [m for m in messages if "vector: handover" in m]
    assert len(hand) == 1 and "inter-system bias C" in hand[0]
    assert "C03" not in hand[0] and "C24" not in hand[0]
    assert any("opened predicted channel C03" in m for m in messages)
    assert any("opened predicted channel C24" in m for m in messages)
    # the B1I recording is 30 ns late: the scalar fix's inter-system bias, the filter's start, is c 30 ns
    isb0 = float(hand[0].split("inter-system bias C")[1].split("m")[0])
    assert abs(isb0 - C_LIGHT * ISB_S) < 1.5
    assert all(f"G{p:02d}" in hand[0] for p in GPS_PRNS) and all(f"C{p:02d}" in hand[0] for p in BDS_SEARCHED)
    ts, mode, err, nsat, vel = _errors(out, truth)
    vec = mode == 1
    n = len(GPS_PRNS) + len(BDS_PRNS)
    assert vec.sum() >= 30 and np.all(mode[ts > START + 0.2] == 1) and np.all(nsat[vec] >= n - 2)
    assert np.all(nsat[vec][ts[vec] > START + 0.5] == n)     # the predicted channels in lock from 0.3 s on
    # measured: 0.92 m (max 2.1 m), bias +9.13 m at the handover, 8.65 +/- 0.24 m at the end (c 30 ns = 8.99 m);
    # the same filter without the bias state 4.7 m; GPS alone (3 satellites): no fix
    assert _rms(err[vec]) < 1.5 and err[vec].max() < 4.0
    assert _rms(np.linalg.norm(vel[vec], axis=1)) < 3.0
    with h5py.File(out, "r") as f:                            # the bias state in /vector (BeiDou column)
        isb, sig = f["vector"]["isb_m"][:], f["vector"]["sigma_isb_m"][:]
        assert np.all(np.isnan(isb[:, 1])) and abs(float(np.median(isb[-100:, 0])) - C_LIGHT * ISB_S) < 1.0
        assert 0.0 < sig[-1, 0] < sig[0, 0]
    _locked_to_the_end(out, [f"G{p:02d}" for p in GPS_PRNS] + [f"C{p:02d}" for p in BDS_PRNS])
    # the predicted B1I channels: code phase from BDT, D2 symbol / D1 bit and NH edges from the predicted
    # transmit time -- on the signal from the start (a wrong NH alignment would wipe the signal off)
    with h5py.File(out, "r") as f:
        for name, top in (("C03", 2), ("C24", 5)):
            c = f["channels"][name]
            t = c["time_s"][:]
            assert START - 0.1 < t[0] < START + 0.1, name
            assert c["integration_ms"][:][t > t[0] + 0.1].max() == top, name
            assert float(np.mean(c["cn0_dbhz"][:][t > t[0] + 0.5])) > 42.0, name


QZSS = """time: {gps_week: 2300, tow_s: 345597.0, duration_s: 7.0, seed: 4}
constellation: {source: embedded, elevation_mask_deg: 5.0, qzss: true, prns: [1, 7, 11, 15, 24, 193, 194, 195, 199]}
receiver: {trajectory: static, lat_deg: 35.68, lon_deg: 139.77, height_m: 40.0}
clock: {bias_s: 1.0e-4, freq_error_ppm: 0.1, noise: tcxo}
cn0: {mode: constant, dbhz: 42.0}
frontend: {sample_rate_hz: 2600000.0, if_hz: 0.0, format: int8_iq}
"""


def test_qzss_channels_in_the_vector_loop(tmp_path):
    """GPS + QZSS (J01 J02 J03 J07): the assisted first fix resolves the QZSS satellites' transmit times too
    (it failed before: one common travel time cannot fit 70-ms GPS and 125-ms QZSS ranges), the QZSS channels
    join the vector loop on GPS's clock (the navigation solution's grouping: same signal, same time) and the
    vector fixes stay accurate."""
    rec, nav, truth = _simulate(tmp_path, "qz", QZSS)
    prns = [1, 7, 11, 15, 24, 193, 194, 195, 199]
    out = tmp_path / "qz.h5"
    cfg = load_receiver_config(None, [
        ("input.path", str(rec)), ("input.format", "int8_iq"), ("input.sample_rate_hz", 2.6e6), ("input.if_hz", 0.0),
        ("input.start_gps_week", 2300), ("input.start_gps_tow_s", 345597.0), ("navigation.ephemeris", str(nav)),
        ("acquisition.prns", prns), ("vector.enabled", True), ("vector.start_s", START), ("output.path", str(out))])
    with _Messages() as messages:
        summary = run(cfg, quiet=False, log=lambda *a: None)
    assert summary.tracked == prns, summary.text()
    hand = [m for m in messages if "vector: handover" in m]
    assert len(hand) == 1 and all(f"J0{k}" in hand[0] for k in (1, 2, 3, 7))
    assert "inter-system" not in hand[0]                          # QZSS shares GPS's clock
    ts, mode, err, nsat, vel = _errors(out, truth)
    vec = mode == 1
    assert (mode == 0).any() and ts[mode == 0][0] < 2.0          # assisted scalar fixes from ~1.3 s
    assert vec.sum() >= 30 and np.all(nsat[vec] == len(prns))
    assert _rms(err[vec]) < 2.0
    _locked_to_the_end(out, ["J01", "J02", "J03", "J07"], cn0=42.0)


def test_inter_system_bias_update_equals_the_batch_kalman_update():
    """kf_update_isb (sequential scalar updates, the channels' inter-system bias columns) equals the textbook
    batch update with H written out: code rows [-e, 0, 1 (b), 0, 1 (isb of the channel's system)], carrier
    rows [0, -e, 0, 1 (d)]; channels of the reference system have no isb column."""
    from receiver.tracking.vector.kalman import kf_update_isb
    rng = np.random.default_rng(3)
    n = 10                                       # [r, v, b, d, isb_C, isb_E]
    lay = np.array([0, 3, 6, 7, -1], np.int64)
    A = rng.normal(size=(n, n))
    P = A @ A.T + n * np.eye(n)
    x = rng.normal(size=n)
    m = 6
    E = rng.normal(size=(m, 3))
    E /= np.linalg.norm(E, axis=1)[:, None]
    G = np.array([-1, -1, 8, 8, 9, -1], np.int64)
    zc, zf = rng.normal(size=m) * 5.0, rng.normal(size=m)
    Rc, Rf = rng.uniform(1.0, 4.0, m), rng.uniform(0.1, 0.5, m)
    valid = np.array([True, True, True, False, True, True])
    H, z, R = [], [], []
    for j in np.flatnonzero(valid):
        h = np.zeros(n)
        h[0:3], h[6] = -E[j], 1.0
        if G[j] >= 0:
            h[G[j]] = 1.0
        H.append(h), z.append(zc[j]), R.append(Rc[j])
    for j in np.flatnonzero(valid):
        h = np.zeros(n)
        h[3:6], h[7] = -E[j], 1.0
        H.append(h), z.append(zf[j]), R.append(Rf[j])
    H, z, R = np.array(H), np.array(z), np.diag(R)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    x_ref, P_ref = x + K @ z, (np.eye(n) - K @ H) @ P
    xs, Ps = x.copy(), P.copy()
    kf_update_isb(xs, Ps, lay, E, G, zc, zf, valid, Rc, Rf, np.zeros((n, n)), 0.0, np.zeros((m, 8)), 0.0)
    assert np.allclose(xs, x_ref, rtol=0, atol=1e-9)
    assert np.allclose(Ps, 0.5 * (P_ref + P_ref.T), rtol=0, atol=1e-9)
    assert not np.allclose(xs[8:], x[8:])                 # the biases were observed
