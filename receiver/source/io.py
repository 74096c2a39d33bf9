"""IF sample files: formats, chunked (memory-mapped) reading and quantised writing.

Formats (``input.format``; the table ``FORMATS``; docs/own-recording.md maps devices to them):

  int8_iq, int16_iq      interleaved I, Q signed integers (HackRF, bladeRF SC8/SC16, USRP sc8/sc16)
  uint8_iq               interleaved I, Q unsigned offset binary, centre 127.5 (RTL-SDR): value = u - 127.5
  complex64              float32 I, float32 Q (GNU Radio gr_complex, SigMF cf32_le)
  float32_real           float32 real samples at an IF
  int8_real, int16_real  signed real samples at an IF
  int4_iq                one byte per complex sample: I in the high nibble, Q in the low nibble, each a
                         two's-complement integer -8..7
  packed1_real, packed1_iq, packed2_real, packed2_iq, packed4_real, packed4_iq
                         1-, 2- or 4-bit fields packed into bytes (MAX2769/MAX2771/NT1065-style front ends,
                         gps-sdr-sim -b 1);
                         ``iq``: I field then Q field.  Two settings describe them:
                           ``bit_order``  msb_first: the first field of a byte occupies its most significant
                                          bits (bits 7-6 for 2-bit); lsb_first: bits 1-0 first.
                           ``encoding``   sign_magnitude: the field's top bit is the sign (1 = negative),
                                          the rest the magnitude m, value +/-(2m + 1);
                                          twos_complement: the field is a two's-complement integer s,
                                          value 2s + 1.
                         Both give the mid-rise levels +/-1, +/-3 (2-bit) or +/-1 ... +/-15 (4-bit).  (A
                         sign convention opposite to the device's only flips the whole signal, a 180 degree
                         carrier phase the receiver's bit-polarity resolution absorbs.)

Aliases: GNSS-SDR ``item_type`` names and SigMF ``core:datatype`` names (``ALIASES``) resolve to these.

Non-finite samples (NaN/Inf, possible only in float files) are replaced by zeros on reading and
counted once each as the reading front advances (``SampleReader.n_nonfinite``): a burst of NaN then costs
the channels a few microseconds of signal instead of their loop state.

Reading never loads the whole file: :class:`SampleReader` memory-maps it (after ``header_bytes``) and
returns complex64 blocks; packed formats are unpacked per block by a numba kernel through a byte lookup
table.  Real formats come back as complex64 with zero imaginary part; the correlator's carrier NCO at
``if_hz + doppler`` performs the down-conversion.
"""
from __future__ import annotations

import mmap
import os
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import UserError


@dataclass(frozen=True)
class Format:
    """A sample format (an entry of :data:`FORMATS`): storage kind, component dtype, components per sample
    (2: I, Q; 1: real) and, for packed formats, bits per field."""
    name: str
    kind: str            # "int" (signed integers), "float", "uint" (offset binary), "packed"
    dtype: type          # numpy dtype of one stored component (uint8 for packed)
    ncomp: int           # components per sample: 2 (I, Q) or 1 (real)
    bits: int = 0        # packed: bits per field
    integer: bool = False  # packed: the field is the plain two's-complement integer (int4_iq)

    @property
    def complex(self) -> bool:
        """True for I/Q formats (two components per sample), False for real samples at an IF."""
        return self.ncomp == 2


FORMATS = {f.name: f for f in (
    Format("int8_iq", "int", np.int8, 2),
    Format("int16_iq", "int", np.int16, 2),
    Format("uint8_iq", "uint", np.uint8, 2),
    Format("complex64", "float", np.float32, 2),
    Format("float32_real", "float", np.float32, 1),
    Format("int8_real", "int", np.int8, 1),
    Format("int16_real", "int", np.int16, 1),
    Format("int4_iq", "packed", np.uint8, 2, 4, True),
    Format("packed1_real", "packed", np.uint8, 1, 1),
    Format("packed1_iq", "packed", np.uint8, 2, 1),
    Format("packed2_real", "packed", np.uint8, 1, 2),
    Format("packed2_iq", "packed", np.uint8, 2, 2),
    Format("packed4_real", "packed", np.uint8, 1, 4),
    Format("packed4_iq", "packed", np.uint8, 2, 4),
)}

