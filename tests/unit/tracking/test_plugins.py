"""Carrier-loop plugins (receiver/plugins.py, receiver/tracking/carrier.py, docs/plugins.md).

The built-in cpll_atan written again as a plugin through the public interface only
(tests/unit/tracking/plugins/cpll_again.py: a reference path and a compiled path) gives bit for bit the
run file of the built-in; broken plugins are one line and exit 2; `gnssrx plugins` lists an installed
(entry-point) plugin and where it comes from; the run file records the plugin's name, version and
parameters."""
import json
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from repo_paths import ROOT

HERE = Path(__file__).resolve().parent / "plugins"
SCENARIO = ROOT / "configs" / "scenarios" / "static_default.yaml"


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """3 s of GPS satellite G06 at 45 dB-Hz (the embedded constellation; no external data)."""
    from receiver.sim.simulate import simulate
    d = tmp_path_factory.mktemp("plugin_rec")
    paths = simulate(SCENARIO, d / "s.bin", [("time.duration_s", 3.0), ("constellation.prns", [6])],
                     progress=False)
    return Path(paths["if"])


@pytest.fixture()
def plugin_path(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    return HERE


def _run(rec, out, *sets):
    from receiver.cli import main
    args = ["run", str(rec.with_suffix(".yaml")), "-o", str(out), "--quiet", "--threads", "1",
            "--set", "navigation.enabled=false"]
    for s in sets:
        args += ["--set", s]
    assert main.main(args, standalone_mode=False) in (0, None)
    return out


@pytest.mark.slow
def test_builtin_loop_as_a_plugin_gives_the_same_run_file(recording, plugin_path, tmp_path):
    from receiver.runfile.compare import compare_h5
    a = _run(recording, tmp_path / "builtin.h5", "tracking.carrier.variant=cpll_atan")
    b = _run(recording, tmp_path / "plugin.h5", "tracking.carrier.variant=cpll_again:CpllAgain")
    c = _run(recording, tmp_path / "pll.h5")
    diffs = []
    compare_h5(a, b, diffs)
    # everything but the config text (variant name, the plugin's section) and the plugins attribute
    assert sorted(d.split(":")[0] for d in diffs) == ["/@config", "/@plugins"], diffs
    with h5py.File(a) as fa, h5py.File(b) as fb, h5py.File(c) as fc:
        assert "plugins" not in fa.attrs                    # the built-in: no plugin recorded
        used = json.loads(fb.attrs["plugins"])
        assert used == [{"kind": "carrier_loop", "key": "tracking.carrier.variant", "name": "cpll_again:CpllAgain",
                         "class": "cpll_again.CpllAgain", "origin": "module cpll_again", "version": "1.0",
                         "params": {"bn_hz": 15.0, "order": 3}}]
        assert "cpll_again:\n      bn_hz: 15.0" in fb.attrs["config"]
        # the loop did take the carrier over: the run differs from the kernel's own PLL
        key = sorted(fa["channels"].keys())[0]
        da, dc = fa["channels"][key]["doppler_hz"][()], fc["channels"][key]["doppler_hz"][()]
        assert len(da) == len(dc) > 2000 and not np.array_equal(da, dc)


def test_plugin_compiled_path_equals_its_reference_path(recording, plugin_path):
    from receiver.schema import load_receiver_config
    from receiver.tracking.scalar import Channel
    raw = np.fromfile(recording, np.int8)
    x = (raw[0::2] + 1j * raw[1::2]).astype(np.complex64)
    from receiver.acquisition import search
    acq = [a for a in search(x[:int(0.06 * 2.6e6)], 0, 2.6e6, 0.0, [6]) if a.detected]
    assert len(acq) == 1
    cfg = load_receiver_config(None, ["tracking.carrier.variant=cpll_again:CpllAgain",
                                      "tracking.carrier.cpll_again.order=2"])
    for a in acq:
        runs = []
        for compiled in (True, False):
            ch = Channel(a.prn, a.doppler_hz, a.code_phase_chips, a.sample_index, cfg.tracking, 2.6e6, 0.0)
            assert ch.loop.order == 2 and ch.use_compiled_loop
            ch.use_compiled_loop = compiled
            chunk, pad, recs = int(0.5 * 2.6e6), int(0.03 * 2.6e6), []
            for start in range(0, len(x) - chunk, chunk):
                s = ch.next_sample if start else a.sample_index
                recs.append(ch.process(x[s:start + chunk + pad], s))
            assert ch._loop_started
            runs.append(np.concatenate(recs))
        for name in ("doppler_hz", "carrier_phase_cycles", "code_phase_chips", "prompt_i", "prompt_q"):
            np.testing.assert_array_equal(runs[0][name], runs[1][name], err_msg=name)


def _cli(args, env_path=None, cwd=None):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(HERE)] + ([str(env_path)] if env_path
                                                                                      else []))}
    return subprocess.run([sys.executable, "-m", "receiver.cli", *args], capture_output=True, text=True,
                          env=env, cwd=cwd)


