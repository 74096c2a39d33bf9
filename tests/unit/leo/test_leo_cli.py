"""``gnssrx leo simulate`` / ``gnssrx leo fix`` (receiver.leo.cli) and the shipped configs."""
import os

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from receiver.leo.cli import leo
from receiver.leo.config import load_fix_config, load_scenario

from repo_paths import ROOT
SCEN = os.path.join(ROOT, "configs", "leo", "scenario_beijing.yaml")
FIX = os.path.join(ROOT, "configs", "leo", "fix_default.yaml")


def test_shipped_configs_equal_schema_defaults():
    # the YAML files document the defaults: they must validate and agree with the schemas
    assert load_scenario(SCEN).to_dict() == load_scenario(None).to_dict()
    assert load_fix_config(FIX).to_dict() == load_fix_config(None).to_dict()


@pytest.fixture(scope="module")
def meas(tmp_path_factory):
    out = tmp_path_factory.mktemp("leo") / "meas.h5"
    res = CliRunner().invoke(leo, ["simulate", SCEN, "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "42 Doppler observations of 2 satellites" in res.output
    return out


@pytest.mark.parametrize("solver", ["lsm", "ekf", "ckf", "sqrt_ckf"])
def test_fix_every_solver(meas, tmp_path, solver):
    out = tmp_path / "fix.h5"
    res = CliRunner().invoke(leo, ["fix", FIX, str(meas), "--solver", solver, "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert f"solver {solver}" in res.output and "GeoSOT level 18" in res.output
    with h5py.File(out) as f:
        est = f["estimates"][()]
        truth = f["truth_ecef_m"][()]
        assert f.attrs["solver"] == solver
    assert est.shape == (21, 4)
    assert np.linalg.norm(est[-1, :3] - truth) < 300.0


def test_user_errors_exit_2_with_one_line_and_no_output(meas, tmp_path):
    runner = CliRunner()
    out = tmp_path / "never.h5"
    cases = [
        ["fix", FIX, str(meas), "-o", str(out), "--set", "leo.solver=kalman"],
        ["fix", FIX, str(meas), "-o", str(out), "--set", "geosot.unknown=1"],
        ["fix", FIX, str(tmp_path / "missing.h5"), "-o", str(out)],
        ["fix", FIX, str(meas), "-o", str(out), "--set", "leo.init=given"],
        ["fix", FIX, str(meas), "-o", str(out), "--set", "geosot.start_level=12",
         "--set", "geosot.end_level=10"],
        ["simulate", SCEN, "-o", str(out), "--set", f"constellation.tle_file={SCEN}"],
        ["simulate", SCEN, "-o", str(out), "--set", "time.step_s=0"],
        ["simulate", str(tmp_path / "nope.yaml"), "-o", str(out)],
        ["simulate", str(tmp_path / "nope.yaml"), "-o", str(tmp_path / "no_dir" / "x.h5")],
    ]
    for args in cases:
        res = runner.invoke(leo, args)
        assert res.exit_code == 2, (args, res.output)
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("gnssrx: error: "), (args, res.output)
        assert not out.exists() and not os.path.exists(str(out) + ".part")
    assert not (tmp_path / "no_dir").exists()            # bad input: no directory made either
    # a missing output directory is made (every command's rule)
    res = runner.invoke(leo, ["simulate", SCEN, "-o", str(tmp_path / "no_dir" / "x.h5")])
    assert res.exit_code == 0 and (tmp_path / "no_dir" / "x.h5").is_file(), res.output


def test_user_tle_file_and_earth_centre_start(tmp_path):
    from receiver.leo.constellation import default_tle_path
    tle = tmp_path / "mine.tle"
    with open(default_tle_path()) as fh:
        tle.write_text(fh.read())
    m = tmp_path / "m.h5"
    res = CliRunner().invoke(leo, ["simulate", SCEN, "-o", str(m), "--set",
                                   f"constellation.tle_file={tle}", "--set",
                                   "measurement.noise_sigma_hz=0"])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(leo, ["fix", FIX, str(m), "--set", "leo.init=earth_center",
                                   "--set", "leo.sigma_hz=0.5"])
    # runs, but the answer is far off (see test_leo_solvers for the divergence test)
    assert "error vs truth" in res.output or "warning" in res.output
    res = CliRunner().invoke(leo, ["fix", FIX, str(m)])
    assert res.exit_code == 2 and "leo.sigma_hz" in res.output
