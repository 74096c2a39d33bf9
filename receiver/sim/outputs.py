"""Simulator output files: the names beside the IF file, the truth HDF5 writer (rows buffered, bounded
memory) and the companion files (receiver input fragment, SigMF metadata, PocketSDR tag)."""
from __future__ import annotations

import os

import numpy as np
import yaml

from .. import __version__
from ..errors import UserError
from ..gnss.satid import sat_label
from ..safeio import GuardedFile, write_error_message
from ..source.metadata import write_sigmf, write_tag
from .scenario import resolve_path


def output_paths(out_path) -> dict:
    """IF file, truth file (<stem>.truth.h5), receiver input fragment (<stem>.yaml) and SigMF metadata
    (<stem>.sigmf-meta; <stem> drops a .bin or .sigmf-data extension) and PocketSDR tag (<out>.tag: only for
    the formats PocketSDR names, receiver/source/metadata.py)."""
    out_path = os.fspath(out_path)
    stem = out_path
    for ext in (".bin", ".sigmf-data"):
        if out_path.endswith(ext):
            stem = out_path[:-len(ext)]
    return {"if": out_path, "truth": stem + ".truth.h5", "yaml": stem + ".yaml", "sigmf": stem + ".sigmf-meta",
            "tag": out_path + ".tag"}


def remove_files(paths):
    """Remove the files that exist among paths (errors ignored)."""
    for p in paths:
        try:
            if os.path.exists(p):
                os.remove(p)
        except OSError:
            pass


def files_read(scenario, sc) -> list:
    """The scenario file and every existing file a scenario value names (RINEX, trajectory CSV, ...)."""
    out = [os.fspath(scenario)] if isinstance(scenario, (str, os.PathLike)) else []

    def walk(v):
        if isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, list):
            for x in v:
                walk(x)
        elif isinstance(v, str) and v and ("/" in v or "." in v):
            try:
                p = resolve_path(v)
            except UserError:
                return
            if os.path.isfile(p):
                out.append(p)
    walk(sc.to_dict())
    return out


class TruthWriter:
    """Truth HDF5 file; rows are buffered and appended every ``flush_rows`` rows (bounded memory)."""

    def __init__(self, path, attrs, prns, sat_attrs, flush_rows=6000, system="G"):
        import h5py
        self.flush_rows = flush_rows
        self.path = path
        self._buf = []
        self._rows = 0
        self._file = GuardedFile(path)      # a write error (disk full) is kept, not passed to HDF5
        self.f = h5py.File(self._file, "w")
        for k, v in attrs.items():
            self.f.attrs[k] = v
        self.rx = self.f.create_group("receiver")
        g = self.f.create_group("satellites")
        g.attrs["prns"] = np.array(sorted(prns), dtype=np.int32)
        self.sats = {}
        for prn in sorted(prns):
            sg = g.create_group(sat_label(prn, system))
            sg.attrs["prn"] = prn
            for k, v in sat_attrs[prn].items():
                sg.attrs[k] = v
            self.sats[prn] = sg

    @staticmethod
    def _append(group, name, data):
        """Append rows to a resizable, LZF-compressed dataset (created on first use)."""
        data = np.ascontiguousarray(data)
        if name not in group:
            group.create_dataset(name, data=data, maxshape=(None,) + data.shape[1:],
                                 chunks=(8192,) + data.shape[1:], compression="lzf", shuffle=True)
        else:
            ds = group[name]
            n = ds.shape[0]
            ds.resize(n + len(data), axis=0)
            ds[n:] = data

    def append(self, rx_rows: dict, sat_rows: dict):
        """Buffer one block's receiver rows and per-satellite rows ({prn: {name: array}})."""
        self._buf.append((rx_rows, sat_rows))
        self._rows += len(rx_rows["time_s"])
        if self._rows >= self.flush_rows:
            self.flush()

    def flush(self):
        """Append the buffered rows to the file."""
        if not self._buf:
            return
        for k in self._buf[0][0]:
            self._append(self.rx, k, np.concatenate([b[0][k] for b in self._buf]))
        for prn, grp in self.sats.items():
            for k in self._buf[0][1][prn]:
                self._append(grp, k, np.concatenate([b[1][prn][k] for b in self._buf]))
        self._buf, self._rows = [], 0
        self.check()

    def check(self):
        """Raise the kept write error (disk full, ...) as a one-line UserError."""
        if self._file.error is not None:
            raise UserError(write_error_message("truth file", self.path, self._file.error))

    def close(self):
        """Flush, close and sync the file (then report a kept write error)."""
        if self.f is not None:
            try:
                self.flush()
            finally:
                self.f.close()
                self.f = None
                self._file.sync()
                self._file.close()
            self.check()



def write_companions(paths, tmp, fe, signal, signals, multi, fs, if_hz, week, t_ref):
    """The SigMF metadata, PocketSDR tag and receiver input fragment of a recording, under the names
    ``tmp``; the fragment and the SigMF description name the final ``paths``.  signal: the first
    signal (at frontend.if_hz); signals: all of them (several when multi)."""
    fmt = fe.format
    packed = {"bit_order": fe.bit_order, "encoding": fe.encoding} if "packed" in fmt else {}
    frag = {"input": {"path": os.path.basename(paths["if"]), "format": fmt, **packed,
                      "sample_rate_hz": fs, "if_hz": if_hz, "start_gps_week": week,
                      "start_gps_tow_s": t_ref}}
    if multi:
        frag = {"signals": [g.name for g in signals], **frag}
    elif signal.name != "gps_l1ca":            # the run config's default signal is GPS L1 C/A
        frag = {"signal": signal.name, **frag}
    write_sigmf(tmp["if"], fmt, fs, if_hz, signal.carrier_hz, week, t_ref,
                description="gnssrx simulator output; truth: " + os.path.basename(paths["truth"]),
                bit_order=fe.bit_order, encoding=fe.encoding, version=__version__, meta=tmp["sigmf"])
    write_tag(tmp["if"], fmt, fs, if_hz, signal.carrier_hz, week, t_ref, tag=tmp["tag"])
    with open(tmp["yaml"], "w") as f:
        f.write(f"# gnssrx simulator output (gnssrx {__version__}): receiver input section for "
                f"{os.path.basename(paths['if'])}\n# truth: {os.path.basename(paths['truth'])}\n")
        yaml.safe_dump(frag, f, sort_keys=False)