# GNSS-SDR item_type and SigMF core:datatype names -> our formats.  SigMF's "i"/"u" prefixes are real
# (r) or complex (c); only little-endian multi-byte types exist here.
ALIASES = {
    # GNSS-SDR item_type
    "gr_complex": "complex64", "cshort": "int16_iq", "ishort": "int16_iq", "cbyte": "int8_iq",
    "ibyte": "int8_iq", "byte": "int8_real", "short": "int16_real", "float": "float32_real",
    # SigMF core:datatype
    "cf32_le": "complex64", "ci16_le": "int16_iq", "ci8": "int8_iq", "cu8": "uint8_iq",
    "rf32_le": "float32_real", "ri16_le": "int16_real", "ri8": "int8_real",
}
BIT_ORDERS = ("msb_first", "lsb_first")
ENCODINGS = ("sign_magnitude", "twos_complement", "offset_binary")
# noise standard deviation per component that suits each format's range (simulator default)
NOISE_SIGMA = {"int8_iq": 8.0, "int8_real": 8.0, "uint8_iq": 8.0, "int16_iq": 1000.0, "int16_real": 1000.0,
               "complex64": 1.0, "float32_real": 1.0, "int4_iq": 2.0, "packed1_real": 1.0, "packed1_iq": 1.0,
               # step 2 between levels = the MSE-optimal step for a Gaussian input (Max 1960)
               "packed2_real": 2.0 / 0.9957, "packed2_iq": 2.0 / 0.9957,
               "packed4_real": 2.0 / 0.3352, "packed4_iq": 2.0 / 0.3352}


def resolve_format(name: str) -> Format:
    """A format or alias name -> its :class:`Format` (UserError when unknown)."""
    key = ALIASES.get(name, name)
    if key not in FORMATS:
        raise UserError(f"unknown input format '{name}' (one of {', '.join(FORMATS)}; aliases "
                        f"{', '.join(ALIASES)})")
    return FORMATS[key]


def bits_per_sample(fmt) -> int:
    """Bits per sample, all components together (16 for int8_iq, 2 for packed2_real); ``fmt`` a format or
    alias name, or a :class:`Format`."""
    f = resolve_format(fmt) if isinstance(fmt, str) else fmt
    return f.bits * f.ncomp if f.kind == "packed" else 8 * np.dtype(f.dtype).itemsize * f.ncomp


def bytes_per_sample(fmt) -> float:
    """Bytes per complex (or real) sample; a fraction for packed formats (0.25 for packed2_real)."""
    b = bits_per_sample(fmt)
    return b // 8 if b % 8 == 0 else b / 8


def is_complex(fmt: str) -> bool:
    """True when the format (name or alias) stores I/Q samples, False for real ones (UserError when unknown)."""
    return resolve_format(fmt).complex


def field_values(f: Format, encoding: str = "sign_magnitude") -> np.ndarray:
    """Value of each field code 0 .. 2^bits-1 of a packed format."""
    b = f.bits
    c = np.arange(2 ** b)
    s = np.where(c >= 2 ** (b - 1), c - 2 ** b, c)                 # two's-complement integer
    if f.integer:
        return s.astype(np.float32)
    if encoding == "twos_complement":
        return (2 * s + 1).astype(np.float32)
    if encoding == "offset_binary":
        return (2 * c - (2 ** b - 1)).astype(np.float32)
    if encoding != "sign_magnitude":
        raise UserError(f"unknown encoding '{encoding}' (one of {', '.join(ENCODINGS)})")
    sign, mag = c >> (b - 1), c & (2 ** (b - 1) - 1)
    return np.where(sign == 1, -(2 * mag + 1), 2 * mag + 1).astype(np.float32)


def _shifts(bits: int, bit_order: str) -> np.ndarray:
    k = 8 // bits
    if bit_order == "msb_first":
        return np.array([8 - bits * (j + 1) for j in range(k)])
    if bit_order == "lsb_first":
        return np.array([bits * j for j in range(k)])
    raise UserError(f"unknown bit order '{bit_order}' (one of {', '.join(BIT_ORDERS)})")


def byte_table(f: Format, bit_order: str = "msb_first", encoding: str = "sign_magnitude") -> np.ndarray:
    """(256, fields per byte) float32: the field values of every byte value, in file order."""
    vals = field_values(f, encoding)
    sh = _shifts(f.bits, "msb_first" if f.integer else bit_order)
    byte = np.arange(256)[:, None]
    return vals[(byte >> sh[None, :]) & (2 ** f.bits - 1)].astype(np.float32)


