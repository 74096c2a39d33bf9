"""End to end: configs/batch/ci_small.yaml (2 PLL bandwidths x 2 short simulated scenarios, assisted) on the
local process pool, the cache, a Dask LocalCluster (identical metrics), and resuming an interrupted batch.

The recordings are simulated once into a shared cache directory (keep_recordings on for the first runs; the
resume test switches it off and checks that the IF files are deleted at the end)."""
import csv
import os
import math
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from receiver.batch.compare import compare, read_summary
from receiver.batch.metrics import METRIC_KEYS, TIMING_KEYS
from receiver.batch.runner import run_batch

from repo_paths import ROOT
CI = ROOT / "configs" / "batch" / "ci_small.yaml"
FINITE = ("ttff_s", "pos_3d_rms_m", "pos_3d_max_m", "pos_h_rms_m", "pos_v_rms_m", "vel_3d_rms_mps",
          "carrier_phase_err_std_cyc", "carrier_disc_std_cyc", "cn0_mean_dbhz", "run_wall_s", "realtime_factor",
          "loss_of_lock", "n_channels_locked")


@pytest.fixture(scope="module")
def dirs(tmp_path_factory):
    base = tmp_path_factory.mktemp("batch")
    return {"rec": base / "recordings", "pool": base / "pool", "dask": base / "dask", "resume": base / "resume"}


def _over(dirs, out, keep=True):
    # a fixed code version: edits of the receiver sources during the test session must not invalidate the cache
    return [("output_dir", str(dirs[out])), ("recordings_dir", str(dirs["rec"])), ("keep_recordings", keep),
            ("code_version", "test-session")]


@pytest.fixture(scope="module")
def pool_run(dirs):
    return run_batch(CI, _over(dirs, "pool"), jobs=2)


def _metrics(rows):
    """Comparable metrics: NaN (metrics that do not apply, e.g. the outage ones) as the string 'nan'."""
    def v(x):
        return "nan" if isinstance(x, float) and math.isnan(x) else x
    return {r["run_id"]: {k: v(r[k]) for k in METRIC_KEYS if k not in TIMING_KEYS} for r in rows}


@pytest.mark.slow
def test_ci_small_summary(pool_run, dirs):
    res = pool_run
    assert (res.n_runs, res.executed, res.cached, res.failed, res.simulated) == (4, 4, 0, 0, 2)
    assert res.executor == "local 2 jobs"
    with open(res.summary_csv) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4
    assert sorted((r["variant"], r["input"]) for r in rows) == [
        ("pll15", "cv"), ("pll15", "static"), ("pll25", "cv"), ("pll25", "static")]
    for r in rows:
        assert r["status"] == "ok" and r["seed"] == "1" and r["error"] == ""
        for k in FINITE:
            assert math.isfinite(float(r[k])), (k, r[k])
        assert 1.0 <= float(r["ttff_s"]) <= 3.0                  # assisted: fixes within ~2 s
        assert float(r["pos_3d_rms_m"]) < 15.0
        assert float(r["carrier_phase_err_std_cyc"]) < 0.05
        assert (Path(res.output_dir) / r["run_file"]).is_file()
    assert {r["tracking.pll_bw_hz"] for r in rows} == {"15.0", "25.0"}
    with open(res.groups_csv) as fh:
        groups = list(csv.DictReader(fh))
    assert [g["variant"] for g in groups] == ["pll15", "pll25"]
    assert all(g["n_ok"] == "2" and math.isfinite(float(g["pos_3d_rms_m_mean"])) for g in groups)
    with h5py.File(res.summary_h5, "r") as f:
        assert f.attrs["n_runs"] == 4 and f["runs/pos_3d_rms_m"].shape == (4,)
        assert f["groups/variant"].shape == (2,)
        assert "pll_bw_hz" in f["runs/config_yaml"][0].decode()
    recs = list(dirs["rec"].glob("*.bin"))
    assert len(recs) == 2 and len(list(dirs["rec"].glob("*.nav"))) == 2      # kept (keep_recordings on)


@pytest.mark.slow
def test_rerun_is_cached(pool_run, dirs):
    again = run_batch(CI, _over(dirs, "pool"), jobs=2)
    assert (again.executed, again.cached, again.simulated) == (0, 4, 0)     # nothing run again
    assert _metrics(again.rows) == _metrics(pool_run.rows)


@pytest.mark.slow
def test_dask_local_cluster_gives_identical_metrics(pool_run, dirs):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        res = run_batch(CI, _over(dirs, "dask"), client=client)
    assert (res.executed, res.simulated, res.failed) == (4, 0, 0)
    assert res.executor.startswith("dask")
    assert _metrics(res.rows) == _metrics(pool_run.rows)


@pytest.mark.slow
def test_compare_by_config_key(pool_run, tmp_path):
    png = tmp_path / "cmp.png"
    table, groups, path = compare(pool_run.summary_h5, ["tracking.pll_bw_hz"], plot=str(png))
    assert [g["tracking.pll_bw_hz"] for g in groups] == [15.0, 25.0]
    assert "pos_3d_rms_m" in table and "2 / 2" in table
    assert png.stat().st_size > 5000
    _t, g2, _p = compare(pool_run.summary_h5, ["vector.variant"])      # a key only in the stored configs
    assert len(g2) == 1 and g2[0]["n_runs"] == 4
    rows, _attrs = read_summary(pool_run.summary_h5)
    assert len(rows) == 4


@pytest.mark.slow
def test_resume_runs_only_the_missing(pool_run, dirs):
    """An interrupted batch (simulated: two runs' results removed, one stale partial file) completes only
    those two; with keep_recordings off the IF files are deleted afterwards."""
    shutil.copytree(dirs["pool"], dirs["resume"])
    runs = dirs["resume"] / "runs"
    victims = sorted(p.stem for p in runs.glob("*.json"))[:2]
    (runs / f"{victims[0]}.json").unlink()                  # finished h5, no result record
    (runs / f"{victims[1]}.json").unlink()
    (runs / f"{victims[1]}.h5").rename(runs / f"{victims[1]}.h5.partial")     # killed while writing
    res = run_batch(CI, _over(dirs, "resume", keep=False), jobs=2)
    assert (res.executed, res.cached, res.simulated, res.failed) == (2, 2, 0, 0)
    assert {r["run_id"] for r in res.rows if r["executed"]} == set(victims)
    assert not list(runs.glob("*.partial"))
    assert _metrics(res.rows) == _metrics(pool_run.rows)
    assert not list(dirs["rec"].glob("*.bin"))              # deleted: no run needs them any more
    assert len(list(dirs["rec"].glob("*.truth.h5"))) == 2   # truth kept for the metrics
    final = run_batch(CI, _over(dirs, "resume", keep=False), jobs=2)
    assert (final.executed, final.cached) == (0, 4)
    assert np.all([r["status"] == "ok" for r in final.rows])


def test_stale_partials_are_removed_but_not_those_another_batch_is_writing(tmp_path):
    """A batch starting in a directory removes the *.partial run files of interrupted runs, not those whose
    lock names a live writer (two batch invocations into one output directory lost each other's runs)."""
    import subprocess
    import sys
    from receiver.batch.runner import remove_stale_partials
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    for key, pid in (("live", os.getpid()), ("dead", dead.pid), ("nolock", None)):
        (tmp_path / f"{key}.h5.partial").write_bytes(b"x")
        if pid is not None:
            (tmp_path / f"{key}.h5.lock").write_text(f"{pid}\n")
    assert remove_stale_partials(tmp_path) == 2
    assert sorted(p.name for p in tmp_path.glob("*.partial")) == ["live.h5.partial"]
