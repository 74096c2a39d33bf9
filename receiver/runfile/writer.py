"""HDF5 run file: one self-describing file per run (schema in docs/reference/runfile-format.md).

The file is written under a temporary name and renamed when the run finishes; a failed run leaves no
output file behind.  Per-channel datasets are appended chunk by chunk, so memory does not grow with the
length of the recording.
"""
from __future__ import annotations

import math
import time

import numpy as np

from .. import __version__
from .. import interrupt
from ..safeio import AtomicH5
from ..gnss.satid import sat_label
from .record import ACQ_REASONS, EPOCH_DTYPE, IONO_PARAMS_NAMES, STATE_LOST, STATE_NAMES
# the storage helpers (receiver.runfile.h5store); COMPRESSION, CHUNK_ROWS and chunk_rows_for are also named here
from .h5store import (CHUNK_ROWS, COMPRESSION, MIN_CHUNK_ROWS, _append, _exists, _gzip_chunk,  # noqa: F401
                      _set_attrs, chunk_rows_for)  # noqa: F401


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
            # a copy: a view would keep the whole concatenation (every row written now) alive until the
            # next take -- up to a chunk of rows per channel held twice
            buffers[key] = [rows[n:].copy()]
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
        ``/ephemeris_bds``, the Galileo ones (field bgd_e1e5a; tgd = BGD(E1,E5b)) in ``/ephemeris_gal``, the
        GPS/QZSS ones in ``/ephemeris``; a Galileo-only run (system E) keeps its own in ``/ephemeris``."""
        if not ephs:
            return
        if self.system == "M":
            bds = {k: e for k, e in ephs.items() if getattr(e, "system", "G") == "C"}
            gal = {k: e for k, e in ephs.items() if getattr(e, "system", "G") == "E"}
            self._write_ephemeris_table("ephemeris", {k: e for k, e in ephs.items() if k not in bds and k not in gal})
            self._write_ephemeris_table("ephemeris_bds", bds)
            self._write_ephemeris_table("ephemeris_gal", gal)
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
