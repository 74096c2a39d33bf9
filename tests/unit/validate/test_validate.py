"""The outside-simulator validation suite's own parts: scenarios, GPS-SDR-SIM driver, post-processing,
pass checks (receiver/validate).  Receiver runs are in tests/test_validate_cases.py.

GPS-SDR-SIM is found or built by receiver.validate.gpssdrsim (skip without it / a C compiler / ../shared).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from receiver.validate import postprocess as pp
from receiver.validate import scenarios
from receiver.validate.matrix import check, load_matrix, seeded

FS = 2.6e6


def _speed_acc(rows):
    v = np.linalg.norm(np.diff(rows, axis=0), axis=1) * 10.0
    a = np.linalg.norm(np.diff(rows, 2, axis=0), axis=1) * 100.0
    return v, a


def test_dynamics_speeds_and_accelerations():
    st = scenarios.trajectory_rows({"dynamics": "static", "duration_s": 5})
    assert st.shape == (51, 3) and np.ptp(st, axis=0).max() == 0.0
    v, a = _speed_acc(scenarios.trajectory_rows({"dynamics": "walk", "duration_s": 30}))
    assert abs(v.max() - 1.4) < 0.01 and abs(v.min() - 1.4) < 0.01
    v, a = _speed_acc(scenarios.trajectory_rows({"dynamics": "highg", "duration_s": 10}))
    assert np.allclose(v, 50.0, atol=0.05) and np.allclose(a, 50.0 ** 2 / 64.0, rtol=0.01)   # 4 g
    rows = scenarios.trajectory_rows({"dynamics": "circle", "duration_s": 20, "place": "sydney"})
    centre = rows.mean(axis=0)            # ~1 turn (8 m/s on r = 20 m: 15.7 s per turn) -> near the centre
    r = np.linalg.norm(rows - centre, axis=1)
    assert 15.0 < np.median(r) < 25.0
    v, _ = _speed_acc(scenarios.trajectory_rows({"dynamics": "drive", "duration_s": 40}))
    assert v.min() < 0.01 and abs(v.max() - 15.0) < 0.05        # stops and the cruise speed
    v, _ = _speed_acc(scenarios.trajectory_rows({"dynamics": "figure8", "duration_s": 10}))
    assert abs(v.max() - 50.0) < 0.1


def test_place_height_and_start_time():
    from receiver.gnss.geodesy import ecef2lla
    rows = scenarios.trajectory_rows({"dynamics": "static", "place": "boulder", "duration_s": 1})
    lat, lon, h = ecef2lla(rows[0])
    assert abs(lat - 40.015) < 1e-6 and abs(lon + 105.2705) < 1e-6 and abs(h - 1655.0) < 1e-3
    # 2022-01-01 is a Saturday: 01:59:44 GPS is TOW 525584 (the reference recording's header)
    assert scenarios.start_tow("01:59:44") == 525584.0


def test_seeds_rotate_place_and_time():
    rows = load_matrix()
    assert len(rows) >= 40
    for row in rows:
        combos = {(seeded(row, k)[0]["place"], seeded(row, k)[0]["start"]) for k in range(row["seeds"])}
        assert len(combos) == row["seeds"] >= 3
        noise = {seeded(row, k)[1]["seed"] for k in range(row["seeds"])}
        assert len(noise) == row["seeds"]


def test_check_bounds():
    exp = {"ttff_s": 10, "availability": 0.95, "rms_3d_m": 5.0, "max_recovery_s": 10.0}
    good = {"ttff_s": 2.0, "availability": 0.99, "rms_3d_m": 1.0, "recovery_s": [], "max_recovery_s": math.nan}
    assert check(good, exp) == []
    assert check({**good, "availability": 0.5}, exp) == ["availability"]
    assert check({**good, "rms_3d_m": 12.8}, exp) == ["rms_3d_m"]
    assert check({**good, "recovery_s": [math.nan], "max_recovery_s": math.inf}, exp) == ["max_recovery_s"]
    assert check({**good, "ttff_s": math.nan}, exp) == ["no fix"]


def _tone_file(path, n, f_hz, amp=250.0, fs=FS):
    k = np.arange(n)
    x = amp * np.exp(2j * np.pi * f_hz * k / fs)
    raw = np.empty(2 * n, np.int16)
    raw[0::2], raw[1::2] = np.rint(x.real), np.rint(x.imag)
    raw.tofile(path)


def _read(path, fmt):
    if fmt == "int16_iq":
        r = np.fromfile(path, np.int16).astype(float)
        return r[0::2] + 1j * r[1::2]
    if fmt == "int16_real":
        return np.fromfile(path, np.int16).astype(float)
    if fmt == "uint8_iq":
        r = np.fromfile(path, np.uint8).astype(float) - 127.5
        return r[0::2] + 1j * r[1::2]
    r = np.fromfile(path, np.int8).astype(float)
    return r if fmt.endswith("real") else r[0::2] + 1j * r[1::2]


@pytest.mark.parametrize("fmt,cn0", [("int16_iq", 45.0), ("int16_iq", 33.0), ("int16_real", 40.0)])
def test_noise_sets_the_cn0(tmp_path, fmt, cn0):
    """A tone of a satellite's power (complex amplitude 250) through the chain: its measured C/N0 is the
    set one (complex: P fs / (2 sigma^2); real IF at 2x the rate: P fs / (4 sigma_r^2))."""
    src = tmp_path / "tone.bin"
    _tone_file(src, 260_000, 1000.0)
    out = tmp_path / "out.bin"
    info = pp.process(src, out, FS, {"format": fmt, "cn0_dbhz": cn0, "seed": 3})
    y = _read(out, fmt)
    real = fmt.endswith("real")
    fs = info["sample_rate_hz"]
    f = info["if_hz"] + 1000.0
    k = np.arange(y.size)
    a = np.mean(y * np.exp(-2j * np.pi * f * k / fs)) * (2.0 if real else 1.0)
    resid = y - (np.real(a * np.exp(2j * np.pi * f * k / fs)) if real else a * np.exp(2j * np.pi * f * k / fs))
    var = np.mean(np.abs(resid) ** 2)                      # 2 sigma^2 (complex) or sigma_r^2 (real)
    meas = abs(a) ** 2 * fs / ((4.0 if real else 1.0) * var)
    assert abs(10 * np.log10(meas) - cn0) < 0.2


def test_oscillator_resampling_and_carrier(tmp_path):
    """+2 ppm: the file holds fs (1 + e) samples per true second, the tone (at f true) sits at
    (f - e f_L1) / (1 + e) on the file's axis, with the phase continuous across the 0.1-s blocks."""
    src = tmp_path / "tone.bin"
    n = 780_000
    _tone_file(src, n, 20_000.0)
    out = tmp_path / "out.bin"
    e = 2e-6
    info = pp.process(src, out, FS, {"format": "int16_iq", "cn0_dbhz": 70.0, "osc_ppm": 2.0,
                                     "whole_ms": False})
    y = _read(out, "int16_iq")
    assert info["n_samples"] == y.size == math.floor((n - 1) * (1 + e)) + 1
    m = np.arange(y.size)
    f_file = (20_000.0 - e * pp.F_L1) / (1 + e)
    z = (y * np.exp(-2j * np.pi * f_file * m / FS))[:26_000 * 29].reshape(29, -1).mean(axis=1)
    ph = np.unwrap(np.angle(z))                             # 10-ms means: a wrong rate or a block-edge
    assert np.ptp(ph) < 0.02                                # slip would turn or jump the phase
    assert np.ptp(np.abs(z)) < 0.01 * np.mean(np.abs(z))