@njit(cache=True, nogil=True)
def _deinterleave(raw, swap, offset, out):
    """out[k] = complex(raw[2k], raw[2k+1]) - offset (I, Q swapped when ``swap``): interleaved integer I/Q
    samples as complex64, in one pass (numpy's strided real / imag assignments take three); the integers
    convert exactly, so the values are numpy's."""
    a, b = (1, 0) if swap else (0, 1)
    for k in range(out.shape[0]):
        out[k] = complex(np.float32(raw[2 * k + a]) - offset.real, np.float32(raw[2 * k + b]) - offset.imag)


@njit(cache=True, nogil=True)
def _unpack(raw, table, first_field, ncomp, out):
    """Fields first_field, first_field+1, ... of the bytes `raw` (via `table`) into the complex64 array
    `out` viewed as float32 pairs: I, Q for ncomp 2, real and 0 for ncomp 1."""
    k = table.shape[1]
    o = out.view(np.float32)
    n = out.size * ncomp
    fi = first_field
    bi = 0
    j = 0
    if ncomp == 2:
        while j < n:
            if fi == k:
                fi = 0
                bi += 1
            o[j] = table[raw[bi], fi]
            fi += 1
            j += 1
    else:
        while j < n:
            if fi == k:
                fi = 0
                bi += 1
            o[2 * j] = table[raw[bi], fi]
            o[2 * j + 1] = 0.0
            fi += 1
            j += 1
    return out


#: how far behind the latest read the mapped pages stay resident (s of signal; re-acquisition reads back
#: less than this) and the smallest span released at once
RELEASE_MARGIN_S = 2.0
RELEASE_STEP_BYTES = 16 << 20


