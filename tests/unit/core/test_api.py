"""receiver.api: the command line's entry points as functions (docs/plugins.md "Python API")."""
import numpy as np
import pytest

from receiver import api
from repo_paths import ROOT


def test_load_config_takes_overrides_as_a_dict_or_strings():
    a = api.load_config(None, {"tracking.pll_bw_hz": 12.0, "navigation.filter": "ekf"})
    b = api.load_config("configs/default.yaml", ["tracking.pll_bw_hz=12", "navigation.filter=ekf"])
    assert a.to_dict() == b.to_dict() and a.tracking.pll_bw_hz == 12.0
    with pytest.raises(api.UserError, match="tracking.pll_bw_hz' must be >= 0.1"):
        api.load_config(None, {"tracking.pll_bw_hz": 0.0})


def test_list_plugins_has_the_builtins():
    got = api.list_plugins()
    assert [n for n, *_ in got["carrier_loop"]][:2] == ["pll", "cpll_atan"]
    assert ("adaptive_r", "built-in") == got["vector_filter"][1][:2]


@pytest.mark.slow
def test_run_open_and_evaluate_a_simulated_recording(tmp_path):
    from receiver.batch.tasks import write_nav_for_scenario
    from receiver.sim.scenario import load_scenario
    from receiver.sim.simulate import simulate
    sc = load_scenario(ROOT / "configs" / "scenarios" / "static_default.yaml", [("time.duration_s", 8.0)])
    paths = simulate(sc, tmp_path / "s.bin", progress=False)
    write_nav_for_scenario(sc.to_dict(), str(tmp_path / "s.nav"))        # assisted: fixes within seconds
    out = api.run(tmp_path / "s.yaml", output=tmp_path / "run.h5",
                  overrides={"navigation.rate_hz": 2.0, "navigation.ephemeris": str(tmp_path / "s.nav")})
    run = api.open_run(out)
    assert run.cfg("navigation.rate_hz") == 2.0 and run.cfg("no.such.key", 7) == 7
    assert len(run.fixes) >= 5 and len(run.observables) >= 4 * len(run.fixes)
    first = next(iter(run.channels.values()))
    assert len(first["doppler_hz"]) > 1000 and np.isfinite(first["cn0_dbhz"]).all()
    stats = api.evaluate(out, paths["truth"])
    assert stats["n_scored"] == len(run.fixes) and stats["pos_3d_rms_m"] < 15.0