def test_whole_ms(tmp_path):
    src = tmp_path / "tone.bin"
    _tone_file(src, 260_000, 0.0)
    info = pp.process(src, tmp_path / "o.bin", FS, {"osc_ppm": 0.7})
    assert info["n_samples"] % 2600 == 0


def test_outage_and_interference(tmp_path):
    """A total outage removes the signal (not the noise); a late CW appears at its start with its power
    over the noise; a pulsed one is on its duty cycle only.  (Per-block AGC: compare ratios.)"""
    src = tmp_path / "tone.bin"
    _tone_file(src, 780_000, 5000.0)                       # 0.3 s
    out = tmp_path / "o.bin"
    pp.process(src, out, FS, {"format": "int16_iq", "cn0_dbhz": 70.0, "seed": 1,
                              "outages": [{"start_s": 0.05, "end_s": 0.1}],
                              "interference": [{"kind": "cw", "freq_hz": 300e3, "power_db": 20,
                                                "start_s": 0.2}]})
    y = _read(out, "int16_iq")
    t = np.arange(y.size) / FS

    def snr(f, a, b):
        sel = (t >= a) & (t < b)
        lo = np.exp(-2j * np.pi * f * t[sel])
        amp = np.mean(y[sel] * lo)
        return abs(amp) ** 2 / np.mean(np.abs(y[sel] - amp / lo) ** 2)

    s0 = snr(5000.0, 0.0, 0.04)
    assert snr(5000.0, 0.06, 0.09) < 0.01 * s0
    assert abs(snr(5000.0, 0.11, 0.19) / s0 - 1.0) < 0.05
    assert snr(300e3, 0.0, 0.19) < 1e-3
    sel = t >= 0.21
    lo = np.exp(-2j * np.pi * 300e3 * t[sel])
    p_cw = abs(np.mean(y[sel] * lo)) ** 2
    lo_s = np.exp(-2j * np.pi * 5000.0 * t[sel])
    rest = y[sel] - np.mean(y[sel] * lo) / lo - np.mean(y[sel] * lo_s) / lo_s      # the noise alone
    assert abs(10 * np.log10(p_cw / np.mean(np.abs(rest) ** 2)) - 20.0) < 0.3
    out2 = tmp_path / "p.bin"
    pp.process(src, out2, FS, {"format": "int16_iq", "cn0_dbhz": 70.0, "seed": 1,
                               "interference": [{"kind": "pulsed", "freq_hz": 100e3, "power_db": 40,
                                                 "period_s": 1e-3, "duty": 0.1}]})
    y2 = _read(out2, "int16_iq")
    on = np.abs(y2) > 5 * np.median(np.abs(y2))
    assert abs(on.mean() - 0.1) < 0.01