class SampleReader:
    """Random access to a span of an IF file as complex64 blocks.

    Sample indices are counted from the first sample of the *file* (after ``header_bytes``); ``first`` and
    ``end`` delimit the span selected by ``skip_s`` and ``duration_s``.
    """

    def __init__(self, path, fmt: str, sample_rate_hz: float, skip_s: float = 0.0,
                 duration_s: float | None = None, iq_swap: bool = False, header_bytes: int = 0,
                 bit_order: str = "msb_first", encoding: str = "sign_magnitude"):
        f = resolve_format(fmt)
        path = os.fspath(path)
        if not os.path.isfile(path):
            raise UserError(f"input file not found: {path}")
        size = os.path.getsize(path)
        if size == 0:
            raise UserError(f"input file is empty: {path}")
        if header_bytes < 0 or header_bytes >= size:
            raise UserError(f"input.header_bytes={header_bytes} leaves no samples in {path} ({size} bytes)")
        data = size - header_bytes
        self.path, self.format, self.fs, self.iq_swap = path, f, float(sample_rate_hz), iq_swap
        self.fmt = f.name
        if f.kind == "packed":
            self._table = byte_table(f, bit_order, encoding)
            self._bits = f.bits * f.ncomp                       # bits per sample
            self.n_file = data * 8 // self._bits
            self._raw = np.memmap(path, dtype=np.uint8, mode="r", offset=header_bytes)
        else:
            bps = bytes_per_sample(f)
            if data % bps:
                raise UserError(f"input file {path} is truncated or not {f.name}: {data} bytes is not a "
                                f"multiple of {bps} bytes per sample")
            self.n_file = data // bps
            self._raw = np.memmap(path, dtype=f.dtype, mode="r", offset=header_bytes)
        self._ncomp = f.ncomp
        self._released = 0             # bytes of the mapping handed back to the kernel (below the read front)
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
        """Number of samples in the span (``end - first``)."""
        return self.end - self.first

    @property
    def duration_s(self) -> float:
        """Length of the span (s)."""
        return self.n_samples / self.fs

    def read(self, start: int, n: int) -> np.ndarray:
        """Samples [start, start+n) (file indices, clipped to the span) as complex64."""
        start = max(start, self.first)
        stop = min(start + n, self.end)
        if stop <= start:
            return np.zeros(0, np.complex64)
        c = self._ncomp
        f = self.format
        self.release_before(start)
        out = np.empty(stop - start, np.complex64)
        if f.kind == "packed":
            k = self._table.shape[1]                             # fields per byte
            f0 = start * c                                       # first field
            b0, b1 = f0 // k, -(-(stop * c) // k)
            _unpack(np.asarray(self._raw[b0:b1]), self._table, f0 - b0 * k, c, out)
            if c == 2 and self.iq_swap:
                out = (out.imag + 1j * out.real).astype(np.complex64)
            elif c == 1 and self.iq_swap:
                out.real[(1 - start % 2)::2] *= -1.0      # odd file indices: consistent across reads
            return out
        raw = self._raw[start * c:stop * c]
        iq = self._int_iq()
        if iq is not None:
            _deinterleave(raw, *iq, out)
        elif c == 2:
            i, q = raw[0::2], raw[1::2]
            if self.iq_swap:
                i, q = q, i
            out.real = i
            out.imag = q
            if f.kind == "uint":
                out -= np.complex64(127.5 + 127.5j)
        else:
            out.real = raw
            out.imag = 0.0
            if self.iq_swap:        # spectral inversion of a real IF signal: (-1)^n, n the file index
                out.real[(1 - start % 2)::2] *= -1.0
        if self._raw.dtype.kind == "f":
            self._sanitize(out, start, stop)
        return out

    def interleaved(self, start: int, n: int):
        """Samples [start, start+n) (clipped like :meth:`read`) still as the file's interleaved 8- or 16-bit
        integers: ``(raw, swap, offset)`` for a stage that converts them as it goes (``complex(raw[2k],
        raw[2k+1]) - offset``, I and Q swapped when ``swap``: :meth:`read`'s values); None for the other
        formats and for an empty span."""
        iq = self._int_iq()
        start = max(start, self.first)
        stop = min(start + n, self.end)
        if iq is None or stop <= start:
            return None
        self.release_before(start)
        return (self._raw[start * 2:stop * 2],) + iq

    def _int_iq(self):
        """(swap, offset) of :func:`_deinterleave` for an interleaved 8- or 16-bit integer I/Q file, else None."""
        if self.format.kind == "packed" or self._ncomp != 2 or self._raw.dtype.kind not in "iu" \
                or self._raw.dtype.itemsize > 2:
            return None
        return bool(self.iq_swap), np.complex64(127.5 + 127.5j if self.format.kind == "uint" else 0.0)

    def release_before(self, index: int):
        """Hand the mapped file pages more than :data:`RELEASE_MARGIN_S` before file index ``index`` back to
        the kernel (``madvise(MADV_DONTNEED)``, in steps of at least :data:`RELEASE_STEP_BYTES`), so that the
        process's resident memory does not grow with the file read so far.  The mapping is read-only and
        file-backed: a later read of a released span faults its pages in again from the file (the same
        bytes), so this changes no result, only what stays resident."""
        mm = getattr(self._raw, "_mmap", None)
        if mm is None or not hasattr(mm, "madvise") or not hasattr(mmap, "MADV_DONTNEED"):
            return
        bits = self._bits if self.format.kind == "packed" else 8 * self._raw.itemsize * self._ncomp
        keep = int(RELEASE_MARGIN_S * self.fs)
        head = self._raw.offset % mmap.ALLOCATIONGRANULARITY    # the array's first byte in the mapping
        target = (head + max(index - keep, 0) * bits // 8) // mmap.PAGESIZE * mmap.PAGESIZE
        if target - self._released >= RELEASE_STEP_BYTES:
            mm.madvise(mmap.MADV_DONTNEED, self._released, target - self._released)
            self._released = target

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


def _components(x: np.ndarray, ncomp: int) -> np.ndarray:
    if ncomp == 2:
        raw = np.empty(2 * x.size, np.float64)
        raw[0::2] = x.real
        raw[1::2] = x.imag
        return raw
    return np.real(x).astype(np.float64)


def field_codes(v: np.ndarray, f: Format, encoding: str = "sign_magnitude") -> np.ndarray:
    """Component values -> field codes of a packed format: the nearest level, saturating."""
    b = f.bits
    if f.integer:
        s = np.clip(np.rint(v), -2 ** (b - 1), 2 ** (b - 1) - 1).astype(np.int64)
        return (s & (2 ** b - 1)).astype(np.uint8)
    s = np.clip(np.floor(v / 2.0), -2 ** (b - 1), 2 ** (b - 1) - 1).astype(np.int64)   # level 2s+1
    if encoding == "twos_complement":
        return (s & (2 ** b - 1)).astype(np.uint8)
    if encoding == "offset_binary":
        return (s + 2 ** (b - 1)).astype(np.uint8)
    if encoding != "sign_magnitude":
        raise UserError(f"unknown encoding '{encoding}' (one of {', '.join(ENCODINGS)})")
    return np.where(s >= 0, s, (1 << (b - 1)) | (-s - 1)).astype(np.uint8)


def pack_codes(codes: np.ndarray, bits: int, bit_order: str = "msb_first") -> np.ndarray:
    """Field codes (a multiple of 8/bits of them) -> bytes."""
    k = 8 // bits
    sh = _shifts(bits, bit_order).astype(np.uint8)
    return np.bitwise_or.reduce(codes.reshape(-1, k) << sh[None, :], axis=1).astype(np.uint8)


def quantize(x: np.ndarray, fmt: str, scale: float = 1.0, bit_order: str = "msb_first",
             encoding: str = "sign_magnitude") -> np.ndarray:
    """Complex (or real) samples -> the raw array of `fmt` (bytes for packed formats), after multiplying
    by scale.

    Integer formats round and saturate; uint8_iq stores round(x + 127.5); packed formats take the
    nearest level (docs/own-recording.md) and need a whole number of bytes' worth of samples.  For real formats the
    real part is written.
    """
    f = resolve_format(fmt)
    raw = _components(np.asarray(x) * scale, f.ncomp)
    if f.kind == "packed":
        k = 8 // f.bits
        if raw.size % k:
            raise ValueError(f"{f.name}: {raw.size} fields do not fill whole bytes ({k} per byte)")
        return pack_codes(field_codes(raw, f, encoding), f.bits, "msb_first" if f.integer else bit_order)
    if f.kind == "uint":
        raw = raw + 127.5
    if np.issubdtype(f.dtype, np.integer):
        info = np.iinfo(f.dtype)
        raw = np.clip(np.rint(raw), info.min, info.max)
    return raw.astype(f.dtype)


class Encoder:
    """Stateful quantiser for a stream of blocks: packed formats carry the fields that do not fill a
    byte to the next block; :meth:`flush` pads the last byte with zero codes."""

    def __init__(self, fmt: str, scale: float = 1.0, bit_order: str = "msb_first",
                 encoding: str = "sign_magnitude"):
        self.format = resolve_format(fmt)
        self.fmt, self.scale, self.bit_order, self.encoding = self.format.name, scale, bit_order, encoding
        if self.format.kind == "packed":
            _shifts(self.format.bits, bit_order)
            field_values(self.format, encoding)
        self._pending = np.zeros(0, np.complex128)

    def encode(self, block: np.ndarray) -> bytes:
        """Quantise the next block of the stream (times ``scale``) -> the bytes to append to the file.  Packed
        formats return whole bytes only: the samples that do not fill one are held back and lead the next block."""
        f = self.format
        if f.kind != "packed":
            return quantize(block, self.fmt, self.scale).tobytes()
        x = np.concatenate([self._pending, np.asarray(block, np.complex128)])
        per_byte = 8 // (f.bits * f.ncomp)                       # samples per byte
        n = x.size - x.size % per_byte
        self._pending = x[n:]
        return quantize(x[:n], self.fmt, self.scale, self.bit_order, self.encoding).tobytes()

    def flush(self) -> bytes:
        """The held-back samples of a packed format as a last byte padded with code-0 fields (b"" when none or
        for other formats); call once at the end of the stream."""
        f = self.format
        if f.kind != "packed" or self._pending.size == 0:
            return b""
        per_byte = 8 // (f.bits * f.ncomp)
        codes = field_codes(_components(self._pending * self.scale, f.ncomp), f, self.encoding)
        codes = np.concatenate([codes, np.zeros(per_byte * f.ncomp - codes.size, np.uint8)])
        self._pending = np.zeros(0, np.complex128)
        return pack_codes(codes, f.bits, "msb_first" if f.integer else self.bit_order).tobytes()


class SampleWriter:
    """Append quantised blocks to a file (the simulator's output)."""

    def __init__(self, path, fmt: str, scale: float = 1.0, bit_order: str = "msb_first",
                 encoding: str = "sign_magnitude"):
        self._enc = Encoder(fmt, scale, bit_order, encoding)
        self.fmt, self.scale = self._enc.fmt, scale
        self._fh = open(path, "wb")

    def write(self, block: np.ndarray):
        """Quantise a block and append its bytes to the file (packed formats: the samples that do not fill a
        byte wait for the next block or :meth:`close`)."""
        self._fh.write(self._enc.encode(block))

    def close(self):
        """Write the held-back samples (:meth:`Encoder.flush`) and close the file."""
        self._fh.write(self._enc.flush())
        self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
