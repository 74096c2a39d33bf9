"""The run writer creates its datasets and scalar attributes through h5py's low-level API with property lists
and types built once (receiver/runfile/writer.py _create, _dcpl, _set_attrs): every dataset must have the
creation properties (H5Pequal: chunks, filters and their order, fill value and time, allocation time,
creation times, attribute order), HDF5 type and values of the one h5py's ``create_dataset`` makes with the
same settings, and every attribute the type and value of h5py's ``attrs[k] = v``."""
import h5py
import numpy as np
import pytest
from h5py import h5a, h5o

from receiver.runfile.record import EPOCH_DTYPE, FIX_DTYPE
from receiver.runfile.writer import COMPRESSION, _append, _set_attrs


def _reference(g, name, data, compression, digits, rows):
    """The dataset as h5py's high-level API makes it (the writer's settings before the low-level path)."""
    if digits is not None:
        kw = {"scaleoffset": digits, **{k: v for k, v in COMPRESSION[compression].items() if k != "shuffle"}}
    else:
        kw = COMPRESSION[compression]
    return g.create_dataset(name, data=data, maxshape=(None,) + data.shape[1:], chunks=(rows,) + data.shape[1:],
                            **kw)


def _columns():
    rng = np.random.default_rng(11)
    cols = []
    for tag, dt in (("e", EPOCH_DTYPE), ("f", FIX_DTYPE)):
        r = np.zeros(300, dt)
        for name in dt.names:
            a = r[name]
            a[...] = rng.normal(0, 1e3, a.shape) if a.dtype.kind == "f" else rng.integers(0, 3, a.shape)
            cols.append((f"{tag}_{name}", np.ascontiguousarray(a)))
    cols.append(("flag", rng.integers(0, 2, 300).astype(bool)))
    return cols


@pytest.mark.parametrize("compression", ["gzip", "lzf", "none"])
def test_datasets_equal_to_h5py_high_level(tmp_path, compression):
    rows = 128
    keys = []
    with h5py.File(tmp_path / "x.h5", "w") as f:
        lo, hi = f.create_group("lo"), f.create_group("hi")
        for name, col in _columns():
            for digits in ((None, 3) if col.dtype.kind == "f" and col.ndim == 1 else (None,)):
                key = f"{name}_{digits}"
                cache = {}
                _append(lo, key, col[:256], compression, digits, rows=rows, cache=cache)  # new: 2 chunks
                _append(lo, key, col[256:], compression, digits, rows=rows, cache=cache)  # later append
                ref = _reference(hi, key, col, compression, digits, rows)
                if digits is not None:
                    ref.attrs["resolution"] = 10.0 ** -digits
                keys.append(key)
    assert len(keys) > 40
    with h5py.File(tmp_path / "x.h5", "r") as f:           # (an open dataset's plist differs from a re-opened one's)
        for key in keys:
            a, ref = f["lo"][key], f["hi"][key]
            assert a.id.get_create_plist().equal(ref.id.get_create_plist()), key
            assert a.id.get_type().equal(ref.id.get_type()), key
            assert a.shape == ref.shape and a.maxshape == ref.maxshape and a.chunks == ref.chunks, key
            assert (a.compression, a.shuffle, a.scaleoffset) == (ref.compression, ref.shuffle, ref.scaleoffset)
            assert h5o.get_info(a.id).ctime == 0, key                  # no creation times (h5py's default)
            assert a[:].tobytes() == ref[:].tobytes(), key
            assert dict(a.attrs) == dict(ref.attrs), key


def test_attributes_equal_to_h5py_high_level(tmp_path):
    vals = {"i": 7, "big": -(2 ** 62), "f": 0.1, "nan": float("nan"), "b": True, "nb": np.bool_(False),
            "f4": np.float32(1.5), "u1": np.uint8(200), "s": "0=pull_in,1=track", "e": "", "u": "ユニコード",
            "tuple": (1.0, 2.0), "arr": np.arange(3), "huge": 2 ** 70}
    with h5py.File(tmp_path / "a.h5", "w") as f:
        lo, hi = f.create_group("lo"), f.create_group("hi")
        for k, v in vals.items():
            if k != "huge":
                hi.attrs[k] = v
        with pytest.raises(TypeError):              # h5py's own error for an int beyond 64 bits
            _set_attrs(lo, {"huge": vals.pop("huge")})
        _set_attrs(lo, {"i": 1})                    # then replaced, like attrs[k] = v
        _set_attrs(lo, vals)
        for k in vals:
            x, y = h5a.open(lo.id, k.encode()), h5a.open(hi.id, k.encode())
            assert x.get_type().equal(y.get_type()) and x.shape == y.shape, k
            p, q = lo.attrs[k], hi.attrs[k]
            assert type(p) is type(q), k
            assert np.asarray(p).tobytes() == np.asarray(q).tobytes() if not isinstance(p, str) else p == q, k
