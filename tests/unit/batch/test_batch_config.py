"""Batch YAML: validation, expansion of variants x sweeps x inputs x seeds, config layering, content hashes,
failing runs, and the CLI's error handling (all without simulating anything)."""
import csv
import math
import os
import subprocess
import sys

import numpy as np
import pytest
import yaml

from receiver.batch.config import load_batch
from receiver.batch.plan import code_fingerprint, make_plan
from receiver.batch.runner import run_batch
from receiver.errors import UserError

from repo_paths import ROOT
SCENARIO = os.path.join(ROOT, "configs", "scenarios", "static_default.yaml")


def _noise(path, seconds, fs=2.6e6, seed=0):
    rng = np.random.default_rng(seed)
    rng.normal(0, 8, int(2 * seconds * fs)).clip(-127, 127).astype(np.int8).tofile(path)
    return str(path)


def _batch(tmp_path, **extra):
    rec = tmp_path / "noise.bin"
    if not rec.exists():
        _noise(rec, 0.2)
    b = {
        "name": "t",
        "output_dir": str(tmp_path / "out"),
        "set": {"navigation.rate_hz": 2.0, "tracking.dll_bw_hz": 1.0},
        "variants": [{"name": "a", "set": {"tracking.pll_bw_hz": 15.0}},
                     {"name": "b", "set": ["tracking.pll_bw_hz=25", "tracking.dll_bw_hz=3"],
                      "sweep": {"tracking.dll_order": [1, 2]}}],
        "inputs": [{"name": "sim", "scenario": SCENARIO, "set": {"time.duration_s": 5.0}, "assisted": True,
                    "seeds": [1, 2]},
                   {"name": "rec", "recording": str(rec), "receiver_set": {"tracking.dll_bw_hz": 2.0,
                                                                           "input.format": "int8_iq"}}],
        "code_version": "test",
    }
    b.update(extra)
    return b


def test_expansion_layering_and_columns(tmp_path):
    b = load_batch(_batch(tmp_path))
    assert [v.label for v in b.variants] == ["a", "b[tracking.dll_order=1]", "b[tracking.dll_order=2]"]
    assert b.set_keys == ["tracking.pll_bw_hz", "tracking.dll_bw_hz", "tracking.dll_order"]
    plan = make_plan(b)
    assert len(plan.runs) == 3 * 3 and len(plan.recordings) == 2
    by = {(r.variant, r.input, r.seed): r for r in plan.runs}
    a_sim = by[("a", "sim", 1)].config
    assert a_sim["tracking"]["pll_bw_hz"] == 15.0
    assert a_sim["tracking"]["dll_bw_hz"] == 1.0                  # batch set
    assert a_sim["navigation"]["rate_hz"] == 2.0
    rec_key = by[("a", "sim", 1)].recording
    assert a_sim["input"]["path"] == plan.recordings[rec_key].paths["if"]
    assert a_sim["navigation"]["ephemeris"] == plan.recordings[rec_key].paths["nav"]     # assisted
    assert a_sim["input"]["start_gps_tow_s"] == 345600.0 and a_sim["input"]["start_gps_week"] == 2300
    assert by[("a", "sim", 2)].recording != rec_key                 # one recording per seed
    assert plan.recordings[by[("a", "sim", 2)].recording].scenario["time"]["seed"] == 2
    assert by[("a", "rec", None)].config["tracking"]["dll_bw_hz"] == 2.0          # input receiver_set
    b_rec = by[("b[tracking.dll_order=1]", "rec", None)]
    assert b_rec.config["tracking"]["dll_bw_hz"] == 3.0              # the variant wins over the input
    assert b_rec.config["tracking"]["dll_order"] == 1
    assert b_rec.set_values == {"tracking.pll_bw_hz": 25.0, "tracking.dll_bw_hz": 3.0, "tracking.dll_order": 1}
    assert b_rec.config["output"]["path"] == b_rec.h5 and b_rec.h5.endswith(b_rec.key + ".h5")
    assert by[("a", "rec", None)].set_values["tracking.dll_order"] == 2          # the default
    assert len({r.key for r in plan.runs}) == len(plan.runs)


def test_hashes_stable_and_selective(tmp_path):
    keys = {(r.variant, r.input, r.seed): r.key for r in make_plan(load_batch(_batch(tmp_path))).runs}
    again = {(r.variant, r.input, r.seed): r.key for r in make_plan(load_batch(_batch(tmp_path))).runs}
    assert keys == again
    changed = _batch(tmp_path)
    changed["variants"][0]["set"] = {"tracking.pll_bw_hz": 16.0}
    new = {(r.variant, r.input, r.seed): r.key for r in make_plan(load_batch(changed)).runs}
    assert all((new[k] != keys[k]) == (k[0] == "a") for k in keys)
    other_out = {(r.variant, r.input, r.seed): r.key
                 for r in make_plan(load_batch(_batch(tmp_path, output_dir=str(tmp_path / "elsewhere")))).runs}
    assert other_out == keys                                         # the output location is not hashed
    code = {(r.variant, r.input, r.seed): r.key
            for r in make_plan(load_batch(_batch(tmp_path, code_version="other"))).runs}
    assert all(code[k] != keys[k] for k in keys)
    _noise(tmp_path / "noise.bin", 0.2, seed=1)                      # same size, new content
    content = {(r.variant, r.input, r.seed): r.key for r in make_plan(load_batch(_batch(tmp_path))).runs}
    assert all((content[k] != keys[k]) == (k[1] == "rec") for k in keys)


