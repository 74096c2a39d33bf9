"""HDF5 storage helpers of the run-file writer (receiver.runfile.writer): compression filters, chunk sizes,
growing (appended) datasets written chunk by chunk -- pre-compressed chunks written directly --, the
scale-offset rounding of channel columns, and attributes of any supported type."""
from __future__ import annotations

import math
import zlib

import h5py
import numpy as np
from h5py import h5a, h5d, h5p, h5s, h5t, h5z

COMPRESSION = {"none": {}, "lzf": {"compression": "lzf", "shuffle": True},
               "gzip": {"compression": "gzip", "compression_opts": 4, "shuffle": True}}

#: rows per HDF5 chunk of the growing datasets; the writer flushes whole chunks (FLUSH_ROWS is a multiple),
#: so no chunk is compressed twice.  16384 rows: 22 % fewer chunks' overhead than 4096, better compression.
CHUNK_ROWS = 16384
#: the smallest chunk :func:`chunk_rows_for` chooses for a short run
MIN_CHUNK_ROWS = 1024


def chunk_rows_for(duration_s: float | None, channel_rate_hz: float | None = None) -> int:
    """Rows per chunk for a run of ``duration_s`` seconds of signal: the smallest power of two that holds
    every record one channel can write (at most one per millisecond, or per 1/channel_rate_hz), between
    MIN_CHUNK_ROWS and CHUNK_ROWS.  A short run's datasets then hold one small chunk each instead of a
    16384-row chunk padded with fill (compressed whole at close: ~0.35 s of CPU for the ~220 datasets of a
    1-s run, ~0.05 s with 1024-row chunks); runs longer than ~16 s keep CHUNK_ROWS."""
    if duration_s is None or not math.isfinite(duration_s) or duration_s <= 0:
        return CHUNK_ROWS
    per_s = min(1000.0, channel_rate_hz) if channel_rate_hz else 1000.0
    need = int(math.ceil(duration_s * per_s * 1.02)) + 64       # (a re-opened channel's overlap, rounding)
    rows = MIN_CHUNK_ROWS
    while rows < need and rows < CHUNK_ROWS:
        rows *= 2
    return rows

def _gzip_chunk(block: np.ndarray, rows: int) -> bytes:
    """One HDF5 chunk of ``rows`` rows through the shuffle + deflate filters of COMPRESSION["gzip"], as
    HDF5 would store it: the rows padded to a whole chunk with the fill value 0, the bytes of the
    elements regrouped by significance (shuffle; a no-op for 1-byte elements), zlib-compressed at the
    same level.  zlib releases the GIL while it compresses, so on the BackgroundWriter thread the
    compression overlaps the main thread (h5py's own filter pipeline runs with the GIL held)."""
    if len(block) < rows:
        pad = np.zeros((rows,) + block.shape[1:], block.dtype)
        pad[:len(block)] = block
        block = pad
    size = block.dtype.itemsize
    raw = np.ascontiguousarray(block).view(np.uint8).reshape(-1, size)
    if size > 1:
        raw = np.ascontiguousarray(raw.T)
    return zlib.compress(raw, COMPRESSION["gzip"]["compression_opts"])


def _direct(ds: h5py.Dataset) -> bool:
    """The dataset's filters are exactly shuffle + deflate at our level (written by :func:`_gzip_chunk`)."""
    return ds.compression == "gzip" and ds.shuffle and ds.scaleoffset is None and not ds.fletcher32 and \
        ds.compression_opts == COMPRESSION["gzip"]["compression_opts"]


#: dataset-creation property lists (chunk shape, filters) and HDF5 types (numpy dtype) built once per process
#: and reused for every dataset the writer creates (h5py's create_dataset builds both anew each time, ~1 ms a
#: dataset with the rest of its checks; a 1-s run creates ~220)
_DCPLS: dict = {}
_TYPES: dict = {}


