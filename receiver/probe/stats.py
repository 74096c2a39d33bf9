"""Byte statistics of an IF file: which sample formats its bytes can be (cheap, no acquisition).

The tests, in order (the first that fits decides the family; ``Stats.evidence`` says why, in words):

  float32   >= 99 % of the aligned 4-byte words are finite floats of plausible magnitude (1e-30 .. 1e12
            or exactly 0): complex64 or float32_real;
  int16     the odd bytes (little-endian high bytes) carry >= 1 bit less entropy than the even bytes, or
            their histograms differ (total variation > 0.3; I/Q or successive 8-bit samples share one), the
            even bytes spread > 3x as much as the odd ones and the odd bytes are centred on 0: int16_iq or int16_real;
  int8      the bytes read as signed values spread much less than read as unsigned (centred on 0) and
            their histogram is one smooth hump (or uses <= 16 values):
            int8_iq or int8_real (how many levels are used is reported: +/-1 +/-3 is a 2-bit front end
            stored in bytes);
  uint8     the reverse (centred on 127.5): uint8_iq offset binary (RTL-SDR);
  packed    otherwise the bytes are spread over all 256 values: fields of 4, 2 or 1 bits.  For each width
            and encoding, the field values at every position of a byte must have the same
            distribution, symmetric about 0 and falling with |value| (a quantiser's output); the first
            width / encoding that fits best is taken (1 bit when none of 2 or 4 bits fits).  The bit order
            (which field comes first) and I/Q vs real leave these marginals unchanged: the acquisition
            decides them (receiver/probe/search.py).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ..source.io import FORMATS, field_values

#: bytes read for the statistics (the whole file when smaller)
STATS_BYTES = 1 << 20


@dataclass
class Candidate:
    """One way to read the file: format and packed-field settings."""
    fmt: str
    bit_order: str = "msb_first"
    encoding: str = "sign_magnitude"

    def keys(self) -> dict:
        """The input config keys of this reading (bit_order / encoding only where they matter)."""
        d = {"format": self.fmt}
        if FORMATS[self.fmt].kind == "packed" and not FORMATS[self.fmt].integer:
            d["bit_order"] = self.bit_order
            if FORMATS[self.fmt].bits > 1:
                d["encoding"] = self.encoding
        return d

    def label(self) -> str:
        """``packed2_iq bit_order=msb_first encoding=sign_magnitude``."""
        return " ".join(f"{v}" if k == "format" else f"{k}={v}" for k, v in self.keys().items())


@dataclass
class Stats:
    """What the bytes say: the family, the sentences why, and the readings to try."""

    family: str                         # float32, int16, int8, uint8, packed4, packed2, packed1, int4, unknown
    evidence: list = field(default_factory=list)      # sentences, most telling first
    candidates: list = field(default_factory=list)    # Candidate, most likely first
    n_bytes: int = 0
    levels: list = field(default_factory=list)        # distinct values of an 8-bit family (when few)
    clip_fraction: float = 0.0          # samples at the extreme codes of an integer format
    zero_fraction: float = 0.0          # exactly-zero components


def _entropy(counts: np.ndarray) -> float:
    p = counts[counts > 0] / counts.sum()
    return float(-(p * np.log2(p)).sum())


def read_head(path, header_bytes: int = 0, n: int = STATS_BYTES) -> np.ndarray:
    """The first ``n`` bytes after the header (a multiple of 8)."""
    size = os.path.getsize(path) - header_bytes
    with open(path, "rb") as fh:
        fh.seek(header_bytes)
        raw = np.frombuffer(fh.read(min(n, max(size, 0))), np.uint8)
    return raw[:len(raw) - len(raw) % 8]


def _float_test(raw: np.ndarray):
    v = raw.view("<f4")
    a = np.abs(v)
    ok = np.isfinite(v) & ((a == 0) | ((a > 1e-30) & (a < 1e12)))
    return float(ok.mean()), v


def _quantiser_fit(vals: np.ndarray, counts: np.ndarray, tol: float = 0.2) -> tuple[float | None, str]:
    """Is the distribution {vals: counts} a quantiser's output: symmetric about 0, falling with |v|,
    the smallest magnitude clearly the most frequent when there are several?  (asymmetry or None, why
    not)."""
    p = counts / counts.sum()
    dist = {}
    for v, q in zip(vals, p):
        dist[float(v)] = dist.get(float(v), 0.0) + q
    asym = 0.5 * sum(abs(q - dist.get(-v, 0.0)) for v, q in dist.items())
    if asym > tol:
        return None, f"asymmetric ({asym:.2f})"
    mags = sorted({abs(v) for v in dist})
    pm = [(dist.get(m, 0.0) + dist.get(-m, 0.0)) / 2 if m else dist.get(0.0, 0.0) for m in mags]  # per value
    for a, b in zip(pm, pm[1:]):
        if b > a + 0.0125:
            return None, "not falling with |value|"
    if len(pm) > 1 and pm[0] < 1.1 * pm[1]:
        return None, "flat"
    return asym, ""


def _packed_fit(raw: np.ndarray, bits: int, encoding: str, integer: bool = False):
    """Field-value histograms at each of the 8/bits positions of a byte: (asymmetry of their mean or None
    when they are no quantiser's output, why not)."""
    k = 8 // bits
    codes = np.bincount(raw, minlength=256)
    fmt = FORMATS["int4_iq" if integer else f"packed{bits}_real"]
    vals = field_values(fmt, encoding)
    per_pos = []
    for j in range(k):
        sh = 8 - bits * (j + 1)
        c = np.bincount((np.arange(256) >> sh) & (2 ** bits - 1), weights=codes, minlength=2 ** bits)
        per_pos.append(c / c.sum())
    mean = np.mean(per_pos, axis=0)
    spread = max(0.5 * np.abs(p - mean).sum() for p in per_pos)
    if spread > 0.05:
        return None, f"field positions differ ({spread:.2f})"
    return _quantiser_fit(vals, mean)


def byte_stats(path, header_bytes: int = 0) -> Stats:
    """The sample family of ``path`` from its first MiB (module docstring)."""
    raw = read_head(path, header_bytes)
    st = Stats("unknown", n_bytes=len(raw))
    if len(raw) < 64:
        st.evidence.append(f"only {len(raw)} bytes: too few for statistics")
        st.candidates = [Candidate("int8_iq"), Candidate("int8_real")]
        return st
    tried = []
    if _float32(st, raw) or _int16(st, raw) or _bytes(st, raw) or _packed(st, raw, tried) or _packed1(st, raw):
        return st
    st.evidence.append("the bytes fit no format's statistics (" + "; ".join(tried[-3:]) + ")")
    st.candidates = [Candidate("int8_iq"), Candidate("int8_real")]
    return st


def _float32(st: Stats, raw: np.ndarray) -> bool:
    """float32 samples: nearly every 4-byte word a finite float of plausible size (fills st)."""
    frac, v = _float_test(raw)
    if frac > 0.99:
        st.family = "float32"
        st.zero_fraction = float((v == 0).mean())
        st.evidence.append(f"{100 * frac:.1f} % of the 4-byte words are finite float32 of plausible size "
                           f"(RMS {np.sqrt(np.mean(v.astype(np.float64) ** 2)):.3g}): float32 samples")
        st.candidates = [Candidate("complex64"), Candidate("float32_real")]
        return True
    return False


def _int16(st: Stats, raw: np.ndarray) -> bool:
    """Little-endian 16-bit samples: the high bytes vary far less than the low ones (fills st)."""
    even, odd = raw[0::2], raw[1::2]
    h_even, h_odd = _entropy(np.bincount(even, minlength=256)), _entropy(np.bincount(odd, minlength=256))
    hi = odd.view(np.int8).astype(np.float64)
    tv = 0.5 * np.abs(np.bincount(even, minlength=256) / len(even) - np.bincount(odd, minlength=256) / len(odd)).sum()
    lo = even.view(np.int8).astype(np.float64)
    # the high bytes vary far less than the low ones (an I/Q imbalance of 8-bit samples: ~1-2x)
    if (h_even - h_odd > 1.0 or tv > 0.3) and lo.std() > 3 * hi.std() and abs(hi.mean()) < 0.25 * (hi.std() + 1):
        st.family = "int16"
        s16 = raw.view("<i2").astype(np.float64)
        st.clip_fraction = float((np.abs(s16) >= 32767).mean())
        st.evidence.append(f"the odd bytes carry {h_odd:.1f} bits of entropy, the even ones {h_even:.1f} (their "
                           f"histograms differ by {tv:.2f}): little-endian 16-bit samples "
                           f"(RMS {np.sqrt(np.mean(s16 ** 2)):.0f})")
        st.candidates = [Candidate("int16_iq"), Candidate("int16_real")]
        return True
    return False


def _bytes(st: Stats, raw: np.ndarray) -> bool:
    """int8 or uint8 samples: one hump in the byte histogram as signed or as unsigned bytes, not two
    4-bit fields per byte (fills st)."""
    s = raw.view(np.int8).astype(np.float64)
    u = raw.astype(np.float64)
    sd_s, sd_u = s.std(), u.std()
    hist = np.bincount(raw, minlength=256)
    used = np.flatnonzero(hist > 1e-4 * len(raw))
    few = len(used) <= 16                                 # a low-resolution converter stored in bytes

    def smooth(h):
        """One hump (a sampled noise distribution), not the spiky byte histogram of packed fields: the
        histogram's total variation is ~2x its peak for one hump (over the values that occur: a signal
        scaled from a coarser converter uses every other value or so)."""
        h = h[h > 0]
        return 0.5 * np.abs(np.diff(h)).sum() / h.max() < 8.0

    # two 4-bit fields of one distribution in every byte (int4_iq, packed4) before 8-bit samples: an 8-bit
    # sample's high nibble is spread far less than its low one
    nibbles = not few and any(_packed_fit(raw, 4, enc, integer)[0] is not None for enc, integer in
                              (("twos_complement", True), ("sign_magnitude", False), ("twos_complement", False),
                               ("offset_binary", False)))
    if sd_s < 0.6 * sd_u and (few or smooth(np.roll(hist, 128))) and not nibbles:
        st.family = "int8"
        lv = sorted(int(x) for x in used.astype(np.uint8).view(np.int8))
        st.levels = lv if len(lv) <= 16 else []
        st.clip_fraction = float(((s == 127) | (s == -128)).mean())
        st.zero_fraction = float((s == 0).mean())
        what = (f"only the values {' '.join(f'{x:+d}' for x in lv)} occur" if len(lv) <= 16
                else f"{len(lv)} values occur")
        st.evidence.append(f"the byte histogram is centred on 0 as signed bytes (mean {s.mean():+.2f}, RMS "
                           f"{np.sqrt(np.mean(s ** 2)):.1f}; {what}): int8 samples (offset binary uint8 would be "
                           f"centred on 127.5)")
        st.candidates = [Candidate("int8_iq"), Candidate("int8_real")]
        return True
    if sd_u < 0.6 * sd_s and (few or smooth(hist)) and not nibbles:
        st.family = "uint8"
        st.clip_fraction = float(((u == 0) | (u == 255)).mean())
        st.evidence.append(f"the byte histogram is centred on {u.mean():.1f} as unsigned bytes (RMS about it "
                           f"{sd_u:.1f}): uint8 offset binary (value - 127.5; int8 would be centred on 0)")
        st.candidates = [Candidate("uint8_iq")]
        return True
    return False


def _packed(st: Stats, raw: np.ndarray, tried: list) -> bool:
    """Packed 4- or 2-bit fields (or int4 I/Q) whose values look like a quantiser's output (fills st);
    the readings that did not fit are appended to ``tried``."""
    # packed fields: the width / encoding whose field values look most like a quantiser's output (1 bit
    # only when no 2- or 4-bit reading fits: every bit pattern is symmetric at one bit)
    fits = []
    for bits, enc, integer in ((4, "sign_magnitude", False), (4, "twos_complement", False),
                               (4, "offset_binary", False), (4, "twos_complement", True),
                               (2, "sign_magnitude", False), (2, "twos_complement", False),
                               (2, "offset_binary", False)):
        asym, why = _packed_fit(raw, bits, enc, integer)
        if asym is None:
            tried.append(f"{bits}-bit {'int4' if integer else enc.replace('_', '-')}: {why}")
        else:
            fits.append((asym, bits, enc, integer))
    if fits:
        asym, bits, enc, integer = min(fits)
        if integer:
            st.family = "int4"
            st.candidates = [Candidate("int4_iq")]
            st.evidence.append("the bytes use all 256 values; as two 4-bit two's-complement integers per byte "
                               "both nibbles are symmetric about 0 and peaked there: int4_iq")
            return True
        st.family = f"packed{bits}"
        st.candidates = [Candidate(f"packed{bits}_{kind}", o, enc) for kind in ("iq", "real")
                         for o in ("msb_first", "lsb_first")]
        vals = field_values(FORMATS[f"packed{bits}_real"], enc)
        fields = np.concatenate([(raw >> (8 - bits * (j + 1))) & (2 ** bits - 1) for j in range(8 // bits)])
        p = np.bincount(fields, minlength=2 ** bits) / len(fields)
        small = float(p[np.abs(vals) == 1].sum())
        st.evidence.append(f"the bytes use all 256 values; read as {bits}-bit {enc.replace('_', '-')} fields "
                           f"every field position shows the same symmetric quantiser output ({100 * small:.0f} % "
                           f"at +/-1): {bits}-bit samples packed {8 // bits} to a byte")
        if tried:
            st.evidence.append("(not " + "; not ".join(tried[:3]) + ")")
        return True
    return False


def _packed1(st: Stats, raw: np.ndarray) -> bool:
    """1-bit samples packed 8 to a byte: about half the bits set (fills st)."""
    p1 = np.unpackbits(raw).mean()
    if abs(p1 - 0.5) < 0.05:
        st.family = "packed1"
        st.candidates = [Candidate(f"packed1_{kind}", o) for kind in ("iq", "real") for o in ("msb_first", "lsb_first")]
        st.evidence.append(f"the bytes use all 256 values, {100 * p1:.0f} % of the bits are 1 and no 2- or 4-bit "
                           "reading looks like a quantiser's output: 1-bit samples packed 8 to a byte")
        return True
    return False


def component_stats(x: np.ndarray, complex_fmt: bool) -> list[str]:
    """Sentences about a decoded block: DC, I/Q balance and correlation (complex formats)."""
    out = []
    if complex_fmt:
        i, q = x.real.astype(np.float64), x.imag.astype(np.float64)
        pi, pq = i.var(), q.var()
        rho = float(np.corrcoef(i, q)[0, 1]) if pi > 0 and pq > 0 else 0.0
        out.append(f"I/Q: power ratio {10 * np.log10(max(pi, 1e-30) / max(pq, 1e-30)):+.2f} dB, correlation "
                   f"{rho:+.3f}, DC {i.mean():+.3g}{q.mean():+.3g}j")
    else:
        r = x.real.astype(np.float64)
        out.append(f"real samples: DC {r.mean():+.3g}, RMS {r.std():.3g}")
    return out


def spectrum_centre(x: np.ndarray, nfft: int = 1024) -> tuple[float, float]:
    """(centre, half-width) of the band that stands above the spectrum's floor, in cycles per sample (the
    positive half only for real samples); averaged periodograms."""
    n = len(x) // nfft
    if n < 1:
        return 0.0, 0.5
    seg = x[:n * nfft].reshape(n, nfft) * np.hanning(nfft)[None, :]
    psd = (np.abs(np.fft.fft(seg, axis=1)) ** 2).mean(axis=0)
    f = np.fft.fftfreq(nfft)
    if not np.iscomplexobj(x) or not np.any(x.imag):
        keep = f >= 0
        psd, f = psd[keep], f[keep]
    floor = np.percentile(psd, 10)
    w = np.clip(psd - 2 * floor, 0, None)
    if np.count_nonzero(w) < 3:            # flat: no band stands out
        return 0.0, 0.5
    c = float((w * f).sum() / w.sum())
    hw = float(np.sqrt((w * (f - c) ** 2).sum() / w.sum()) * np.sqrt(3))
    return c, hw
