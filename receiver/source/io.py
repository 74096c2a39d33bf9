"""IF sample files: formats, chunked (memory-mapped) reading and quantised writing.

Formats (``input.format``):
  int8_iq, int16_iq   interleaved I, Q integers (complex baseband or complex IF)
  complex64           numpy complex64 (float32 I, float32 Q)
  int8_real, int16_real  real samples at an IF

Non-finite samples (NaN/Inf, possible only in complex64 files) are replaced by zeros on reading and
counted once each as the reading front advances (``SampleReader.n_nonfinite``): a burst of NaN then costs
the channels a few microseconds of signal instead of their loop state.

Reading never loads the whole file: :class:`SampleReader` memory-maps it and returns complex64 blocks.
Real formats come back as complex64 with zero imaginary part; the correlator's carrier NCO at
``if_hz + doppler`` performs the down-conversion.
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import UserError

# name -> (numpy dtype of one component, components per sample)
FORMATS = {
    "int8_iq": (np.int8, 2),
    "int16_iq": (np.int16, 2),
    "complex64": (np.float32, 2),
    "int8_real": (np.int8, 1),
    "int16_real": (np.int16, 1),
}


def bytes_per_sample(fmt: str) -> int:
    dt, n = FORMATS[fmt]
    return np.dtype(dt).itemsize * n


def is_complex(fmt: str) -> bool:
    return FORMATS[fmt][1] == 2


class SampleReader:
    """Random access to a span of an IF file as complex64 blocks.

    Sample indices are counted from the first sample of the *file*; ``first`` and ``end`` delimit the
    span selected by ``skip_s`` and ``duration_s``.
    """

    def __init__(self, path, fmt: str, sample_rate_hz: float, skip_s: float = 0.0,
                 duration_s: float | None = None, iq_swap: bool = False):
        if fmt not in FORMATS:
            raise UserError(f"unknown input format '{fmt}' (one of {', '.join(FORMATS)})")
        path = os.fspath(path)
        if not os.path.isfile(path):
            raise UserError(f"input file not found: {path}")
        size = os.path.getsize(path)
        bps = bytes_per_sample(fmt)
        if size == 0:
            raise UserError(f"input file is empty: {path}")
        if size % bps:
            raise UserError(f"input file {path} is truncated or not {fmt}: {size} bytes is not a "
                            f"multiple of {bps} bytes per sample")
        self.path, self.fmt, self.fs, self.iq_swap = path, fmt, float(sample_rate_hz), iq_swap
        self.n_file = size // bps
        dt, ncomp = FORMATS[fmt]
        self._raw = np.memmap(path, dtype=dt, mode="r")
        self._ncomp = ncomp
        self.first = int(round(skip_s * self.fs))
        if self.first >= self.n_file:
            raise UserError(f"input.skip_s={skip_s} is beyond the end of {path} "
                            f"({self.n_file / self.fs:.3f} s)")
        end = self.n_file if duration_s is None else self.first + int(round(duration_s * self.fs))
        self.end = min(end, self.n_file)
        self.n_nonfinite = 0           # NaN/Inf samples zeroed so far (each counted once)
        self.first_nonfinite = None    # file index of the first one
        self._front = 0                # samples before this file index have been counted

    @property
    def n_samples(self) -> int:
        return self.end - self.first

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.fs

    def read(self, start: int, n: int) -> np.ndarray:
        """Samples [start, start+n) (file indices, clipped to the span) as complex64."""
        start = max(start, self.first)
        stop = min(start + n, self.end)
        if stop <= start:
            return np.zeros(0, np.complex64)
        c = self._ncomp
        raw = self._raw[start * c:stop * c]
        out = np.empty(stop - start, np.complex64)
        if c == 2:
            i, q = raw[0::2], raw[1::2]
            if self.iq_swap:
                i, q = q, i
            out.real = i
            out.imag = q
        else:
            out.real = raw
            out.imag = 0.0
            if self.iq_swap:        # spectral inversion of a real IF signal
                out.real[1::2] *= -1.0
        if self._raw.dtype.kind == "f":
            self._sanitize(out, start, stop)
        return out

    def _sanitize(self, out: np.ndarray, start: int, stop: int):
        """Zero NaN/Inf samples in place; count those at or after the reading front."""
        bad = ~np.isfinite(out)
        if bad.any():
            out[bad] = 0
            idx = np.flatnonzero(bad)
            new = idx[idx + start >= self._front]
            if len(new):
                self.n_nonfinite += len(new)
                if self.first_nonfinite is None:
                    self.first_nonfinite = int(start + new[0])
        self._front = max(self._front, stop)

    def chunks(self, chunk_samples: int, overlap: int = 0):
        """Yield (start_index, block) over the span; blocks overlap by `overlap` samples."""
        pos = self.first
        while pos < self.end:
            block = self.read(pos, chunk_samples + overlap)
            yield pos, block
            pos += chunk_samples


def quantize(x: np.ndarray, fmt: str, scale: float = 1.0) -> np.ndarray:
    """Complex (or real) samples -> the raw interleaved array of `fmt`, after multiplying by scale.

    Integer formats round and saturate. For real formats the real part is written.
    """
    dt, ncomp = FORMATS[fmt]
    x = np.asarray(x) * scale
    if ncomp == 2:
        raw = np.empty(2 * x.size, np.float64 if dt != np.float32 else np.float32)
        raw[0::2] = x.real
        raw[1::2] = x.imag
    else:
        raw = np.real(x).astype(np.float64)
    if np.issubdtype(dt, np.integer):
        info = np.iinfo(dt)
        raw = np.clip(np.rint(raw), info.min, info.max)
    return raw.astype(dt)


class SampleWriter:
    """Append quantised blocks to a file (the simulator's output)."""

    def __init__(self, path, fmt: str, scale: float = 1.0):
        if fmt not in FORMATS:
            raise UserError(f"unknown sample format '{fmt}'")
        self.fmt, self.scale = fmt, scale
        self._fh = open(path, "wb")

    def write(self, block: np.ndarray):
        quantize(block, self.fmt, self.scale).tofile(self._fh)

    def close(self):
        self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
