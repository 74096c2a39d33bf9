"""The paper figures are reproducible: the same seed gives the same numbers for any number of parallel jobs,
and figures-check compares against its reference with the stated tolerances."""
import importlib.util
import json
import os
import subprocess
import sys

from repo_paths import ROOT


def _load(name):
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, "scripts", "figures", f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_carrier_monte_carlo_is_identical_for_one_and_two_jobs(tmp_path):
    fc = _load("figures_carrier")
    docs = []
    for jobs in (1, 2):
        out = tmp_path / f"j{jobs}"
        js = tmp_path / f"j{jobs}.json"
        # a subprocess: the worker pool pickles the script's job functions by module name
        subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "figures", "figures_carrier.py"),
                        "--out", str(out),
                        "--seeds", "2", "--duration", "4", "--scenarios", "3", "--weak-seeds", "2", "--weak-T", "20",
                        "--jobs", str(jobs), "--json", str(js)], check=True, stdout=subprocess.DEVNULL,
                       env={**os.environ, "PYTHONPATH": os.path.abspath(ROOT)})
        docs.append(json.loads(js.read_text()))
    a, b = docs
    assert a == b                                    # every per-seed value, bit for bit
    # and the experiment is not degenerate: two seeds differ, the loops differ
    s = a["scint"]["s3_cpll_atan"]["std_per_seed"]
    assert s[0] != s[1]
    assert a["scint"]["s3_ekf"]["std_per_seed"] != s
    assert len(a["weak"]["static_T20_adaptive_kf"]) == 2
    # the table shows the seed statistics (mean ± Student-t half width)
    table = (tmp_path / "j1" / "table.md").read_text()
    m, h = fc.ci95(s)
    assert f"{m:.2f} ± {h:.2f}" in table


def test_figures_check_tolerances(tmp_path):
    chk = _load("figures_check")
    ref = {"values": {"a": {"value": 10.0, "tol_abs": 0.05, "tol_rel": 0.02},
                      "b": {"value": 0.001, "tol_abs": 0.004, "tol_rel": 0.1}}}
    bad, _ = chk.compare({"a": (10.19, ""), "b": (0.004, "")}, ref)
    assert bad == []
    bad, lines = chk.compare({"a": (10.21, ""), "b": (0.0051, "")}, ref)
    assert bad == ["a", "b"] and all("MISMATCH" in ln for ln in lines)
    bad, _ = chk.compare({"a": (float("nan"), "")}, ref)
    assert bad == ["a", "b"]                          # NaN and a missing value both fail


def test_committed_reference_is_complete():
    with open(os.path.join(ROOT, "configs", "figures_reference.json")) as fh:
        ref = json.load(fh)
    names = set(ref["values"])
    assert any(n.startswith("carrier/s3_pli_ekf_paper/") for n in names)
    assert any(n.startswith("leo/sqrt_ckf/") for n in names)
    assert any(n.startswith("vector/accel/poly_25/") for n in names)
    for v in ref["values"].values():
        assert v["tol_abs"] > 0 and 0 < v["tol_rel"] < 0.2


def test_carrier_theory_crossing_is_exact():
    """The theory row of the carrier table: sigma_phi at which the paper's eq. 9 jitter reaches 15 deg, in
    closed form (a search grid stopping at 5 rad printed 'nan' for p = 2.5 and 3)."""
    import math
    fc = _load("figures_carrier")
    for p in (2.0, 2.5, 3.0):
        x, ts = fc.sigma_phi_at(15.0, p=p)
        assert math.isfinite(x) and x > 0 and ts > 0
        assert abs(fc.sigma_pll_deg(0.0, x, p=p)[0] - 15.0) < 1e-9
        assert fc.sigma_pll_deg(0.0, 0.99 * x, p=p)[0] < 15.0
    assert abs(fc.sigma_phi_at(15.0, p=2.0)[0] - 3.23) < 0.01      # what the grid search found for p = 2
    assert fc.sigma_phi_at(15.0, p=2.5)[0] > 5.0                   # beyond the old grid: was nan


def _vector_dir(path, per_seed, diverged, fv):
    rows = [{"run": "fixed_r", "pos_rms": 0.0, "seed": s, "diverged": d, "lock_kept": not d,
             **{k: (v if k == "pos_rms" else 1.0) for k in fv.NUMERIC}}
            for s, v, d in zip((8, 101, 102), per_seed, diverged)]
    for r, v in zip(rows, per_seed):
        r["pos_rms"] = v
    agg = fv.aggregate(rows, ["fixed_r"])
    (path / "vector").mkdir(parents=True)
    (path / "vector" / "vector_results.json").write_text(json.dumps(fv._jsonable(
        {"fig8": {"rows": agg, "per_seed_rows": rows, "plotted_seed": 8}})))
    return str(path)


def test_figures_compare(tmp_path, capsys):
    cmp, fv = _load("figures_compare"), _load("figures_vector")
    a = _vector_dir(tmp_path / "a", [10.0, 12.0, 14.0], [False, False, True], fv)
    same = _vector_dir(tmp_path / "same", [10.0, 12.0, 14.0], [False, False, True], fv)
    near = _vector_dir(tmp_path / "near", [10.5, 12.0, 14.0], [False, False, True], fv)   # inside the intervals
    far = _vector_dir(tmp_path / "far", [40.0, 42.0, 44.0], [False, False, True], fv)     # outside
    div = _vector_dir(tmp_path / "div", [10.0, 12.0, 14.0], [False, False, False], fv)   # divergence count differs
    assert cmp.main([a, same]) == 0
    assert "1 identical per seed" not in capsys.readouterr().out     # every cell identical, none listed
    assert cmp.main([a, near]) == 0
    out = capsys.readouterr().out
    assert "vector/fig8/fixed_r/pos_rms" in out and "within intervals" in out and "max per-seed |diff| 0.5" in out
    assert cmp.main([a, far]) == 1
    assert "OUTSIDE intervals" in capsys.readouterr().out
    assert cmp.main([a, div]) == 1
    assert "fixed_r/diverged: 1/3 | 0/3 -> OUTSIDE" in capsys.readouterr().out
    assert cmp.main([a, str(tmp_path / "nope")]) == 2
    assert "not a directory" in capsys.readouterr().err
    # a run cut short (fewer seeds): the seeds both have must agree per seed, the means within the intervals
    sub = _vector_dir(tmp_path / "sub", [10.0, 12.0], [False, False], fv)
    assert cmp.main([a, sub]) == 0
    assert "common seeds [8, 101]: identical" in capsys.readouterr().out
    sub_bad = _vector_dir(tmp_path / "sub_bad", [10.3, 12.0], [False, False], fv)
    assert cmp.main([a, sub_bad]) == 1
    assert "common seeds [8, 101]: DIFFER" in capsys.readouterr().out
