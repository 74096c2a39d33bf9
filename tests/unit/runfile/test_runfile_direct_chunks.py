"""The run writer compresses whole chunks itself (shuffle + deflate, zlib outside the GIL) and writes them
with H5Dwrite_chunk (receiver/runfile/writer.py _gzip_chunk): the stored chunk must be what HDF5's own
filter pipeline stores (same filters, same byte layout), every reader gets the values back, and appends
after a partly filled chunk (the last one) still go through h5py."""
import zlib

import h5py
import numpy as np

from receiver.runfile.writer import COMPRESSION, _append, _gzip_chunk


def test_chunk_bytes_are_those_of_the_hdf5_filters(tmp_path):
    rng = np.random.default_rng(5)
    rows = 64
    cols = {"f8": rng.normal(0, 1e3, 50), "f4": rng.normal(0, 1, 50).astype("f4"),
            "i8": rng.integers(-10**12, 10**12, 50), "u1": rng.integers(0, 3, 50).astype("u1"),
            "v3": rng.normal(0, 1e6, (50, 3))}
    with h5py.File(tmp_path / "x.h5", "w") as f:
        for name, a in cols.items():
            ds = f.create_dataset(name, data=a, maxshape=(None,) + a.shape[1:], chunks=(rows,) + a.shape[1:],
                                  **COMPRESSION["gzip"])            # HDF5's pipeline (partial chunk: fill 0)
            f.flush()
            mask, stored = ds.id.read_direct_chunk((0,) * a.ndim)
            assert mask == 0
            assert zlib.decompress(stored) == zlib.decompress(_gzip_chunk(a, rows))


def test_direct_appends_read_back_exactly(tmp_path):
    rng = np.random.default_rng(6)
    rows = 32
    a = rng.normal(0, 1, 100).astype("f4")
    a[40] = np.nan
    v = rng.normal(0, 1e6, (100, 3))
    with h5py.File(tmp_path / "y.h5", "w") as f:
        g = f.create_group("g")
        _append(g, "a", a[:64], "gzip", rows=rows)            # two whole chunks: the direct path
        _append(g, "a", a[64:70], "gzip", rows=rows)          # a partial chunk (direct, padded)
        _append(g, "a", a[70:], "gzip", rows=rows)            # unaligned: h5py merges into that chunk
        _append(g, "v", v[:96], "gzip", rows=rows)
        _append(g, "v", v[96:], "gzip", rows=rows)
        assert g["a"].compression == "gzip" and g["a"].shuffle and g["a"].chunks == (rows,)
    with h5py.File(tmp_path / "y.h5", "r") as f:
        np.testing.assert_array_equal(f["g/a"][:], a)
        np.testing.assert_array_equal(f["g/v"][:], v)
