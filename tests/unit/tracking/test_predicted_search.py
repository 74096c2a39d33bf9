"""The ephemeris-aided search of satellites no channel tracks: the prediction from a tracked satellite against
transmit times computed directly, and the search's sensitivity and false alarms on synthetic signals."""
import numpy as np
import pytest

from receiver.acquisition.high_sensitivity import search_predicted
from receiver.gnss.ephemeris import earth_rotation, sat_state, select
from receiver.gnss.rinex import read_rinex_nav
from receiver.gnss.signals import C_LIGHT, GPS_L1CA, sample_code
from receiver.tracking.predicted import predict

from repo_paths import SHARED

NAV = SHARED / "data" / "brdc0010.22n"
RX = np.array([-3959617.48, 3350136.61, 3699531.46])       # Tokyo
VEL = np.array([30.0, -40.0, 5.0])                         # a moving receiver (m/s)


def _clock_at_tx(eph, t_rx, rx):
    """The satellite clock's reading at the transmission of the signal received at t_rx at rx (direct)."""
    tau = 0.07
    for _ in range(6):
        pos, _, clk, _ = sat_state(eph, t_rx - tau)
        tau = float(np.linalg.norm(earth_rotation(np.asarray(pos), tau) - rx)) / C_LIGHT
    return t_rx - tau + float(clk)


@pytest.mark.skipif(not NAV.exists(), reason="needs ../shared/data/brdc0010.22n")
def test_prediction_from_a_reference_satellite_matches_the_transmit_times():
    ephs, _ = read_rinex_nav(NAV)
    t = 525600.0 + 10.0
    ep, eq = select(ephs[32], t), select(ephs[23], t)
    tq, tp = _clock_at_tx(eq, t, RX), _clock_at_tx(ep, t, RX)
    chip, f_c = GPS_L1CA.chip_rate, GPS_L1CA.carrier_hz
    cp_q = (tq % 1e-3) * chip
    # Doppler from the transmit times' rates (received frequency f_c dT / dt_rx) for the moving receiver
    h = 0.5                          # (T is ~5e5 s: float64 resolves 1e-10 s, so the step is not tiny)
    rate = {k: (_clock_at_tx(e, t + h, RX + VEL * h) - _clock_at_tx(e, t - h, RX - VEL * h)) / (2 * h)
            for k, e in (("p", ep), ("q", eq))}
    dop_q = f_c * (rate["q"] - 1.0) + 1234.5             # plus a receiver oscillator offset common to both
    # the receiver's GPS time wrong by 50 us (its clock): it cancels but for the satellites' motion over it
    cp, dop, dt = predict(ep, eq, t + 5e-5, RX, VEL, cp_q, dop_q, GPS_L1CA)
    want_cp = (tp % 1e-3) * chip
    assert abs((cp - want_cp + 511.5) % 1023 - 511.5) < 0.02            # chips (~6 m)
    assert abs(dt - (tp - tq)) < 1e-7
    assert abs(dop - (f_c * (rate["p"] - 1.0) + 1234.5)) < 0.5           # Hz


FS = 2.6e6


def _signal(rng, cn0, dop, cp0, n):
    code = sample_code(GPS_L1CA.code(7), GPS_L1CA.chip_rate * (1 + dop / GPS_L1CA.carrier_hz), FS, n, cp0)
    bits = np.repeat(rng.choice([-1.0, 1.0], size=n // 52000 + 2), 52000)[13000:13000 + n]   # 20-ms bits
    t = np.arange(n) / FS
    noise = (rng.normal(size=n) + 1j * rng.normal(size=n)) / np.sqrt(2)
    return (np.sqrt(10 ** (cn0 / 10) / FS) * code * bits * np.exp(2j * np.pi * (dop * t + 0.3)) + noise
            ).astype(np.complex64)


def test_predicted_search_finds_a_24_dbhz_satellite_and_not_noise():
    """0.5 s of 10-ms blocks at a 3.1-kHz Doppler (the code drifts 1 chip over the search: compensated): a
    24 dB-Hz signal is found within half a chip and 30 Hz of the truth every time; noise alone never."""
    rng = np.random.default_rng(11)
    n = int(0.5 * FS) + 10
    for _ in range(5):
        x = _signal(rng, 24.0, 3100.0, 400.3, n)
        r = search_predicted(x, 0, FS, 0.0, 7, 3100.0 + rng.uniform(-20, 20), 50.0, 400.3 + rng.uniform(-0.3, 0.3),
                             2.0)
        assert r.detected
        assert abs(r.code_phase_chips - 400.3) < 0.5 and abs(r.doppler_hz - 3100.0) < 30.0
    for _ in range(5):
        x = ((rng.normal(size=n) + 1j * rng.normal(size=n)) / np.sqrt(2)).astype(np.complex64)
        assert not search_predicted(x, 0, FS, 0.0, 7, 3100.0, 50.0, 400.3, 2.0).detected


def test_predicted_search_needs_the_code_drift_compensation():
    """Without the per-block code drift (the search told a 0-Hz code Doppler) the same 24 dB-Hz signal at
    6 kHz spreads over ~4 chips in 0.5 s: its statistic drops well below the compensated one."""
    rng = np.random.default_rng(12)
    n = int(0.5 * FS) + 10
    x = _signal(rng, 27.0, 6000.0, 100.0, n)
    good = search_predicted(x, 0, FS, 0.0, 7, 6000.0, 50.0, 100.0, 6.0)
    x0 = x * np.exp(-2j * np.pi * 6000.0 * np.arange(n) / FS).astype(np.complex64)   # carrier removed only
    bad = search_predicted(x0, 0, FS, 0.0, 7, 0.0, 50.0, 100.0, 6.0)
    assert good.detected and good.metric > 1.5 * bad.metric