def _dcpl(chunk: tuple, compression: str, digits, kind: str):
    """The dataset-creation property list h5py's ``create_dataset(chunks=chunk, maxshape=(None, ...),
    scaleoffset=digits, **COMPRESSION[compression])`` builds (h5py/_hl/filters.py fill_dcpl and
    dataset.py make_new_dset: chunk, scale-offset, shuffle, deflate or LZF in that order, no creation
    times, attribute creation order per h5py's track_order setting; fill value and times HDF5's defaults).
    tests/unit/runfile/test_runfile_lowlevel.py checks it equals h5py's (H5Pequal)."""
    track_order = bool(h5py.get_config().track_order)
    key = (chunk, compression, digits, kind, track_order)
    p = _DCPLS.get(key)
    if p is None:
        kw = COMPRESSION[compression]
        p = h5p.create(h5p.DATASET_CREATE)
        p.set_chunk(chunk)
        if digits is not None:
            if kind in "ui":
                p.set_scaleoffset(h5z.SO_INT, int(digits))
            else:
                p.set_scaleoffset(h5z.SO_FLOAT_DSCALE, int(digits))
        if kw.get("shuffle") and digits is None:
            p.set_shuffle()
        if kw.get("compression") == "gzip":
            p.set_deflate(kw["compression_opts"])
        elif kw.get("compression") == "lzf":
            p.set_filter(h5z.FILTER_LZF, h5z.FLAG_OPTIONAL)
        elif kw.get("compression") is not None:
            raise ValueError(f"compression {compression!r}")
        p.set_obj_track_times(False)
        p.set_attr_creation_order(h5p.CRT_ORDER_TRACKED | h5p.CRT_ORDER_INDEXED if track_order else 0)
        _DCPLS[key] = p
    return p


def _h5type(dtype: np.dtype):
    t = _TYPES.get(dtype)
    if t is None:
        t = _TYPES[dtype] = h5t.py_create(dtype, logical=1)
    return t


def _exists(group: h5py.Group, name: str) -> bool:
    """``name in group`` for a plain name (no path): H5Lexists, ~4x cheaper than h5py's check."""
    return group.id.links.exists(name.encode("ascii"))


def _create(group: h5py.Group, name: str, data: np.ndarray, rows: int, compression: str, digits, write: bool):
    """A new growing dataset group[name] of ``len(data)`` rows (maxshape (None,) + data.shape[1:], chunks of
    ``rows`` rows, the filters of ``compression`` / scale-offset ``digits``): what ``group.create_dataset``
    makes, through h5py's low-level API with the cached property list and type.  ``write``: store ``data``
    through HDF5's filters (else the caller writes whole chunks directly).  Returns the low-level id."""
    tail = data.shape[1:]
    space = h5s.create_simple((len(data),) + tail, (h5s.UNLIMITED,) + tail)
    dsid = h5d.create(group.id, name.encode("ascii"), _h5type(data.dtype), space,
                      dcpl=_dcpl((rows,) + tail, compression, digits, data.dtype.kind))
    if write:
        dsid.write(h5s.ALL, h5s.ALL, np.ascontiguousarray(data))
    return dsid


_STR = h5t.string_dtype()        # h5py's type for a str attribute (variable-length UTF-8)
_SCALAR_TYPES = (bool, int, float, str, np.bool_, np.integer, np.floating)
_ATTR_TYPES: dict = {}


def _set_attrs(obj, attrs: dict):
    """``obj.attrs[k] = v`` for every item (``obj``: an h5py File, Group or Dataset, or a low-level dataset
    id): a scalar (bool, int, float, str, numpy number) through h5py's low-level calls with types built
    once (the calls h5py's AttributeManager.create makes: the same attribute type and value, ~2x faster),
    anything else through h5py."""
    if isinstance(obj, h5d.DatasetID):           # a low-level dataset id (no h5py.Dataset made unless needed)
        oid, obj = obj, None
    else:
        oid = obj.id
    for k, v in attrs.items():
        if not isinstance(v, _SCALAR_TYPES) or not k.isascii() or (isinstance(v, str) and type(v) is not str):
            (obj if obj is not None else h5py.Dataset(oid)).attrs[k] = v
            continue
        if isinstance(v, str):
            dt = _STR
            data = np.asarray(v, order="C", dtype=dt).view(dt)
        else:
            data = np.asarray(v, order="C")
            dt = data.dtype
            if dt.kind not in "biuf":        # (an int beyond 64 bits: h5py's error)
                (obj if obj is not None else h5py.Dataset(oid)).attrs[k] = v
                continue
        key = "str" if dt is _STR else dt          # (_STR == dtype("O") as a dict key)
        types = _ATTR_TYPES.get(key)
        if types is None:
            types = _ATTR_TYPES[key] = (h5t.py_create(dt, logical=True), h5t.py_create(dt), h5s.create_simple(()))
        name = k.encode("ascii")
        if h5a.exists(oid, name):
            h5a.delete(oid, name)
        a = h5a.create(oid, name, types[0], types[2])
        try:
            a.write(data, mtype=types[1])
        except BaseException:
            a.close()
            h5a.delete(oid, name)
            raise
        a.close()