def test_code_fingerprint():
    auto = code_fingerprint("auto")
    assert auto.startswith("auto:") and auto == code_fingerprint("auto")
    assert code_fingerprint("v1") == "fixed:v1"


def test_code_fingerprint_follows_the_numeric_libraries(monkeypatch):
    import numba
    import numpy as np
    before = code_fingerprint("auto")
    monkeypatch.setattr(numba, "__version__", numba.__version__ + ".post1")
    after_numba = code_fingerprint("auto")
    monkeypatch.setattr(np, "__version__", np.__version__ + ".post1")
    assert len({before, after_numba, code_fingerprint("auto")}) == 3
    assert code_fingerprint("v1") == "fixed:v1"          # a pinned version stays pinned


@pytest.mark.parametrize("mutate, message", [
    (lambda b: b.update(bogus=1), "unknown config key 'bogus'"),
    (lambda b: b["variants"][0].update(colour="red"), "variants[0].colour"),
    (lambda b: b["variants"].append({"name": "a"}), "duplicate variant name 'a'"),
    (lambda b: b["variants"][0].pop("name"), "variants[0].name"),
    (lambda b: b["inputs"][0].update(recording="x.bin"), "exactly one of 'scenario' or 'recording'"),
    (lambda b: b["inputs"][1].update(name="sim"), "duplicate input name 'sim'"),
    (lambda b: b["inputs"][0].update(scenario="nope.yaml"), "inputs[0].scenario not found"),
    (lambda b: b["inputs"][1].update(seeds=[1]), "applies to scenarios only"),
    (lambda b: b.update(inputs=[]), "at least one input"),
    (lambda b: b.update(sweep={"tracking.pll_bw_hz": 5}), "non-empty list"),
    (lambda b: b["variants"][0].update(set={"tracking.pll_bw_hz": "wide"}), "variant 'a', input 'sim'"),
    (lambda b: b["variants"][0].update(set={"tracking.no_such_key": 1}), "tracking.no_such_key"),
    (lambda b: b["inputs"][0]["set"].update({"time.duration_s": -1}), "time.duration_s"),
    (lambda b: b.update(variants=[{"name": "x"}, {"name": "y"}]), "identical configs"),
])
def test_bad_batches(tmp_path, mutate, message):
    b = _batch(tmp_path)
    mutate(b)
    with pytest.raises(UserError) as exc:
        make_plan(load_batch(b))
    assert message in str(exc.value)


@pytest.mark.slow
def test_failing_run_is_recorded_and_others_continue(tmp_path):
    """A recording too short for acquisition fails; the other run completes; failures are cached unless
    retry_failed."""
    good = _noise(tmp_path / "good.bin", 0.6)
    bad = _noise(tmp_path / "bad.bin", 0.0005)     # under 1 ms: not even a fitted search fits
    b = {"name": "f", "output_dir": str(tmp_path / "out"), "code_version": "test",
         "set": {"acquisition.prns": [1, 2], "navigation.enabled": False},
         "inputs": [{"name": "good", "recording": good}, {"name": "bad", "recording": bad}]}
    res = run_batch(b, jobs=1)
    assert (res.n_runs, res.executed, res.failed) == (2, 2, 1)
    rows = {r["input"]: r for r in res.rows}
    assert rows["good"]["status"] == "ok" and rows["good"]["n_fixes"] == 0
    assert math.isnan(rows["good"]["pos_3d_rms_m"]) and rows["good"]["signal_s"] == pytest.approx(0.6)
    assert rows["bad"]["status"] == "failed" and "too short" in rows["bad"]["error"]
    with open(res.summary_csv) as fh:
        csv_rows = {r["input"]: r for r in csv.DictReader(fh)}
    assert csv_rows["bad"]["status"] == "failed" and "too short" in csv_rows["bad"]["error"]
    again = run_batch(b, jobs=1)
    assert (again.executed, again.cached, again.failed) == (0, 2, 1)
    retry = run_batch(b, jobs=1, retry_failed=True)
    assert (retry.executed, retry.cached) == (1, 1)


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "receiver.cli", *args], capture_output=True, text=True,
                          cwd=cwd or ROOT)


@pytest.mark.slow
def test_cli_errors_and_dry_run(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"inputs": [{"scenario": SCENARIO}], "variants": [{"name": "v", "set": {
        "tracking.pll_bw_hz": -3}}]}))
    p = _cli("batch", str(bad), "--out", str(tmp_path / "o"))
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "tracking.pll_bw_hz" in p.stderr
    p = _cli("batch", str(tmp_path / "missing.yaml"))
    assert p.returncode == 2 and "not found" in p.stderr
    good = tmp_path / "good.yaml"
    good.write_text(yaml.safe_dump(_batch(tmp_path)))
    p = _cli("batch", str(good), "--dry-run")
    assert p.returncode == 0, p.stderr
    assert "9 runs: 9 to run, 0 cached; 2 simulated recordings (2 not on disk)" in p.stdout
    p = _cli("compare", str(tmp_path / "nothing.h5"))
    assert p.returncode == 2 and "summary file not found" in p.stderr
