"""Simulator CLI, scenario loading/validation, output files and the fast quantiser."""
import os

import h5py
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from receiver import __version__
from receiver.schema import load_receiver_config
from receiver.errors import UserError
from receiver.source.io import FORMATS, quantize
from receiver.sim import simulate as sim_mod
from receiver.sim.cli import evaluate_cmd, simulate as simulate_cmd
from receiver.sim.kernel import quantize_fast
from receiver.sim.scenario import REPO_ROOT, load_scenario, resolve_path, scenario_doc

TINY = {"time": {"duration_s": 0.05, "seed": 3}, "constellation": {"prns": [11, 24]},
        "frontend": {"sample_rate_hz": 1.0e6}}


def test_cli_simulate_and_outputs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sc.yaml").write_text(yaml.safe_dump(TINY))
    # a missing output directory is made (every command's rule), but not for bad input
    res = CliRunner().invoke(simulate_cmd, ["sc.yaml", "-o", "out/rec.bin", "--set", "cn0.dbhz=-"])
    assert isinstance(res.exception, UserError) and not os.path.exists("out")
    res = CliRunner().invoke(simulate_cmd, ["sc.yaml", "-o", "out/rec.bin", "--set", "cn0.dbhz=47",
                                            "--set", "frontend.format=int16_iq"])
    assert res.exit_code == 0, res.output
    assert "G11" in res.output and "G24" in res.output
    assert os.path.getsize("out/rec.bin") == 50000 * 4
    with h5py.File("out/rec.truth.h5", "r") as f:
        a = f.attrs
        assert a["gnssrx_version"] == __version__ and a["format"] == "int16_iq" and a["seed"] == 3
        assert a["sample_rate_hz"] == 1e6 and a["if_hz"] == 0.0 and a["gps_week"] == 2190
        sc = yaml.safe_load(a["scenario"])
        assert sc["cn0"]["dbhz"] == 47.0
        assert f["receiver/ecef"].shape == (5, 3) and f["receiver/time_s"][-1] == pytest.approx(0.04)
        g = f["satellites/G11"]
        for name in ("time_s", "gps_tow", "pseudorange_m", "range_m", "range_rate_mps", "doppler_hz",
                     "carrier_phase_cycles", "code_phase_chips", "cn0_dbhz", "visible", "scint_amplitude",
                     "scint_phase_rad", "elevation_deg", "azimuth_deg"):
            assert g[name].shape == (5,), name
        assert g["visible"].dtype == bool
    # the fragment is a valid receiver input section
    frag = yaml.safe_load(open("out/rec.yaml"))
    cfg = load_receiver_config(None, [("input." + k, v) for k, v in frag["input"].items()])
    assert cfg.input.path == "rec.bin" and cfg.input.format == "int16_iq"
    assert cfg.input.start_gps_tow_s == 525584.0 and cfg.input.start_gps_week == 2190


def test_cli_errors_leave_no_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    from receiver.cli import main
    (tmp_path / "sc.yaml").write_text(yaml.safe_dump({"frontend": {"bogus": 1}}))
    res = CliRunner().invoke(main, ["simulate", "sc.yaml", "-q"])
    assert res.exit_code == 2 and "frontend.bogus" in res.output and len(res.output.splitlines()) == 1
    (tmp_path / "sc.yaml").write_text(yaml.safe_dump({"frontend": {"format": "int8_real"}}))
    res = CliRunner().invoke(main, ["simulate", "sc.yaml", "-q"])
    assert res.exit_code == 2 and "frontend.if_hz" in res.output
    assert not any(p.suffix in (".bin", ".h5") for p in tmp_path.iterdir())


