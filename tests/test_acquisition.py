import numpy as np
import pytest

from receiver.acquisition import search

from synth import make_signal

FS = 2.6e6


def test_detects_known_doppler_and_code_phase():
    sats = [dict(prn=5, doppler_hz=2345.0, code_phase_chips=300.25, cn0_dbhz=40.0),
            dict(prn=17, doppler_hz=-6120.0, code_phase_chips=812.6, cn0_dbhz=35.0)]
    x = make_signal(sats, FS, 0.1, seed=4)
    res = {r.prn: r for r in search(x, 0, FS, 0.0, [5, 17, 9, 30])}
    for s in sats:
        r = res[s["prn"]]
        assert r.detected, r
        assert abs(r.doppler_hz - s["doppler_hz"]) < 15.0
        d = (r.code_phase_chips - s["code_phase_chips"] + 511.5) % 1023 - 511.5
        assert abs(d) < 0.5
    assert not res[9].detected and not res[30].detected
    assert res[5].cn0_dbhz_est == pytest.approx(40, abs=3)


def test_real_if_input():
    sats = [dict(prn=11, doppler_hz=-1500.0, code_phase_chips=77.0, cn0_dbhz=42.0)]
    fs = 4e6
    x = make_signal(sats, fs, 0.06, seed=2, if_hz=1.0e6, real=True).astype(np.complex64)
    r = search(x, 0, fs, 1.0e6, [11, 12])
    assert r[0].detected and abs(r[0].doppler_hz + 1500) < 15
    assert not r[1].detected


def test_false_alarm_rate_on_noise():
    """pfa=1e-2 per PRN search grid: over 32 noise-only searches expect ~0.3 detections."""
    x = make_signal([], FS, 0.05, seed=11)
    res = search(x, 0, FS, 0.0, range(1, 33), pfa=1e-2)
    assert sum(r.detected for r in res) <= 2
    assert max(r.metric for r in res) < 1.3
