"""Configuration validation and the CLI's error contract: one line, exit code 2, no output file."""
import subprocess
import sys

import numpy as np
import pytest

from receiver.config import build
from receiver.schema import RECEIVER_SCHEMA, load_receiver_config
from receiver.errors import UserError

from synth import make_signal


def test_defaults_and_overrides():
    cfg = load_receiver_config(None, ["tracking.pll_bw_hz=15", "acquisition.prns=[3, 5]"])
    assert cfg.tracking.pll_bw_hz == 15.0 and cfg.acquisition.prns == [3, 5]
    assert cfg.input.format == "int8_iq" and cfg.tracking.dll_bw_hz == 2.0


def test_exponent_floats_without_a_dot(tmp_path):
    """1e-3 / 2e-19 are floats in config files and --set (PyYAML alone reads them as strings)."""
    p = tmp_path / "c.yaml"
    p.write_text("tracking:\n  carrier:\n    clock_h0: 2e-19\n    kf: {cn0_dbhz: 3.5e1}\n")
    cfg = load_receiver_config(p, ["vector.cv.q_velocity=1e-3", "tracking.carrier.clock_h_2=0e0"])
    assert cfg.tracking.carrier.clock_h0 == 2e-19 and cfg.tracking.carrier.kf.cn0_dbhz == 35.0
    assert cfg.vector.cv.q_velocity == 1e-3 and cfg.tracking.carrier.clock_h_2 == 0.0


@pytest.mark.parametrize("raw,match", [
    ({"tracking": {"pll_bw": 10}}, "unknown config key 'tracking.pll_bw'"),
    ({"bogus": 1}, "unknown config key 'bogus'"),
    ({"tracking": {"pll_bw_hz": "fast"}}, "'tracking.pll_bw_hz' must be of type float"),
    ({"input": {"format": "int4"}}, "'input.format' must be one of"),
    ({"tracking": {"pll_order": 4}}, "'tracking.pll_order' must be one of"),
    ({"input": {"sample_rate_hz": -5}}, "'input.sample_rate_hz' must be >="),
    ({"acquisition": {"prns": [1, 240]}}, "'acquisition.prns' must be <= 202"),
    ({"tracking": {"carrier": {"variant": "magic"}}}, "'tracking.carrier.variant' must be one of"),
    ({"tracking": 5}, "config section 'tracking' must be a mapping"),
])
def test_bad_config(raw, match):
    with pytest.raises(UserError, match=match):
        build(RECEIVER_SCHEMA, raw)


def test_default_yaml_is_complete_and_valid():
    import yaml
    from repo_paths import CONFIGS
    raw = yaml.safe_load((CONFIGS / "default.yaml").read_text())
    cfg = build(RECEIVER_SCHEMA, raw)

    def keys(schema, prefix=""):
        for k, v in schema.items():
            if isinstance(v, dict):
                yield from keys(v, prefix + k + ".")
            else:
                yield prefix + k
    for k in keys(RECEIVER_SCHEMA):          # every key is spelled out in the default config
        node = raw
        for part in k.split("."):
            assert part in node, f"configs/default.yaml lacks {k}"
            node = node[part]
        assert cfg.get(k) == build(RECEIVER_SCHEMA).get(k)


def _gnssrx(*args, cwd):
    return subprocess.run([sys.executable, "-m", "receiver.cli", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


@pytest.fixture(scope="module")
def small_recording(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    x = make_signal([dict(prn=4, doppler_hz=900.0, code_phase_chips=20.0, cn0_dbhz=45.0)], 2.6e6, 0.6,
                    noise_sigma=8.0, seed=1)
    raw = np.empty(2 * len(x), np.int8)
    raw[0::2] = np.clip(np.round(x.real), -127, 127)
    raw[1::2] = np.clip(np.round(x.imag), -127, 127)
    p = d / "rec.bin"
    raw.tofile(p)
    cfg = d / "cfg.yaml"
    cfg.write_text(f"input:\n  path: {p}\nacquisition:\n  prns: [4, 7]\n")
    return d, p, cfg


@pytest.mark.slow
@pytest.mark.parametrize("args,message", [
    (["--set", "tracking.pll_bw=3"], "unknown config key 'tracking.pll_bw'"),
    (["--set", "tracking.pll_bw_hz=abc"], "must be of type float"),
    (["--input", "missing.bin"], "input file not found"),
    (["--set", "input.format=int16_iq", "--input", "odd.bin"], "truncated"),
    (["--set", "vector.variant=nonsense"], "'vector.variant' must be one of"),
    (["--set", "vector.enabled=true", "--set", "vector.variant=polynomial", "--set", "vector.motion_model=ca"],
     "vector.motion_model 'ca' applies to fixed_r and adaptive_r only"),
])
def test_cli_errors_are_one_line_exit_2_no_output(small_recording, args, message):
    d, _, cfg = small_recording
    (d / "odd.bin").write_bytes(b"\x00" * 7)
    out = d / "out.h5"
    res = _gnssrx("run", str(cfg), "-o", str(out), *args, cwd=d)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], res.stderr
    assert "Traceback" not in res.stderr
    assert not out.exists() and not (d / "out.h5.partial").exists()


@pytest.mark.slow
def test_cli_missing_config_and_bad_yaml(tmp_path):
    res = _gnssrx("run", "nope.yaml", cwd=tmp_path)
    assert res.returncode == 2 and "config file not found" in res.stderr
    (tmp_path / "bad.yaml").write_text("input: [unclosed\n")
    res = _gnssrx("run", "bad.yaml", cwd=tmp_path)
    assert res.returncode == 2 and "not valid YAML" in res.stderr and len(res.stderr.splitlines()) == 1


@pytest.mark.slow
def test_cli_run_and_acquire(small_recording):
    d, p, cfg = small_recording
    res = _gnssrx("acquire", str(cfg), cwd=d)
    assert res.returncode == 0, res.stderr
    assert "detected: 4" in res.stdout
    out = d / "ok.h5"
    res = _gnssrx("run", str(cfg), "-o", str(out), "--quiet", "--set", "navigation.enabled=false", cwd=d)
    assert res.returncode == 0, res.stderr
    assert "tracked         1 satellites: G04" in res.stdout       # --quiet keeps the summary
    import h5py
    with h5py.File(out) as f:
        assert "tracking" in f.attrs["config"] and f.attrs["gnssrx_version"]
        assert list(f["acquisition/prn"][:]) == [4, 7]
        assert list(f["acquisition/detected"][:]) == [True, False]
        g = f["channels/G04"]
        for name in ("time_s", "cn0_dbhz", "doppler_hz", "carrier_phase_cycles", "code_phase_chips",
                     "prompt_i", "prompt_q", "pll_lock"):
            assert g[name].shape == g["time_s"].shape and len(g[name]) > 400
        assert abs(np.mean(g["doppler_hz"][-100:]) - 900.0) < 2.0