@pytest.mark.parametrize("variant,message", [
    ("cpll_again:NoUpdate", "missing method step"),
    ("cpll_again:BadParam", "the default of parameter 'bn_hz' must be >= 0.1"),
    ("no_such_module:Loop", "cannot import module no_such_module (ModuleNotFoundError"),
    ("cpll_again:Nothing", "module cpll_again has no Nothing"),
])
def test_a_broken_plugin_is_one_line_and_exit_2(variant, message, tmp_path):
    r = _cli(["run", str(ROOT / "configs" / "default.yaml"), "--input", str(tmp_path / "none.bin"),
              "--set", f"tracking.carrier.variant={variant}"])
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], r.stderr


@pytest.mark.slow
def test_a_plugin_parameter_is_validated_like_ours(tmp_path):
    base = ["run", str(ROOT / "configs" / "default.yaml"), "--input", str(tmp_path / "none.bin"),
            "--set", "tracking.carrier.variant=cpll_again:CpllAgain"]
    for extra, message in ((["--set", "tracking.carrier.cpll_again.order=4"],
                            "config key 'tracking.carrier.cpll_again.order' must be one of 2, 3; got 4"),
                           (["--set", "tracking.carrier.cpll_again.bw=4"],
                            "unknown config key 'tracking.carrier.cpll_again.bw'")):
        r = _cli(base + extra)
        assert r.returncode == 2 and r.stderr.strip().splitlines() == [f"gnssrx: error: {message}"], r.stderr


def _fake_distribution(site: Path, name: str, entries: dict):
    """An installed distribution (dist-info with entry points) on a path entry, without pip."""
    info = site / f"{name.replace('-', '_')}-0.3.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.3\n")
    (info / "entry_points.txt").write_text("[gnssrx.carrier_loops]\n" +
                                           "".join(f"{k} = {v}\n" for k, v in entries.items()))


@pytest.mark.slow
def test_gnssrx_plugins_lists_an_installed_plugin(tmp_path):
    _fake_distribution(tmp_path / "site", "demo-loops", {"cpll_again": "cpll_again:CpllAgain",
                                                         "broken": "cpll_again:NoUpdate"})
    r = _cli(["plugins"], env_path=tmp_path / "site")
    assert r.returncode == 0, r.stderr
    lines = {ln.split()[0]: ln for ln in r.stdout.splitlines() if ln.startswith("  ")}
    assert "built-in" in lines["pll"] and "built-in" in lines["adaptive_r"]
    assert "plugin" in lines["cpll_again"] and "entry point gnssrx.carrier_loops of demo-loops" in \
        lines["cpll_again"] and "1.0" in lines["cpll_again"]
    assert "BROKEN" in lines["broken"] and "missing method step" in lines["broken"]
    # and the entry-point name is a variant like a built-in one
    r = _cli(["run", str(ROOT / "configs" / "default.yaml"), "--input", str(tmp_path / "none.bin"),
              "--set", "tracking.carrier.variant=cpll_again", "--set", "tracking.carrier.cpll_again.order=5"],
             env_path=tmp_path / "site")
    assert r.returncode == 2 and "tracking.carrier.cpll_again.order' must be one of 2, 3" in r.stderr


def test_a_vector_filter_plugin_takes_its_parameters(plugin_path):
    from receiver.errors import UserError
    from receiver.schema import load_receiver_config, used_plugins
    from receiver.tracking.vector import make_filter
    cfg = load_receiver_config(None, ["vector.enabled=true", "vector.variant=vector_again:ScaledR",
                                      "vector.scaled_r.r_scale=4"])
    f = make_filter(cfg.vector.variant, cfg.vector)
    assert (f.r_code, f.r_carr) == (4 * cfg.vector.r_code_m2, 4 * cfg.vector.r_carrier_m2s2)
    assert [(u["name"], u["version"], u["params"]) for u in used_plugins(cfg)] == \
        [("vector_again:ScaledR", "2.0", {"r_scale": 4.0})]
    with pytest.raises(UserError, match="vector.scaled_r.r_scale' must be <= 1000.0"):
        load_receiver_config(None, ["vector.variant=vector_again:ScaledR", "vector.scaled_r.r_scale=1e4"])
    with pytest.raises(UserError, match="vector filter plugin 'vector_again:NoModel': missing method matrices"):
        load_receiver_config(None, ["vector.variant=vector_again:NoModel"])