@pytest.mark.parametrize("fmt,bits,levels", [("int8_iq", 2, {-3, -1, 1, 3}), ("int8_iq", 1, {-1, 1}),
                                             ("uint8_iq", None, None), ("int8_real", 3, set(range(-7, 8, 2)))])
def test_quantiser_levels(tmp_path, fmt, bits, levels):
    src = tmp_path / "tone.bin"
    _tone_file(src, 26_000, 1000.0)
    out = tmp_path / "o.bin"
    pp.process(src, out, FS / (2 if fmt.endswith("real") else 1), {"format": fmt, "bits": bits, "cn0_dbhz": 45})
    y = _read(out, fmt)
    comps = np.concatenate([y.real, y.imag]) if np.iscomplexobj(y) else y
    if levels is None:                                     # uint8: mid-rise +/-0.5 .. +/-127.5, centred
        assert np.all(np.mod(comps, 1.0) == 0.5) and abs(comps.mean()) < 1.0 and comps.std() > 20
    else:
        assert set(np.unique(comps).astype(int)) <= levels
        assert len(np.unique(comps)) == len(levels)


def test_gpssdrsim_power_and_length(tmp_path):
    """GPS-SDR-SIM with -p 128: (rows - 1) x 0.1 s of samples, total power = SAT_POWER x (satellites)."""
    from receiver.validate import gpssdrsim
    try:
        gpssdrsim.simulator(tmp_path)
    except gpssdrsim.SimulatorUnavailable as e:
        pytest.skip(str(e))
    if not gpssdrsim.NAV_FILE.is_file():
        pytest.skip("../shared/data/brdc0010.22n absent")
    rows = scenarios.trajectory_rows({"dynamics": "static", "duration_s": 1.0})
    deep = tmp_path / ("d" * 90)            # GPS-SDR-SIM keeps file names in 100-character buffers
    path = gpssdrsim.generate(rows, "2022/01/01,02:00:00", 2.048e6, deep)
    raw = np.fromfile(path, np.int16).astype(float)
    assert raw.size == 2 * 10 * 204_800
    nsat = np.mean(raw ** 2) * 2 / gpssdrsim.SAT_POWER
    assert abs(nsat - round(nsat)) < 0.05 * nsat and 6 <= round(nsat) <= 16
    again = gpssdrsim.generate(rows, "2022/01/01,02:00:00", 2.048e6, deep)
    assert again == path                                   # cached by hash


