"""Compact run files (issue 18): the channel columns stored rounded by the HDF5 scale-offset filter
(receiver/runfile/writer.py ROUNDED_DIGITS) come back within half their resolution as float64, every other
column exactly, non-finite values survive; on the reference recording each rounded column's resolution is
far below its noise, and the default run file is at most half the 50.0 MB it took when the issue was
filed."""
import os

import h5py
import numpy as np
import pytest

from receiver.runfile.reader import RunFile
from receiver.runfile.record import EPOCH_DTYPE, FIX_DTYPE
from receiver.runfile.writer import ROUNDED_DIGITS, SCHEMA, RunWriter


def _records(n, seed):
    rng = np.random.default_rng(seed)
    r = np.zeros(n, EPOCH_DTYPE)
    for name in EPOCH_DTYPE.names:
        kind = r[name].dtype.kind
        r[name] = rng.integers(0, 3, n) if kind == "u" else (np.arange(n) if kind == "i" else rng.normal(0, 1e3, n))
    r["time_s"] = np.arange(n) * 1e-3
    r["code_rate_hz"] = 1.023e6 + rng.normal(0, 1.0, n)
    r["code_phase_chips"] = rng.uniform(0, 0.4, n)
    return r


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    d = tmp_path_factory.mktemp("storage")
    recs = {3: _records(40000, 1), 7: _records(5000, 2)}
    recs[7]["doppler_hz"][100] = np.nan                     # a diverged loop's record
    recs[7]["code_rate_hz"][200] = np.inf
    recs[3]["doppler_hz"][30000] = np.nan                   # ... after 16384 rounded rows
    fixes = np.zeros(30, FIX_DTYPE)
    fixes["time_s"] = np.arange(30) * 0.1
    out = {}
    for name, rounded in (("rounded", True), ("exact", False)):
        w = RunWriter(d / f"{name}.h5", "{}", {"sample_rate_hz": 2.6e6}, compression="gzip",
                      round_columns=rounded)
        for k in range(0, 40000, 500):                      # the pipeline's chunk-by-chunk appends
            for prn, r in recs.items():
                w.append_channel(prn, r[k:k + 500])
            w.append_fixes(fixes[k // 500:k // 500 + 1] if k // 500 < 30 else fixes[:0])
        w.close()
        out[name] = d / f"{name}.h5"
    return out, recs, fixes


@pytest.mark.slow
def test_rounded_columns_within_one_step(written):
    out, recs, fixes = written
    with h5py.File(out["rounded"]) as f, h5py.File(out["exact"]) as g:
        assert f.attrs["schema"] == SCHEMA and g.attrs["schema"] == "gnssrx-run-1"
        for prn, r in recs.items():
            a, b = f[f"channels/G{prn:02d}"], g[f"channels/G{prn:02d}"]
            for name in EPOCH_DTYPE.names:
                v, want = a[name][:], r[name]
                assert v.dtype == want.dtype, name
                assert np.array_equal(b[name][:], want, equal_nan=want.dtype.kind == "f"), name
                if "resolution" not in a[name].attrs:
                    assert np.array_equal(v, want, equal_nan=want.dtype.kind == "f"), name
                    continue
                res = 10.0 ** -ROUNDED_DIGITS[name]
                assert a[name].attrs["resolution"] == res
                fin = np.isfinite(want)
                assert np.array_equal(np.isnan(v), np.isnan(want)) and np.array_equal(np.isinf(v), np.isinf(want))
                # the filter's decimal scaling rounds (x - chunk minimum) * 10**N: error below one step
                err = np.abs(v[fin] - want[fin])
                assert err.max() <= res, (name, err.max() / res)
                assert np.mean(err[:16384]) > 0.1 * res, name        # really rounded (not stored exactly)
        # a NaN in a later block: that column is stored exactly from then on (rows before stay rounded)
        d3 = f["channels/G03/doppler_hz"]
        assert d3.scaleoffset is None and np.isnan(d3[30000]) and d3[30001] == recs[3]["doppler_hz"][30001]
        # NaN / Inf in the first block: stored exactly from the start
        for name in ("doppler_hz", "code_rate_hz"):
            assert "resolution" not in f["channels/G07"][name].attrs
        assert f["channels/G07/code_phase_chips"].scaleoffset == ROUNDED_DIGITS["code_phase_chips"]
        # buffered tables are all there, in order
        assert np.array_equal(f["navigation/time_s"][:], fixes["time_s"])
    with RunFile(out["rounded"]) as rf:                      # the reader reads them as before
        ch = rf.channel("G03", ("doppler_hz", "time_s"))
        assert ch["doppler_hz"].dtype == np.float64 and len(ch["time_s"]) == 40000


@pytest.fixture(scope="module")
def tokyo_columns(tokyo_run):
    cols = {}
    with h5py.File(tokyo_run) as f:
        for name, g in f["channels"].items():
            lock = (g["pll_lock"][:] > 0) & (g["state"][:] == 2)
            if lock.sum() < 5000:
                continue
            cols[name] = {k: g[k][:][lock] for k in ("doppler_hz", "code_rate_hz", "code_err_chips")}
            cols[name]["res"] = {k: g[k].attrs["resolution"] for k in ROUNDED_DIGITS}
    assert len(cols) >= 6
    return cols


def _scatter(x):
    """Epoch-to-epoch scatter of a slowly varying quantity: robust standard deviation of the first
    differences divided by sqrt(2) (the true change over 20 ms is far smaller for a static receiver)."""
    d = np.diff(x)
    return 1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2)


def test_resolution_far_below_the_noise_on_the_reference_run(tokyo_columns):
    """Rounding error (uniform, std = resolution / sqrt(12)) at least 100x below each column's noise:
    doppler_hz against the carrier NCO's epoch-to-epoch scatter, code_rate_hz against the code NCO's,
    code_phase_chips against the code discriminator's scatter (the DLL's measurement noise)."""
    for name, c in tokyo_columns.items():
        res = c["res"]
        noise = {"doppler_hz": _scatter(c["doppler_hz"]), "code_rate_hz": _scatter(c["code_rate_hz"]),
                 "code_phase_chips": float(np.std(c["code_err_chips"]))}
        for k, n in noise.items():
            assert res[k] / np.sqrt(12) < n / 100, (name, k, res[k], n)


def test_reference_run_file_at_most_25_mb(tokyo_run):
    """Default output settings (every epoch, gzip, rounded columns): the run file of the 43.9-s reference
    recording (10 channels) was 50.0 MB uncompressed when issue 18 was filed; at most half of that."""
    with h5py.File(tokyo_run) as f:
        assert f["channels"].attrs["channel_rate_hz"] == 0.0 and f.attrs["schema"] == SCHEMA
        assert sum(g["time_s"].shape[0] for g in f["channels"].values()) > 400_000     # every epoch stored
    assert os.path.getsize(tokyo_run) <= 25.0e6


def test_fix_iono_params_column_reads_back_and_old_files_read_unknown(tmp_path):
    """/navigation/iono_params (which Klobuchar set each fix used) is written and read back with its mapping;
    a run file written before the column existed reads IONO_UNKNOWN, not 'none'."""
    from receiver.runfile.record import IONO_BROADCAST, IONO_FALLBACK, IONO_NONE, IONO_UNKNOWN
    fixes = np.zeros(5, FIX_DTYPE)
    fixes["time_s"] = np.arange(5) * 0.1
    fixes["iono_params"] = [IONO_FALLBACK, IONO_FALLBACK, IONO_BROADCAST, IONO_BROADCAST, IONO_NONE]
    w = RunWriter(tmp_path / "new.h5", "{}", {"sample_rate_hz": 2.6e6})
    w.append_fixes(fixes[:2])
    w.append_fixes(fixes[2:])
    w.close()
    with RunFile(tmp_path / "new.h5") as rf:
        assert np.array_equal(rf.fixes(), fixes)
        assert rf.group_attrs("navigation")["iono_params_mapping"] == "0=none,1=broadcast,2=fallback"
    with h5py.File(tmp_path / "new.h5", "a") as f:
        del f["navigation/iono_params"]
    with RunFile(tmp_path / "new.h5") as rf:
        old = rf.fixes()
    assert np.all(old["iono_params"] == IONO_UNKNOWN) and np.array_equal(old["time_s"], fixes["time_s"])


def test_short_runs_get_small_chunks_and_read_back_alike(tmp_path):
    """The pipeline sizes the chunks from the run's duration (writer.chunk_rows_for): a 1-s run's datasets
    hold one 2048-row chunk each, not a 16384-row one padded with fill; the values read back as with the
    default chunks (rounded columns within half a step, the others exact, a NaN after the first chunks
    kept)."""
    from receiver.runfile.writer import CHUNK_ROWS, chunk_rows_for
    assert chunk_rows_for(1.0) == 2048 and chunk_rows_for(0.5) == 1024
    assert chunk_rows_for(10.0) == 16384 and chunk_rows_for(3600.0) == CHUNK_ROWS == chunk_rows_for(None)
    assert chunk_rows_for(60.0, channel_rate_hz=50.0) == 4096     # 3000 stored records per channel
    r = _records(3000, 3)
    r["doppler_hz"][2500] = np.nan
    w = RunWriter(tmp_path / "short.h5", "{}", {"sample_rate_hz": 2.6e6}, compression="gzip", chunk_rows=1024)
    for k in range(0, 3000, 500):
        w.append_channel(5, r[k:k + 500])
    w.close()
    with h5py.File(tmp_path / "short.h5") as f:
        g = f["channels/G05"]
        for name in EPOCH_DTYPE.names:
            assert g[name].chunks == (1024,), name
            v = g[name][:]
            if name in ROUNDED_DIGITS:
                ok = np.isfinite(r[name])
                assert np.all(np.abs(v[ok] - r[name][ok]) <= 0.5 * 10.0 ** -ROUNDED_DIGITS[name] * 1.0001), name
                assert np.isnan(v[2500]) if name == "doppler_hz" else True
            else:
                assert np.array_equal(v, r[name], equal_nan=True), name


def test_rows_kept_after_a_flush_do_not_hold_the_written_rows(tmp_path):
    """A flush writes whole chunks and keeps the rest buffered; the rest is its own array, not a view of the
    concatenation of everything buffered (which would keep up to a chunk of rows per channel alive twice:
    ~20 MB of a 10-channel run's peak memory), and the file holds every row once, in order."""
    r = _records(2500, 4)
    w = RunWriter(tmp_path / "keep.h5", "{}", {"sample_rate_hz": 2.6e6}, compression="gzip", chunk_rows=1024)
    for k in range(0, 2500, 300):
        w.append_channel(7, r[k:k + 300].copy())
        for kept in w._buffers.get(7, []):
            assert kept.base is None or len(kept.base) == len(kept), "the rows kept are a view of a larger array"
    assert sum(len(b) for b in w._buffers[7]) == 2500 - 2048
    w.close()
    with h5py.File(tmp_path / "keep.h5") as f:
        assert np.array_equal(f["channels/G07/sample_index"][:], r["sample_index"])


def test_cpu_attribute_names_the_compiled_kernels_target(monkeypatch):
    """The run file's ``cpu`` attribute names the CPU numba compiles for: NUMBA_CPU_NAME when set, else the
    host CPU as LLVM names it (the kernels' instructions, hence the last digits of results, depend on it)."""
    import llvmlite.binding as llvm

    from receiver.runfile.provenance import cpu_target, provenance
    monkeypatch.setenv("NUMBA_CPU_NAME", "generic")
    assert cpu_target().startswith("generic (NUMBA_CPU_NAME)")
    monkeypatch.delenv("NUMBA_CPU_NAME")
    assert cpu_target().startswith(f"{llvm.get_host_cpu_name()} (host)")
    assert provenance(__file__)["cpu"] == cpu_target()


def test_provenance_computed_on_a_thread_is_the_same(tmp_path):
    """The pipeline starts the provenance attributes (package versions, git commit: subprocesses) on a
    thread while the input opens: the same attributes as computed in line."""
    from receiver.runfile.provenance import HASH_BYTES, provenance, provenance_async
    f = tmp_path / "x.bin"
    f.write_bytes(bytes(range(256)) * (HASH_BYTES // 128))
    later = provenance_async()
    want = provenance(f)
    assert later(f) == want and want["input_size_bytes"] == 2 * HASH_BYTES
