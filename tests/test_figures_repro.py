"""The paper figures are reproducible: the same seed gives the same numbers for any number of parallel jobs,
and figures-check compares against its reference with the stated tolerances."""
import importlib.util
import json
import os
import subprocess
import sys

ROOT = os.path.join(os.path.dirname(__file__), "..")


def _load(name):
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, "scripts", f"{name}.py"))
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
        subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "figures_carrier.py"), "--out", str(out),
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
