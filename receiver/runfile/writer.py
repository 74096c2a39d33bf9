"""HDF5 run file: one self-describing file per run (schema in docs/reference/runfile-format.md).

The file is written under a temporary name and renamed when the run finishes; a failed run leaves no
output file behind.  Per-channel datasets are appended chunk by chunk, so memory does not grow with the
length of the recording.
"""
from __future__ import annotations

import math
import time
import zlib

import h5py
import numpy as np
from h5py import h5a, h5d, h5p, h5s, h5t, h5z

from .. import __version__
from .. import interrupt
from ..safeio import AtomicH5
from ..gnss.satid import sat_label
from .record import ACQ_REASONS, EPOCH_DTYPE, IONO_PARAMS_NAMES, STATE_LOST, STATE_NAMES


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

#: /channels columns stored rounded to 10**-digits of their unit by the HDF5 scale-offset filter (the
#: dataset stays float64; every HDF5 reader undoes the filter).  The rounding step is far below each
#: column's noise (docs/how-it-works/runfile.md; tests/unit/runfile/test_runfile_storage.py checks it on the
#: reference run):
#: doppler_hz 1e-3 Hz, code_rate_hz 1e-5 chip/s, code_phase_chips 1e-7 chip.  A chunk holding a NaN or
#: Inf is stored unrounded (the filter declines it), so non-finite values survive.
ROUNDED_DIGITS = {"doppler_hz": 3, "code_rate_hz": 5, "code_phase_chips": 7}

#: the run-file layout version (root attribute ``schema``): 2 = rounded columns above, 16384-row chunks;
#: 1 = every column exact.  Readers read both alike.
SCHEMA = "gnssrx-run-2"

#: /channels/Gnn attribute state_mapping
STATE_MAPPING = ",".join(f"{k}={v}" for k, v in STATE_NAMES.items())


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


class ChannelStats:
    """Statistics of one channel over every epoch (written as attributes of /channels/Gnn, so they stay
    exact when output.channel_rate_hz stores fewer records): ``epochs``, ``epochs_locked`` (pll_lock),
    ``lock_losses`` (pll_lock 1 -> 0 transitions), ``cn0_locked_mean_dbhz`` (mean C/N0 over the locked
    epochs, NaN when none), ``dropped`` (state reached 3 = lost), ``first_time_s`` / ``last_time_s``."""

    def __init__(self):
        self.epochs = self.locked = self.losses = 0
        self.cn0_sum = 0.0
        self.cn0_n = 0
        self.dropped = False
        self.first = self.last = math.nan
        self._last_lock = 0
        self._last_bucket = None

    def add(self, r: np.ndarray):
        """Count a chunk of the channel's epoch records (EPOCH_DTYPE, in time order, every epoch, before
        thinning): epochs, locked epochs, lock losses (also across chunks), C/N0 of the locked epochs, the lost
        state and the first / last ``time_s``."""
        lock = (r["pll_lock"] > 0).astype(np.int8)
        self.epochs += len(r)
        self.locked += int(lock.sum())
        self.losses += int(np.count_nonzero(np.diff(np.concatenate(([self._last_lock], lock))) == -1))
        self._last_lock = int(lock[-1])
        c = r["cn0_dbhz"][lock > 0].astype(float)
        c = c[np.isfinite(c)]
        self.cn0_sum += float(c.sum())
        self.cn0_n += c.size
        self.dropped |= bool(np.any(r["state"] == STATE_LOST))
        if math.isnan(self.first):
            self.first = float(r["time_s"][0])
        self.last = float(r["time_s"][-1])

    def thin(self, r: np.ndarray, rate_hz: float) -> np.ndarray:
        """The first record of every 1/rate_hz interval of time_s not yet stored."""
        b = np.floor(r["time_s"] * rate_hz + 1e-9).astype(np.int64)
        prev = np.concatenate(([b[0] - 1 if self._last_bucket is None else self._last_bucket], b[:-1]))
        keep = b > prev
        self._last_bucket = int(max(b[-1], self._last_bucket if self._last_bucket is not None else b[-1]))
        return r[keep]

    def attrs(self) -> dict:
        """The statistics as /channels/Gnn attributes (names in the class docstring; C/N0 in dB-Hz, times in s
        since the first sample of the file)."""
        return {"epochs": self.epochs, "epochs_locked": self.locked, "lock_losses": self.losses,
                "cn0_locked_mean_dbhz": self.cn0_sum / self.cn0_n if self.cn0_n else math.nan,
                "dropped": self.dropped, "first_time_s": self.first, "last_time_s": self.last}


