"""output.channel_rate_hz: thinned channel records, with the statistics that need every epoch computed
before thinning (/channels/Gnn attributes) -- the batch metrics of a thinned run equal those of the
full-rate run of the same recording, and the stored records respect the rate."""
from pathlib import Path

import h5py
import numpy as np
import pytest

from receiver.batch.metrics import compute_metrics
from receiver.config import load_receiver_config
from receiver.pipeline import run
from receiver.runfile.reader import RunFile
from receiver.sim.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("chrate")
    # PRN 6 loses its signal for 0.4 s: a loss of lock that thinning alone could miss or misplace
    paths = simulate(ROOT / "configs" / "scenarios" / "static_default.yaml", d / "c.bin",
                     [("time.duration_s", 2.5), ("constellation.prns", [1, 6, 9]), ("clock.noise", "none"),
                      ("blockage.outages", [{"prn": 6, "start_s": 1.4, "end_s": 1.8}])], progress=False)
    out = {}
    for name, rate in (("full", None), ("r50", 50.0)):
        cfg = load_receiver_config(paths["yaml"], [("output.path", str(d / f"{name}.h5")),
                                                   ("navigation.enabled", False),
                                                   ("output.channel_rate_hz", rate)])
        run(cfg, quiet=True, log=lambda *a: None)
        out[name] = d / f"{name}.h5"
    return out


def test_thinned_records_and_exact_statistics(runs):
    with h5py.File(runs["full"]) as f, h5py.File(runs["r50"]) as g:
        assert f["channels"].attrs["channel_rate_hz"] == 0.0 and g["channels"].attrs["channel_rate_hz"] == 50.0
        assert set(f["channels"]) == set(g["channels"]) == {"G01", "G06", "G09"}
        for name in f["channels"]:
            a, b = f["channels"][name], g["channels"][name]
            t_full, t = a["time_s"][:], b["time_s"][:]
            # at most one record per 20 ms interval, each one a record of the full-rate run
            assert np.all(np.diff(np.floor(t * 50.0 + 1e-9)) >= 1)
            assert np.isin(b["sample_index"][:], a["sample_index"][:]).all()
            assert len(t) < len(t_full) / 10
            # the statistics attributes are the same in both files and match the full-rate records
            for k in ("epochs", "epochs_locked", "lock_losses", "dropped"):
                assert a.attrs[k] == b.attrs[k], (name, k)
            lock = a["pll_lock"][:] > 0
            assert a.attrs["epochs"] == len(t_full) and a.attrs["epochs_locked"] == lock.sum()
            assert a.attrs["lock_losses"] == np.count_nonzero(np.diff(lock.astype(int)) == -1)
            assert b.attrs["cn0_locked_mean_dbhz"] == pytest.approx(np.mean(a["cn0_dbhz"][:][lock]), abs=1e-3)
        assert f["channels/G06"].attrs["lock_losses"] >= 1          # the outage was seen


def test_metrics_and_reader_on_a_thinned_file(runs):
    mf, mt = compute_metrics(runs["full"]), compute_metrics(runs["r50"])
    for k in ("loss_of_lock", "channels_dropped", "n_channels_locked"):
        assert mf[k] == mt[k], k
    assert mt["cn0_mean_dbhz"] == pytest.approx(mf["cn0_mean_dbhz"], abs=1e-3)
    with RunFile(runs["r50"]) as rf:
        ch = rf.channel("G01", ("time_s", "cn0_dbhz"))
        assert 100 <= len(ch["time_s"]) <= 126
