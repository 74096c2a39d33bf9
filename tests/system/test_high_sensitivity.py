"""High sensitivity (issue 17): the high-sensitivity acquisition pass and weak-signal tracking."""
import numpy as np
import pytest

from receiver.acquisition import search
from receiver.acquisition.high_sensitivity import doppler_window, search_hs
from receiver.schema import load_receiver_config
from receiver.runfile.record import STATE_BIT_SYNC
from receiver.tracking.scalar import Channel

from synth import make_signal

FS = 2.6e6


@pytest.fixture(scope="module")
def weak_sat():
    """0.8 s of one satellite at 28 dB-Hz with data bits (the HS pass: 400 ms search + 400 ms verify)."""
    bits = np.random.default_rng(3).choice([-1, 1], size=60)
    sat = dict(prn=17, doppler_hz=2911.3, code_phase_chips=412.6, cn0_dbhz=28.0, bits=bits, bit_start_ms=11)
    return sat, make_signal([sat], FS, 0.8, seed=21)


def test_hs_pass_finds_what_the_fast_search_misses(weak_sat):
    sat, x = weak_sat
    fast = search(x[:int(0.04 * FS)], 0, FS, 0.0, [17], 4, 10, 10000.0, threshold=1.25)[0]
    assert not fast.detected                              # 28 dB-Hz: below the fast search (~33 dB-Hz)
    n = int(0.2 * FS)
    r = search_hs(x[:n], 0, FS, 0.0, [17], 10, 20, doppler_center_hz=2500.0, doppler_max_hz=1000.0,
                  verify_samples=x[n:2 * n])[0]
    assert r.detected and r.verified == 1
    dc = (r.code_phase_chips - sat["code_phase_chips"] + 511.5) % 1023 - 511.5
    assert abs(dc) < 0.5
    assert r.doppler_hz == pytest.approx(sat["doppler_hz"], abs=6.0)     # fine Doppler: a tracking start
    assert r.cn0_dbhz_est == pytest.approx(28.0, abs=4.0)


def test_hs_pass_noise_only_and_wrong_prn(weak_sat):
    _sat, x = weak_sat
    n = int(0.2 * FS)
    res = search_hs(x[:n], 0, FS, 0.0, [3, 5], 10, 20, doppler_center_hz=2500.0, doppler_max_hz=1000.0,
                    verify_samples=x[n:2 * n])
    assert not any(r.detected for r in res)


def test_doppler_window_from_satellites_found():
    # two satellites found at -1857 and -2249 Hz; a satellite's own Doppler is within +/-5 kHz: the common
    # offset is in [-2249 - 5000 + ..]: the others lie in [max - 10 k, min + 10 k]
    c, half = doppler_window([-1857.0, -2249.0], 0.0, 10000.0, 5000.0)
    assert c - half == pytest.approx(-10000.0) and c + half == pytest.approx(-2249.0 + 10000.0)
    c, half = doppler_window([4000.0, -3000.0], 0.0, 10000.0, 5000.0)
    assert (c - half, c + half) == pytest.approx((-6000.0, 7000.0))
    assert doppler_window([], 100.0, 10000.0, 5000.0) == (100.0, 10000.0)


def test_weak_channel_bit_sync_20ms_and_lock():
    """27 dB-Hz, opened weak (as from the HS pass): the 1-ms PLL does not lock and the sign-change histogram
    cannot sync (1-ms bit errors ~ 14 %); the energy bit sync (complex 20-ms sums) does,
    the channel integrates 20 ms after it, keeps lock and its narrower loops, and stays tracking."""
    bits = np.random.default_rng(4).choice([-1, 1], size=300)
    dop = -1210.0
    sat = dict(prn=5, doppler_hz=dop, code_phase_chips=77.7, cn0_dbhz=27.0, bits=bits, bit_start_ms=13)
    x = make_signal([sat], FS, 3.5, seed=8)
    cfg = load_receiver_config(None, [])
    ch = Channel(5, dop + 3.0, 77.6, 0, cfg.tracking, FS, 0.0, weak=True)     # as the HS pass opens it
    recs = []
    chunk = int(0.5 * FS)
    for start in range(0, len(x), chunk):
        s = ch.next_sample
        recs.append(ch.process(x[s:start + chunk + int(0.03 * FS)], s))
    r = np.concatenate(recs)
    assert not ch.lost
    assert ch.bit_offset == (13 - 1) % 20             # channel period 0 = signal period 1
    sync = r[r["state"] == STATE_BIT_SYNC]
    assert len(sync) and sync["time_s"][0] < 2.0
    late = r[r["time_s"] > 2.5]
    assert np.all(late["integration_ms"] == 20)
    assert late["pll_lock"].mean() > 0.9
    assert np.mean(late["doppler_hz"]) == pytest.approx(dop, abs=1.0)
    assert np.median(late["cn0_dbhz"]) == pytest.approx(27.0, abs=1.5)     # the weak channel's estimator


def test_strong_channel_unchanged_by_weak_mode():
    """A 45 dB-Hz channel is never weak: the records with and without tracking.weak are identical."""
    bits = np.random.default_rng(1).choice([-1, 1], size=200)
    sat = dict(prn=3, doppler_hz=-800.0, code_phase_chips=10.0, cn0_dbhz=45.0, bits=bits, bit_start_ms=3)
    x = make_signal([sat], FS, 2.0, seed=6)
    out = []
    for weak in (True, False):
        cfg = load_receiver_config(None, [("tracking.weak.enabled", weak)])
        ch = Channel(3, -790.0, 10.2, 0, cfg.tracking, FS, 0.0)
        out.append(ch.process(x, 0))
    assert np.array_equal(out[0], out[1])


def test_carrier_variant_auto_picks_the_loop_by_the_acquisition_estimate():
    """tracking.carrier.variant auto: a channel opened weak runs auto_weak (adaptive_kf), any other auto_strong
    (pll) -- record for record the same as configuring that variant outright."""
    from receiver.errors import UserError
    bits = np.random.default_rng(4).choice([-1, 1], size=120)
    sat = dict(prn=9, doppler_hz=1200.0, code_phase_chips=300.4, cn0_dbhz=30.0, bits=bits, bit_start_ms=7)
    x = make_signal([sat], FS, 1.5, seed=9)
    auto = load_receiver_config(None, [("tracking.carrier.variant", "auto")])
    for weak, name in ((True, "adaptive_kf"), (False, "pll")):
        fixed = load_receiver_config(None, [("tracking.carrier.variant", name)])
        a = Channel(9, 1195.0, 300.0, 0, auto.tracking, FS, 0.0, weak=weak)
        b = Channel(9, 1195.0, 300.0, 0, fixed.tracking, FS, 0.0, weak=weak)
        assert a.loop.name == name
        assert np.array_equal(a.process(x, 0), b.process(x, 0)), name
    with pytest.raises(UserError):
        load_receiver_config(None, [("tracking.carrier.variant", "auto"), ("tracking.carrier.auto_weak", "x")])