def test_partial_outputs_removed_on_failure(tmp_path, monkeypatch):
    calls = []
    real_block = sim_mod._Simulator._block

    def failing(self, g0, n):
        calls.append(g0)
        if len(calls) > 1:
            raise RuntimeError("disk full")
        return real_block(self, g0, n)

    monkeypatch.setattr(sim_mod._Simulator, "_block", failing)
    out = tmp_path / "x.bin"
    with pytest.raises(RuntimeError):
        sim_mod.simulate({**TINY, "time": {"duration_s": 0.3}, "output": {"block_s": 0.1}}, str(out),
                         progress=False)
    assert len(calls) == 2 and list(tmp_path.iterdir()) == []


def test_eval_command(tmp_path):
    paths = sim_mod.simulate(TINY, str(tmp_path / "t.bin"), progress=False)
    with h5py.File(paths["truth"], "r") as f:
        rx = f["receiver"]
        n = rx["gps_tow"].shape[0]
        run = tmp_path / "run.h5"
        with h5py.File(run, "w") as r:
            g = r.create_group("navigation")
            g["gps_week"] = np.full(n, f.attrs["gps_week"], np.int32)
            g["gps_tow"] = rx["gps_tow"][:]
            g["ecef"] = rx["ecef"][:] + [1.0, 2.0, 2.0]
            g["velocity_ecef"] = rx["velocity_ecef"][:]
            g["clock_bias_m"] = rx["clock_bias_m"][:]
            g["clock_drift_mps"] = rx["clock_drift_mps"][:]
    res = CliRunner().invoke(evaluate_cmd, [str(run), paths["truth"]])
    assert res.exit_code == 0 and "position 3D RMS" in res.output and "3.000" in res.output
    res = CliRunner().invoke(evaluate_cmd, [str(run), paths["truth"], "--json"])
    assert yaml.safe_load(res.output)["pos_3d_rms_m"] == pytest.approx(3.0)


def test_scenario_validation_and_paths(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(UserError, match="time.duration_s"):
        load_scenario({"time": {"duration_s": "long"}})
    with pytest.raises(UserError, match="output.truth_rate_hz"):
        load_scenario({"output": {"truth_rate_hz": 300.0}})
    with pytest.raises(UserError, match="constellation.rinex"):
        load_scenario({"constellation": {"source": "rinex"}})
    # relative paths: current directory first, then the repository root
    assert resolve_path("data/gps_nominal_constellation.yaml") == str(REPO_ROOT /
                                                                    "data/gps_nominal_constellation.yaml")
    (tmp_path / "data").mkdir()
    (tmp_path / "data/gps_nominal_constellation.yaml").write_text("x: 1\n")
    assert resolve_path("data/gps_nominal_constellation.yaml") == str(tmp_path /
                                                                    "data/gps_nominal_constellation.yaml")
    with pytest.raises(UserError, match="not found"):
        resolve_path("nowhere/file.22n", "RINEX file")
    keys = [r[0] for r in scenario_doc()]
    assert "scintillation.s4" in keys and "frontend.format" in keys and "clock.noise" in keys


@pytest.mark.parametrize("scenario", ["static_default.yaml", "static_tokyo_brdc.yaml"])
def test_shipped_scenarios_load(scenario):
    sc = load_scenario(REPO_ROOT / "configs" / "scenarios" / scenario)
    assert sc.frontend.format == "int8_iq" and sc.frontend.sample_rate_hz == 2.6e6
    if scenario == "static_default.yaml":
        assert sc.time.duration_s == 45.0 and sc.constellation.source == "embedded"
        assert sc.cn0.dbhz == 45.0 and sc.receiver.trajectory == "static"


@pytest.mark.parametrize("fmt", [f for f in FORMATS if FORMATS[f].kind in ("int", "float")])
def test_fast_quantizer_equals_io_quantize(fmt):
    rng = np.random.default_rng(0)
    x = (rng.standard_normal(5000) * 60 + 1j * rng.standard_normal(5000) * 60).astype(np.complex64)
    x[:8] = [0.5, 1.5, 2.5, -0.5, -2.5, 200.0, -40000.0, 3.5 - 2.5j]
    a, b = quantize_fast(x, fmt), quantize(x, fmt)
    assert a.dtype == b.dtype and np.array_equal(a, b)
