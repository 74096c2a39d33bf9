"""output.channel_rate_hz: thinned channel records, with the statistics that need every epoch computed
before thinning (/channels/Gnn attributes).  Two writers get the same stream of channel-epoch records
(chunks of 500 epochs, 1-ms epochs then 20-ms ones after bit sync, lock lost for 150 ms and a short
10-ms unlock that thinning alone would miss); the batch metrics of the thinned file equal those of the
full-rate file; the pipeline passes the key to the writer."""
import numpy as np
import pytest

from receiver.batch.metrics import compute_metrics
from receiver.runfile.reader import RunFile
from receiver.runfile.record import EPOCH_DTYPE, STATE_BIT_SYNC, STATE_LOST, STATE_TRACK
from receiver.runfile.writer import RunWriter


def _records(n_ms=3000, unlock=((800, 950), (1505, 1515)), lost_after=None, seed=0):
    rng = np.random.default_rng(seed)
    t = np.concatenate([np.arange(0, 2000) * 1e-3, 2.0 + np.arange(0, (n_ms - 2000) // 20) * 20e-3])
    r = np.zeros(len(t), EPOCH_DTYPE)
    r["time_s"] = t
    r["sample_index"] = np.round(t * 2.6e6).astype(np.int64)
    r["cn0_dbhz"] = 40 + rng.standard_normal(len(t)).astype(np.float32)
    r["pll_lock"] = 1
    r["state"] = np.where(t < 2.0, STATE_TRACK, STATE_BIT_SYNC)
    r["integration_ms"] = np.where(t < 2.0, 1, 20)
    r["pll_lock"][:100] = 0                                 # pull-in
    for a, b in unlock:
        r["pll_lock"][a:b] = 0
    if lost_after is not None:
        r["state"][t >= lost_after] = STATE_LOST
        r["pll_lock"][t >= lost_after] = 0
    return r


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("chrate")
    recs = {1: _records(), 6: _records(lost_after=2.5, seed=1), 9: _records(unlock=(), seed=2)}
    out = {}
    for name, rate in (("full", None), ("r50", 50.0)):
        w = RunWriter(d / f"{name}.h5", "{}", {"sample_rate_hz": 2.6e6}, channel_rate_hz=rate)
        for k in range(0, 3000, 500):                       # the pipeline's chunk-by-chunk appends
            for prn, r in recs.items():
                w.append_channel(prn, r[k:k + 500])
        w.close()
        out[name] = d / f"{name}.h5"
    return out, recs


def test_thinned_records_and_exact_statistics(files):
    import h5py
    out, recs = files
    with h5py.File(out["full"]) as f, h5py.File(out["r50"]) as g:
        assert f["channels"].attrs["channel_rate_hz"] == 0.0 and g["channels"].attrs["channel_rate_hz"] == 50.0
        for prn, r in recs.items():
            a, b = f["channels"][f"G{prn:02d}"], g["channels"][f"G{prn:02d}"]
            t = b["time_s"][:]
            assert np.array_equal(a["time_s"][:], r["time_s"])           # full rate: every epoch
            # one record per 20-ms interval: the first epoch of each (every 20th 1-ms epoch, then each 20-ms one)
            assert np.all(np.diff(np.floor(t * 50.0 + 1e-9)) == 1)
            assert np.isin(b["sample_index"][:], r["sample_index"]).all() and len(t) == 100 + 50
            lock = r["pll_lock"] > 0
            want = {"epochs": len(r), "epochs_locked": lock.sum(),
                    "lock_losses": np.count_nonzero(np.diff(lock.astype(int)) == -1),
                    "dropped": bool(np.any(r["state"] == STATE_LOST))}
            for k, v in want.items():
                assert a.attrs[k] == v and b.attrs[k] == v, (prn, k, a.attrs[k], b.attrs[k], v)
            assert b.attrs["cn0_locked_mean_dbhz"] == pytest.approx(np.mean(r["cn0_dbhz"][lock]), abs=1e-4)
        # G01's 10-ms unlock falls between two stored records: only the statistics know it
        assert g["channels/G01"].attrs["lock_losses"] == 2
        stored = g["channels/G01/pll_lock"][:]
        assert np.count_nonzero(np.diff((stored > 0).astype(int)) == -1) == 1


def test_metrics_and_reader_on_a_thinned_file(files):
    out, _ = files
    mf, mt = compute_metrics(out["full"]), compute_metrics(out["r50"])
    for k in ("loss_of_lock", "channels_dropped", "n_channels_locked"):
        assert mf[k] == mt[k], k
    assert mf["loss_of_lock"] == 2 + 3 + 0 and mf["channels_dropped"] == 1     # G06 also at its loss
    assert mt["cn0_mean_dbhz"] == pytest.approx(mf["cn0_mean_dbhz"], abs=1e-4)
    with RunFile(out["r50"]) as rf:
        assert len(rf.channel("G09", ("time_s",))["time_s"]) == 150


def test_pipeline_passes_the_rate_to_the_writer(tmp_path, monkeypatch):
    import receiver.pipeline as pl
    from receiver.schema import load_receiver_config
    seen = {}

    class Stop(Exception):
        pass

    def fake_writer(*a, **k):
        seen.update(k)
        raise Stop
    monkeypatch.setattr(pl, "RunWriter", fake_writer)
    x = tmp_path / "x.bin"
    x.write_bytes(b"\0" * 2 * 26000)
    cfg = load_receiver_config(None, [("input.path", str(x)), ("output.path", str(tmp_path / "o.h5")),
                                      ("output.channel_rate_hz", 25.0)])
    with pytest.raises(Stop):
        pl.run(cfg, quiet=True)
    assert seen["channel_rate_hz"] == 25.0