def _append(group: h5py.Group, name: str, data: np.ndarray, compression: str = "none", digits=None,
            rows: int = CHUNK_ROWS, cache: dict | None = None, chunks: list | None = None):
    """Append ``data`` to group[name] (created on the first call).  ``cache``: a dict the caller keeps per
    group, name -> [low-level dataset id, rows], for the datasets written by whole compressed chunks
    (saves the h5py look-ups of every later append; those writes bypass HDF5's chunk cache).  The other
    datasets are opened per call: closing one flushes its chunk cache through the filters (what the
    scale-offset columns rely on).  ``chunks``: ``data``'s chunks already compressed by :func:`_gzip_chunk`
    (used on the direct path), or a callable returning them (called once the dataset exists: the chunks
    may still be being compressed on another thread meanwhile)."""
    hit = cache.get(name) if cache is not None else None
    if digits is not None and not np.isfinite(data).all():
        # the scale-offset filter would turn NaN/Inf into numbers: this column of this group is stored
        # exactly from now on (the rows already written stay rounded; ``resolution`` still bounds them)
        digits = None
        if name in group and group[name].scaleoffset is not None:
            _unround(group, name, compression, rows)
            hit = None
    tail = (0,) * (data.ndim - 1)
    if hit is not None:
        dsid, n = hit
        dsid.set_extent((n + len(data),) + data.shape[1:])
    elif not _exists(group, name):
        if digits is None and compression == "gzip":      # written below, chunk by chunk
            dsid = _create(group, name, data, rows, compression, None, write=False)
            if cache is not None:
                cache[name] = [dsid, len(data)]
            if callable(chunks):
                chunks = chunks()
            for i, a in enumerate(range(0, len(data), rows)):
                z = chunks[i] if chunks is not None else _gzip_chunk(data[a:a + rows], rows)
                dsid.write_direct_chunk((a,) + tail, z)
            return
        dsid = _create(group, name, data, rows, compression, digits, write=True)
        if digits is not None:
            _set_attrs(dsid, {"resolution": 10.0 ** -int(digits)})
        return
    else:
        ds = group[name]
        if not (compression == "gzip" and ds.chunks[0] == rows and _direct(ds)):
            n = ds.shape[0]
            ds.resize(n + len(data), axis=0)
            ds[n:] = data
            return
        dsid, n = ds.id, ds.shape[0]
        dsid.set_extent((n + len(data),) + data.shape[1:])
    if cache is not None:
        cache[name] = [dsid, n + len(data)]
    if n % rows == 0:
        # whole chunks compressed here (the same bytes in the file as through h5py's filters)
        if callable(chunks):
            chunks = chunks()
        for i, a in enumerate(range(0, len(data), rows)):
            z = chunks[i] if chunks is not None else _gzip_chunk(data[a:a + rows], rows)
            dsid.write_direct_chunk((n + a,) + tail, z)
    else:
        ds = h5py.Dataset(dsid)
        ds[n:] = data


def _unround(group: h5py.Group, name: str, compression: str, rows: int):
    """Replace the scale-offset dataset group[name] by an unfiltered (compressed) copy, block by block."""
    old = group[name]
    res = old.attrs.get("resolution")
    tmp = name + ".rounded"
    group.move(name, tmp)
    old = group[tmp]
    new = group.create_dataset(name, shape=old.shape, dtype=old.dtype, maxshape=old.maxshape,
                               chunks=old.chunks, **COMPRESSION[compression])
    for a in range(0, old.shape[0], rows):
        new[a:a + rows] = old[a:a + rows]
    if res is not None:
        new.attrs["resolution"] = res
    del group[tmp]