def test_table_and_generated_section(tmp_path):
    """The table has one line per (row, variant) with what the seeds measured; the doc's generated
    section is replaced, not appended, on a second write."""
    from receiver.validate.matrix import table, write_doc
    rows = [r for r in load_matrix() if r["name"] in ("static_2600", "fig8_outage8")]
    ok = {"ttff_s": 1.3, "availability": 1.0, "rms_3d_m": 0.8, "max_err_m": 2.0, "max_err_meas_m": 2.0,
          "recovery_s": [], "max_recovery_s": math.nan, "cn0_dbhz": 44.1, "error": None, "failed": []}
    never = {**ok, "recovery_s": [math.nan], "max_recovery_s": math.inf, "failed": ["max_recovery_s"]}
    res = {("static_2600", k, "scalar"): ok for k in range(3)}
    res.update({("fig8_outage8", k, "scalar"): never for k in range(3)})
    text = table(rows, res)
    lines = text.splitlines()
    assert len(lines) == 2 + 3                       # header, rule, fig8 scalar / vector, static
    assert "not run" in lines[3]                     # fig8 vector: no results
    fig8, static = lines[2], lines[4]                # the matrix's order
    assert "| static_2600 |" in static and static.rstrip().endswith("| 3/3 |")
    assert "| fig8_outage8 |" in fig8 and "never" in fig8 and fig8.rstrip().endswith("| 0/3 |")
    doc = tmp_path / "v.md"
    doc.write_text("# title\n\ntext\n")
    write_doc(text, doc)
    write_doc(text, doc)
    body = doc.read_text()
    assert body.startswith("# title") and body.count("| static_2600 |") == 1


def test_dropout_writes_zeros(tmp_path):
    """An outage with dropout: true: the front end delivers zeros (no noise) in the window, and only there."""
    src = tmp_path / "tone.bin"
    _tone_file(src, 520_000, 5000.0)
    out = tmp_path / "d.bin"
    pp.process(src, out, FS, {"format": "int8_iq", "seed": 1,
                              "outages": [{"start_s": 0.05, "end_s": 0.1, "dropout": True}]})
    x = np.fromfile(out, np.int8).reshape(-1, 2)
    t = np.arange(x.shape[0]) / FS
    dead = (t >= 0.05) & (t < 0.1)
    assert np.all(x[dead] == 0)
    assert np.mean(np.all(x[~dead] == 0, axis=1)) < 0.01 and x[~dead].std() > 10


def test_simulator_needs_a_compiler(tmp_path, monkeypatch):
    """No prebuilt binary, no $GNSSRX_GPSSDRSIM and no C compiler on PATH: SimulatorUnavailable says so."""
    from receiver.validate import gpssdrsim
    monkeypatch.delenv("GNSSRX_GPSSDRSIM", raising=False)
    if not gpssdrsim.BUILD_SCRIPT.is_file():
        pytest.skip("../shared/tools absent")
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(gpssdrsim.SimulatorUnavailable, match="no C compiler"):
        gpssdrsim.simulator(tmp_path / "cache")


@pytest.mark.slow
def test_simulator_is_built_into_the_cache(tmp_path, monkeypatch):
    """Without a prebuilt binary the shared build script compiles GPS-SDR-SIM into <cache>/sim-bin."""
    import shutil
    from receiver.validate import gpssdrsim
    monkeypatch.delenv("GNSSRX_GPSSDRSIM", raising=False)
    if not gpssdrsim.BUILD_SCRIPT.is_file():
        pytest.skip("../shared/tools absent")
    if not (shutil.which("gcc") or shutil.which("cc")):
        pytest.skip("no C compiler")
    exe = gpssdrsim.simulator(tmp_path / "cache")
    assert exe == tmp_path / "cache" / "sim-bin" / "gps-sdr-sim" and exe.is_file()


def test_validate_set_is_checked_before_any_row_runs():
    """``gnssrx validate --set`` with a key the receiver does not know stops at once with the receiver's own
    suggestion (not one error per row after the recordings were made)."""
    from click.testing import CliRunner

    from receiver.errors import UserError
    from receiver.validate.cli import validate
    from receiver.validate.gpssdrsim import NAV_FILE
    if not NAV_FILE.is_file():
        pytest.skip(f"{NAV_FILE} absent (../shared or $GNSSRX_SHARED)")
    res = CliRunner().invoke(validate, ["--set", "navigation.lookahed_s=10", "--only", "static_2600", "--dry-run"])
    assert isinstance(res.exception, UserError), res.output
    assert "navigation.lookahead_s" in str(res.exception)