class RunWriter:
    """The writer of one run file (HDF5): acquisition results, per-channel epoch records, navigation tables
    (fixes, observables, vector log), ephemerides, iono/UTC parameters and attributes.  Channels are keyed
    by the signal's PRN (a satellite key in a run over several signals, system ``M``).  The file is written
    under a temporary name and renamed into place by :meth:`close`."""

    def __init__(self, path, config_yaml: str, attrs: dict | None = None, reads=(), compression: str = "none",
                 channel_rate_hz: float | None = None, round_columns: bool = True, chunk_rows: int | None = None):
        """Checks the output path first (safeio.check_output: directory, name length, not one of `reads`,
        not locked by another run), then opens ``<path>.partial``.  ``compression`` (none, lzf, gzip; both
        with the shuffle filter) applies to the growing datasets (channels, navigation, observables).
        ``channel_rate_hz``: store channel records at most at this rate (the first epoch of every
        1/rate interval of ``time_s``); None or 0: every epoch.  The per-channel statistics
        (:class:`ChannelStats`) always see every epoch.  ``round_columns``: store the
        :data:`ROUNDED_DIGITS` channel columns rounded (scale-offset filter); False: exact.
        Channel records and table rows (fixes, observables, vector log) are buffered and written in whole
        chunks (few large HDF5 writes; the file is only renamed into place at the end anyway).
        ``chunk_rows``: rows per HDF5 chunk of the growing datasets (default CHUNK_ROWS; the pipeline
        sizes it from the run's duration, :func:`chunk_rows_for`)."""
        self.chunk_rows = self.FLUSH_ROWS = int(chunk_rows or CHUNK_ROWS)
        self._buffers: dict[int, list] = {}
        self._tables: dict[str, list] = {}
        self._groups: dict = {}     # prn or table group -> (h5py group, _append's dataset cache)
        self.round_columns = bool(round_columns)
        self.system = str((attrs or {}).get("system", "G"))     # RINEX letter of the signal: group names
        self.compression = compression
        self.channel_rate_hz = float(channel_rate_hz or 0.0)
        self._stats: dict[int, ChannelStats] = {}
        self._out = AtomicH5(path, "output", reads=reads)
        self.path, self.tmp, self.f = self._out.path, self._out.tmp, self._out.f
        try:
            _set_attrs(self.f, {"gnssrx_version": __version__, "config": config_yaml,
                                "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                                "schema": SCHEMA if self.round_columns else "gnssrx-run-1", **(attrs or {})})
            _set_attrs(self.f.create_group("channels"), {"channel_rate_hz": self.channel_rate_hz})
            _set_attrs(self.f.create_group("navigation"), {
                "mode_mapping": "0=scalar,1=vector,2=coast,3=aided",
                "iono_params_mapping": ",".join(f"{k}={v}" for k, v in IONO_PARAMS_NAMES.items())})
            self._out.check()
        except BaseException:
            self.close(ok=False)
            raise

    # ------------------------------------------------------------------ acquisition
    def write_acquisition(self, results, attrs: dict | None = None):
        """Append acquisition results (AcqResult: prn, doppler_hz, code_phase_chips, metric, detected,
        cn0_dbhz_est, reason, verified) to /acquisition, one dataset per column, at once (not buffered);
        ``time_s`` is the result's file sample index divided by ``attrs['fs']`` (Hz; without it the index
        itself).  ``attrs`` become attributes of the group, with ``reason_codes`` (code -> reason)."""
        g = self.f.require_group("acquisition")
        rows = {
            "prn": np.array([r.prn for r in results], np.int32),
            "doppler_hz": np.array([r.doppler_hz for r in results]),
            "code_phase_chips": np.array([r.code_phase_chips for r in results]),
            "metric": np.array([r.metric for r in results]),
            "detected": np.array([r.detected for r in results], bool),
            "cn0_dbhz_est": np.array([r.cn0_dbhz_est for r in results]),
            "time_s": np.array([r.sample_index for r in results], float) / (attrs or {}).get("fs", 1.0),
            # integrity: why a peak was not detected (attrs reason_codes) and the verification dwell
            "reason": np.array([ACQ_REASONS.get(getattr(r, "reason", ""), 0) for r in results], np.int8),
            "verified": np.array([getattr(r, "verified", -1) for r in results], np.int8),
        }
        g.attrs["reason_codes"] = ",".join(f"{v}={k or 'detected'}" for k, v in ACQ_REASONS.items())
        for k, v in rows.items():
            _append(g, k, v, rows=256)               # a few rows per search: small chunks
        _set_attrs(g, attrs or {})

    # ------------------------------------------------------------------ channels
    def append_channel(self, prn: int, records: np.ndarray):
        """Buffered: records are written in blocks of FLUSH_ROWS per channel (few large HDF5 writes)."""
        if len(records) == 0:
            return
        st = self._stats.setdefault(prn, ChannelStats())
        st.add(records)
        if self.channel_rate_hz > 0:
            records = st.thin(records, self.channel_rate_hz)
            if len(records) == 0:
                return
        buf = self._buffers.setdefault(prn, [])
        buf.append(records)
        if sum(len(b) for b in buf) >= self.FLUSH_ROWS:
            self._flush_channel(prn)

    def _flush_channel(self, prn: int, final: bool = False):
        """Write the buffered records of prn: whole chunks (the rest stays buffered), all of them if final."""
        job = self._channel_job(prn, final)
        if job is not None:
            self._write_channel(*job[:2], self._precompress(job[2]))

    def _channel_job(self, prn: int, final: bool):
        """(prn, columns, the columns that go the direct way) of the rows of prn to write now
        (:meth:`_take`), or None.  No HDF5 call."""
        records = self._take(self._buffers, prn, final)
        if records is None:
            return None
        rounded = ROUNDED_DIGITS if self.round_columns else {}
        cols = [(name, np.ascontiguousarray(records[name]), rounded.get(name)) for name in EPOCH_DTYPE.names]
        return prn, cols, self._direct_columns(*self._groups.get(prn, (None, None)), cols)

    def _channel_group(self, prn: int):
        """(group, dataset cache) of prn's /channels group, created (with its prn / state_mapping
        attributes) on first use."""
        hit = self._groups.get(prn)
        if hit is None:
            g = self.f["channels"].require_group(sat_label(prn, self.system))
            if "prn" not in g.attrs:
                _set_attrs(g, {"prn": prn, "state_mapping": STATE_MAPPING})
            hit = self._groups[prn] = (g, {})
        return hit

    def _write_channel(self, prn: int, cols, pre: dict):
        g, cache = self._channel_group(prn)
        for name, col, digits in cols:
            _append(g, name, col, self.compression, digits, rows=self.chunk_rows, cache=cache,
                    chunks=pre.get(name))
        self._out.check()

    def _direct_columns(self, g, cache: dict | None, cols) -> list:
        """[(name, column)] of the columns that go the direct way (gzip, not rounded, a new dataset or one
        whose rows end on a chunk boundary): _append writes them as chunks compressed by _gzip_chunk.
        ``g`` None: the channel's group is not created yet (every such column is a new dataset).  (Only
        a matter of speed: _append ignores the chunks of a column that does not go the direct way and
        compresses those of one that does when it has none.)"""
        if self.compression != "gzip":
            return []
        todo = []
        for name, col, digits in cols:
            if digits is not None:
                continue
            hit = cache.get(name) if cache is not None else None
            if g is None or (hit is not None and hit[1] % self.chunk_rows == 0) or \
                    (hit is None and not _exists(g, name)):
                todo.append((name, col))
        return todo

    def _compress(self, todo) -> list:
        r = self.chunk_rows
        return [[_gzip_chunk(c[a:a + r], r) for a in range(0, len(c), r)] for _, c in todo]

    def _precompress(self, todo) -> dict:
        """name -> the compressed chunks of the columns ``todo`` (:meth:`_direct_columns`), compressed on
        the receiver's thread pool (zlib releases the GIL: the columns of a flush use every core).
        The chunks are the ones _append would compute, so the file does not depend on it."""
        if not todo:
            return {}
        from ..threads import map_ordered, threads
        # a few batches of columns, one per thread: a short run's columns are one small chunk each, and a
        # pool job per column cost as much as compressing it (future, locks, GIL hand-offs)
        k = max(1, min(threads(), len(todo)))
        groups = [todo[i * len(todo) // k:(i + 1) * len(todo) // k] for i in range(k)]
        done = [z for g in map_ordered(self._compress, groups) for z in g]
        return {name: z for (name, _), z in zip(todo, done)}

    def _flush_channels_final(self):
        """Every channel's last rows (at close).  The compression of all of them is started on the thread
        pool first (one job per channel) and runs while this thread creates the datasets (HDF5 calls hold
        the GIL, zlib does not); each channel's chunks are waited for when its datasets exist.  The same
        datasets and chunks as flushing the channels one after the other."""
        from ..threads import submit_each
        jobs = [j for j in (self._channel_job(prn, True) for prn in list(self._buffers)) if j is not None]
        waits = submit_each(self._compress, [todo for _, _, todo in jobs])
        for (prn, cols, todo), wait in zip(jobs, waits):
            self._write_channel(prn, cols,
                                {name: (lambda i=i, wait=wait: wait()[i]) for i, (name, _) in enumerate(todo)})

    def _take(self, buffers: dict, key, final: bool):
        """The buffered rows of ``key`` to write now: a whole number of chunks (chunk_rows), the rest kept
        for later (every chunk is then written once, compressed whole: _append's direct path), or all of
        them when ``final``.  None: nothing to write."""
        buf = buffers.pop(key, None)
        if not buf:
            return None
        rows = np.concatenate(buf) if len(buf) > 1 else buf[0]
        n = len(rows) if final else len(rows) // self.chunk_rows * self.chunk_rows
        if n < len(rows):
            buffers[key] = [rows[n:]]
        return rows[:n] if n else None

    def _write_stats(self):
        for prn, st in self._stats.items():
            _set_attrs(self._channel_group(prn)[0], st.attrs())

    # ------------------------------------------------------------------ navigation
    def _append_table(self, group: str, rows: np.ndarray):
        """Append structured rows to /group, one dataset per field (buffered: written FLUSH_ROWS at a time
        and at :meth:`close`)."""
        if rows is None or len(rows) == 0:
            return
        buf = self._tables.setdefault(group, [])
        buf.append(np.array(rows, copy=True))
        if sum(len(b) for b in buf) >= self.FLUSH_ROWS:
            self._flush_table(group)

    def _flush_table(self, group: str, final: bool = False):
        rows = self._take(self._tables, group, final)
        if rows is None:
            return
        g, cache = self._groups.get(group, (None, None))
        if g is None:
            g, cache = self.f.require_group(group), {}
            self._groups[group] = (g, cache)
        for name in rows.dtype.names:
            _append(g, name, np.ascontiguousarray(rows[name]), self.compression, rows=self.chunk_rows,
                    cache=cache)
        self._out.check()

    def append_fixes(self, fixes: np.ndarray):
        """Append fix rows (FIX_DTYPE) to /navigation, one dataset per field (buffered: written in whole chunks
        and at :meth:`close`)."""
        self._append_table("navigation", fixes)             # FIX_DTYPE

    def append_vector_log(self, rows: np.ndarray):
        """Append vector-tracking diagnostics rows (VECTOR_LOG_DTYPE) to /vector (buffered like
        :meth:`append_fixes`)."""
        self._append_table("vector", rows)                  # VECTOR_LOG_DTYPE

    def append_observables(self, obs: np.ndarray):
        """Append observable rows (OBS_DTYPE) to /observables (buffered like :meth:`append_fixes`)."""
        self._append_table("observables", obs)              # OBS_DTYPE

    def append_band(self, group: str, rows: np.ndarray):
        """Append rows of a second band's table (/acquisition_l5, /observables_l5, /navigation_ionofree:
        receiver/dualband.py) to /group, one dataset per field (buffered like :meth:`append_fixes`)."""
        self._append_table(group, rows)

    def write_ephemerides(self, ephs: dict):
        """ephs: prn -> Ephemeris (dataclass); stored as one compound-free table of fields.  A run over
        several signals (system M) keeps the BeiDou ones (BDT, field tgd2) in a table of their own,
        ``/ephemeris_bds``, the GPS/QZSS ones in ``/ephemeris``."""
        if not ephs:
            return
        if self.system == "M":
            bds = {k: e for k, e in ephs.items() if getattr(e, "system", "G") == "C"}
            self._write_ephemeris_table("ephemeris", {k: e for k, e in ephs.items() if k not in bds})
            self._write_ephemeris_table("ephemeris_bds", bds)
        else:
            self._write_ephemeris_table("ephemeris", ephs)

    def _write_ephemeris_table(self, name: str, ephs: dict):
        if not ephs:
            return
        g = self.f.require_group(name)
        items = sorted(ephs.items())
        fields = list(vars(items[0][1]).keys())
        for name in fields:
            vals = [getattr(e, name) for _, e in items]
            try:
                arr = np.array(vals, dtype=float)
            except (TypeError, ValueError):
                continue
            if name in g:
                del g[name]
            g.create_dataset(name, data=arr)

    def write_iono_utc(self, iono, source: str):
        """The Klobuchar / GPS-UTC parameters the fixes used: group /iono_utc, one attribute per field."""
        if iono is None:
            return
        g = self.f.require_group("iono_utc")
        for name, val in vars(iono).items():
            if val is None:
                continue
            g.attrs[name] = np.asarray(val, dtype=float) if isinstance(val, tuple) else val
        g.attrs["source"] = source

    def set_attrs(self, group: str, attrs: dict):
        """Set attributes of the group ``group`` (created when absent; ``"/"``: the file's root), at once."""
        g = self.f.require_group(group) if group != "/" else self.f
        _set_attrs(g, attrs)

    def check(self):
        """Raise a one-line UserError if a write failed (disk full, file size limit)."""
        self._out.check()

    def close(self, ok: bool = True):
        """ok: flush, close, fsync and rename to the final name (only if every write succeeded and no
        SIGINT/SIGTERM is pending); otherwise, or if any of that fails, remove the temporary file."""
        if self.f is None:
            return
        if not ok:
            self.f = None
            self._out.abort()
            return
        try:
            self._flush_channels_final()
            for group in list(self._tables):
                self._flush_table(group, final=True)
            self._write_stats()
            self._out.check()
        except BaseException:
            self.f = None
            self._out.abort()
            raise
        self.f = None
        self._out.commit(before_rename=interrupt.check)
