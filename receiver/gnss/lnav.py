"""GPS L1 C/A LNAV navigation message (IS-GPS-200): parity, frame encoder, decoder.

Bit conventions
---------------
* Message bits are 0/1 (uint8).  A 30-bit word is D1..D30 (transmitted), of which D1..D24
  are the source data d1..d24 XOR D30* (D30 of the previous word) and D25..D30 the parity.
* Soft bits fed to :class:`LnavDecoder` are floats; with polarity +1 a positive value is
  bit 0 and a negative value bit 1 (the BPSK mapping 0 -> +1, 1 -> -1).  The decoder finds the
  polarity itself from the preamble.
* Words 2 (HOW) and 10 of every subframe end with D29 = D30 = 0 (the two "t" bits solved),
  so the TLM word of the next subframe is always sent with D30* = 0.

Why this module is long: the whole LNAV message stays in one module; the parity, the encoder (the
simulator's) and the decoder share the word layouts and scale factors of IS-GPS-200, and each would import
the others' tables.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .ephemeris import Ephemeris, IonoUtc, GPS_PI
from .time import HALF_WEEK, WEEK_S, wrap_week_seconds

PREAMBLE = np.array([1, 0, 0, 0, 1, 0, 1, 1], dtype=np.uint8)
SUBFRAME_BITS = 300
FRAME_BITS = 1500
WORD_BITS = 30
TOW_COUNT_MAX = 100800           # HOW TOW count modulus: 604800 s / 6 s

# parity equations (IS-GPS-200 Table 20-XIV): (which previous bit, source data bits)
_PARITY_EQ = (
    (29, (1, 2, 3, 5, 6, 10, 11, 12, 13, 14, 17, 18, 20, 23)),
    (30, (2, 3, 4, 6, 7, 11, 12, 13, 14, 15, 18, 19, 21, 24)),
    (29, (1, 3, 4, 5, 7, 8, 12, 13, 14, 15, 16, 19, 20, 22)),
    (30, (2, 4, 5, 6, 8, 9, 13, 14, 15, 16, 17, 20, 21, 23)),
    (30, (1, 3, 5, 6, 7, 9, 10, 14, 15, 16, 17, 18, 21, 22, 24)),
    (29, (3, 5, 6, 8, 9, 10, 11, 13, 15, 19, 22, 23, 24)),
)
# parity check matrix as 0/1 (6 x 24) for vectorised use
_H = np.zeros((6, 24), dtype=np.uint8)
for _r, (_, _taps) in enumerate(_PARITY_EQ):
    _H[_r, np.array(_taps) - 1] = 1
_PREV_IS_29 = np.array([p == 29 for p, _ in _PARITY_EQ])


# ----------------------------------------------------------------------------- parity

def parity_bits(d24, d29s: int, d30s: int) -> np.ndarray:
    """The six parity bits D25..D30 of the source data bits d1..d24 (0/1 array)."""
    d = np.asarray(d24, dtype=np.uint8).reshape(24)
    par = (_H @ d.astype(np.int64)) & 1
    prev = np.where(_PREV_IS_29, d29s & 1, d30s & 1)
    return (par ^ prev).astype(np.uint8)


def encode_word(data24, d29s: int, d30s: int, solve_t: bool = False) -> np.ndarray:
    """Source data d1..d24 (0/1 array, or int with d1 as MSB) -> transmitted word D1..D30.

    With ``solve_t`` the last two data bits (the "t" bits of words 2 and 10) are replaced by
    the values that make D29 = D30 = 0.
    """
    d = int_to_bits(data24, 24) if np.isscalar(data24) else np.array(data24, dtype=np.uint8).reshape(24)
    if solve_t:
        for t in ((0, 0), (0, 1), (1, 0), (1, 1)):
            d[22], d[23] = t
            par = parity_bits(d, d29s, d30s)
            if par[4] == 0 and par[5] == 0:
                break
        else:  # cannot happen: the two t bits span the D29/D30 space
            raise AssertionError("no t bits give D29 = D30 = 0")
    par = parity_bits(d, d29s, d30s)
    return np.concatenate([d ^ (d30s & 1), par]).astype(np.uint8)


def decode_word(word30, d29s: int, d30s: int):
    """Transmitted word D1..D30 -> (source data d1..d24 as uint8 array, parity_ok)."""
    w = np.asarray(word30, dtype=np.uint8).reshape(30)
    d = w[:24] ^ (d30s & 1)
    ok = bool(np.array_equal(parity_bits(d, d29s, d30s), w[24:]))
    return d, ok


def word_parity_ok(word30_bits, d29s: int, d30s: int) -> bool:
    """True when a transmitted 30-bit word satisfies the LNAV parity equations."""
    return decode_word(word30_bits, d29s, d30s)[1]


def hard_bits(bits) -> np.ndarray:
    """Decoded bits (uint8 0/1) from a tracking loop's bit stream: booleans / unsigned 0-1 values as
    they are, signed soft values (prompt sums) by sign (negative -> 1)."""
    arr = np.asarray(bits).ravel()
    if arr.dtype == bool or np.issubdtype(arr.dtype, np.unsignedinteger):
        return (arr != 0).astype(np.uint8)
    return (arr < 0).astype(np.uint8)


def int_to_bits(value: int, n: int) -> np.ndarray:
    """Unsigned int -> n bits, MSB first."""
    value = int(value)
    return np.array([(value >> (n - 1 - k)) & 1 for k in range(n)], dtype=np.uint8)


def bits_to_int(bits) -> int:
    """Integer of a 0/1 bit sequence, first bit most significant."""
    v = 0
    for b in np.asarray(bits, dtype=np.uint8).ravel():
        v = (v << 1) | int(b)
    return v


# ----------------------------------------------------------------------------- field layout
# chunk = (word 1..10, first data bit 1..24, number of bits), MSB chunk first
@dataclass(frozen=True)
class _Field:
    name: str
    chunks: tuple
    scale: float = 1.0
    signed: bool = False
    semicircles: bool = False

    @property
    def nbits(self):
        return sum(c[2] for c in self.chunks)

    @property
    def lsb(self):
        """LSB in stored (SI/radian) units."""
        return self.scale * (GPS_PI if self.semicircles else 1.0)


_SF1 = (
    _Field("wn", ((3, 1, 10),)),
    _Field("code_on_l2", ((3, 11, 2),)),
    _Field("ura_index", ((3, 13, 4),)),
    _Field("health", ((3, 17, 6),)),
    _Field("iodc", ((3, 23, 2), (8, 1, 8))),
    _Field("l2p_flag", ((4, 1, 1),)),
    _Field("tgd", ((7, 17, 8),), 2.0 ** -31, True),
    _Field("toc", ((8, 9, 16),), 2.0 ** 4),
    _Field("af2", ((9, 1, 8),), 2.0 ** -55, True),
    _Field("af1", ((9, 9, 16),), 2.0 ** -43, True),
    _Field("af0", ((10, 1, 22),), 2.0 ** -31, True),
)
_SF2 = (
    _Field("iode", ((3, 1, 8),)),
    _Field("crs", ((3, 9, 16),), 2.0 ** -5, True),
    _Field("delta_n", ((4, 1, 16),), 2.0 ** -43, True, True),
    _Field("m0", ((4, 17, 8), (5, 1, 24)), 2.0 ** -31, True, True),
    _Field("cuc", ((6, 1, 16),), 2.0 ** -29, True),
    _Field("e", ((6, 17, 8), (7, 1, 24)), 2.0 ** -33),
    _Field("cus", ((8, 1, 16),), 2.0 ** -29, True),
    _Field("sqrt_a", ((8, 17, 8), (9, 1, 24)), 2.0 ** -19),
    _Field("toe", ((10, 1, 16),), 2.0 ** 4),
    _Field("fit_interval", ((10, 17, 1),)),
    _Field("aodo", ((10, 18, 5),), 900.0),
)
_SF3 = (
    _Field("cic", ((3, 1, 16),), 2.0 ** -29, True),
    _Field("omega0", ((3, 17, 8), (4, 1, 24)), 2.0 ** -31, True, True),
    _Field("cis", ((5, 1, 16),), 2.0 ** -29, True),
    _Field("i0", ((5, 17, 8), (6, 1, 24)), 2.0 ** -31, True, True),
    _Field("crc", ((7, 1, 16),), 2.0 ** -5, True),
    _Field("omega", ((7, 17, 8), (8, 1, 24)), 2.0 ** -31, True, True),
    _Field("omega_dot", ((9, 1, 24),), 2.0 ** -43, True, True),
    _Field("iode", ((10, 1, 8),)),
    _Field("idot", ((10, 9, 14),), 2.0 ** -43, True, True),
)
# subframe 4 page 18: ionosphere and UTC
_P18 = (
    _Field("data_id", ((3, 1, 2),)),
    _Field("sv_id", ((3, 3, 6),)),
    _Field("alpha0", ((3, 9, 8),), 2.0 ** -30, True),
    _Field("alpha1", ((3, 17, 8),), 2.0 ** -27, True),
    _Field("alpha2", ((4, 1, 8),), 2.0 ** -24, True),
    _Field("alpha3", ((4, 9, 8),), 2.0 ** -24, True),
    _Field("beta0", ((4, 17, 8),), 2.0 ** 11, True),
    _Field("beta1", ((5, 1, 8),), 2.0 ** 14, True),
    _Field("beta2", ((5, 9, 8),), 2.0 ** 16, True),
    _Field("beta3", ((5, 17, 8),), 2.0 ** 16, True),
    _Field("a1", ((6, 1, 24),), 2.0 ** -50, True),
    _Field("a0", ((7, 1, 24), (8, 1, 8)), 2.0 ** -30, True),
    _Field("tot", ((8, 9, 8),), 2.0 ** 12),
    _Field("wnt", ((8, 17, 8),)),
    _Field("dt_ls", ((9, 1, 8),), 1.0, True),
    _Field("wn_lsf", ((9, 9, 8),)),
    _Field("dn", ((9, 17, 8),)),
    _Field("dt_lsf", ((10, 1, 8),), 1.0, True),
)

#: LSB (in Ephemeris units: s, m, rad, rad/s ...) of every broadcast Ephemeris field
EPH_LSB = {f.name: f.lsb for f in _SF1 + _SF2 + _SF3
           if f.name not in ("wn",)}
#: LSB of the IonoUtc fields (alpha/beta per coefficient)
IONO_LSB = {f.name: f.lsb for f in _P18 if f.name not in ("data_id", "sv_id")}

# subframe 4 page -> SV ID (IS-GPS-200 Table 20-V); pages carrying almanacs use SV ID 0 (dummy)
_SF4_SVID = {1: 57, 2: 25, 3: 26, 4: 27, 5: 28, 6: 57, 7: 29, 8: 30, 9: 31, 10: 32, 11: 57,
             12: 62, 13: 52, 14: 53, 15: 54, 16: 57, 17: 55, 18: 56, 19: 58, 20: 59, 21: 57,
             22: 60, 23: 61, 24: 62, 25: 63}
_ALMANAC_SF4_PAGES = {2, 3, 4, 5, 7, 8, 9, 10}


#: issue-of-data field per subframe 1-3 (one word each): the key of word-by-word assembly across frames
_IOD_KEY = {1: _Field("iodc_lsb", ((8, 1, 8),)), 2: _Field("iode", ((3, 1, 8),)),
            3: _Field("iode", ((10, 1, 8),))}


def _put(words: list, fld: _Field, raw: int):
    """Write the raw (two's complement) integer of a field into the 24-bit data words."""
    n = fld.nbits
    raw &= (1 << n) - 1
    shift = n
    for w, start, nb in fld.chunks:
        shift -= nb
        part = (raw >> shift) & ((1 << nb) - 1)
        pos = 24 - (start - 1) - nb            # bit offset from LSB within the 24-bit word
        words[w - 1] = (words[w - 1] & ~(((1 << nb) - 1) << pos)) | (part << pos)


def _get(words, fld: _Field) -> int:
    raw = 0
    for w, start, nb in fld.chunks:
        pos = 24 - (start - 1) - nb
        raw = (raw << nb) | ((words[w - 1] >> pos) & ((1 << nb) - 1))
    if fld.signed and raw >> (fld.nbits - 1):
        raw -= 1 << fld.nbits
    return raw


def _quantise(fld: _Field, value: float) -> int:
    """Physical value -> integer count (rounded to nearest), range-checked."""
    raw = int(np.round(float(value) / fld.lsb))
    n = fld.nbits
    lo, hi = (-(1 << (n - 1)), (1 << (n - 1)) - 1) if fld.signed else (0, (1 << n) - 1)
    if not lo <= raw <= hi:
        raise ValueError(f"LNAV field {fld.name}={value!r} out of range for {n} bits "
                         f"(LSB {fld.lsb:g})")
    return raw


def _value(fld: _Field, words) -> float:
    return _get(words, fld) * fld.lsb


# ----------------------------------------------------------------------------- encoder

def _tlm_how_words(tow_start: float, sfid: int, alert: int = 0, anti_spoof: int = 1):
    tlm = bits_to_int(PREAMBLE) << 16            # TLM message, integrity flag, reserved: 0
    count = (int(round(tow_start / 6.0)) + 1) % TOW_COUNT_MAX
    how = (count << 7) | ((alert & 1) << 6) | ((anti_spoof & 1) << 5) | ((sfid & 7) << 2)
    return tlm, how


def _sf1_words(eph: Ephemeris, week: int) -> list:
    w = [0] * 10
    vals = dict(wn=week % 1024, code_on_l2=eph.code_on_l2, ura_index=eph.ura_index,
                health=eph.health, iodc=eph.iodc, l2p_flag=eph.l2p_flag)
    for f in _SF1:
        raw = int(vals[f.name]) if f.name in vals else _quantise(f, getattr(eph, f.name))
        if f.name in vals and not 0 <= raw < (1 << f.nbits):
            raise ValueError(f"LNAV field {f.name}={raw} out of range for {f.nbits} bits")
        _put(w, f, raw)
    return w


def _sf2_words(eph: Ephemeris) -> list:
    w = [0] * 10
    for f in _SF2:
        if f.name in ("iode", "fit_interval"):
            raw = int(getattr(eph, f.name))
        elif f.name == "aodo":
            raw = int(round(eph.aodo / 900.0))
        else:
            raw = _quantise(f, getattr(eph, f.name))
        if not f.signed and not 0 <= raw < (1 << f.nbits):
            raise ValueError(f"LNAV field {f.name}={raw} out of range for {f.nbits} bits")
        _put(w, f, raw)
    return w


def _sf3_words(eph: Ephemeris) -> list:
    w = [0] * 10
    for f in _SF3:
        raw = int(eph.iode) if f.name == "iode" else _quantise(f, getattr(eph, f.name))
        if f.name == "iode" and not 0 <= raw < 256:
            raise ValueError(f"LNAV field iode={raw} out of range for 8 bits")
        _put(w, f, raw)
    return w


def _page18_words(iono: IonoUtc) -> list:
    w = [0] * 10
    dt_lsf = iono.dt_ls if iono.dt_lsf is None else iono.dt_lsf
    wn_lsf = iono.wnt if iono.wn_lsf is None else iono.wn_lsf
    dn = 7 if iono.dn is None else iono.dn
    vals = dict(data_id=1, sv_id=56, wnt=int(iono.wnt) % 256, wn_lsf=int(wn_lsf) % 256,
                dn=int(dn), dt_ls=int(iono.dt_ls), dt_lsf=int(dt_lsf))
    for k in range(4):
        vals[f"alpha{k}"] = iono.alpha[k]
        vals[f"beta{k}"] = iono.beta[k]
    vals.update(a0=iono.a0, a1=iono.a1, tot=iono.tot)
    for f in _P18:
        v = vals[f.name]
        raw = int(v) if isinstance(v, (int, np.integer)) and f.lsb == 1.0 else _quantise(f, v)
        _put(w, f, raw)
    # reserved 14 bits of word 10: alternating ones and zeros
    _put(w, _Field("reserved", ((10, 9, 14),)), 0b10101010101010)
    return w


def _dummy_page_words(sv_id: int) -> list:
    """Subframe 4/5 page with data ID 01, the given SV ID and alternating 1/0 data bits."""
    w = [0xAAAAAA] * 10
    _put(w, _Field("data_id", ((3, 1, 2),)), 1)
    _put(w, _Field("sv_id", ((3, 3, 6),)), sv_id)
    w[9] &= ~0x3                                   # t bits, solved at encoding
    return w


def _encode_subframe(words: list, d29s: int, d30s: int):
    """10 data words (24-bit ints, words 1/2 included) -> 300 transmitted bits."""
    out = np.empty(SUBFRAME_BITS, dtype=np.uint8)
    for k, data in enumerate(words):
        word = encode_word(int(data), d29s, d30s, solve_t=k in (1, 9))
        out[k * 30:(k + 1) * 30] = word
        d29s, d30s = int(word[28]), int(word[29])
    return out, d29s, d30s


def subframe45_page(tow_s_of_subframe1_start: float) -> int:
    """Page number 1..25 of subframes 4/5 in the frame starting at this TOW (s)."""
    return int(tow_s_of_subframe1_start // 30) % 25 + 1


def encode_subframes(eph: Ephemeris, iono_utc: IonoUtc | None, tow_s_of_subframe1_start: float,
                     week: int, page18_every_frame: bool = False, alert: int = 0,
                     anti_spoof: int = 1) -> np.ndarray:
    """One 1500-bit LNAV frame (subframes 1..5) as transmitted bits (uint8 0/1).

    tow_s_of_subframe1_start: GPS seconds of week at the start of subframe 1 (a multiple of 6;
    real satellites start frames on multiples of 30).  week: full GPS week of transmission
    (broadcast modulo 1024).  The subframe 4/5 page is (TOW // 30) mod 25 + 1; subframe 4
    page 18 carries ``iono_utc`` (when None, page 18 is a dummy page with SV ID 57), and with
    ``page18_every_frame`` every frame's subframe 4 is page 18.  Other pages are dummies with
    alternating 1/0 data bits (almanac pages use the dummy SV ID 0).
    """
    tow0 = float(tow_s_of_subframe1_start)
    if tow0 < 0 or tow0 >= WEEK_S or abs(tow0 / 6.0 - round(tow0 / 6.0)) > 1e-9:
        raise ValueError(f"subframe 1 start TOW must be a multiple of 6 s in [0, 604800), got {tow0}")
    page = subframe45_page(tow0)
    sf4_page = 18 if page18_every_frame else page
    if sf4_page == 18 and iono_utc is not None:
        sf4 = _page18_words(iono_utc)
    elif sf4_page == 18:
        sf4 = _dummy_page_words(57)
    else:
        sf4 = _dummy_page_words(0 if sf4_page in _ALMANAC_SF4_PAGES else _SF4_SVID[sf4_page])
    sf5 = _dummy_page_words(0 if page <= 24 else 51)
    bodies = [_sf1_words(eph, week), _sf2_words(eph), _sf3_words(eph), sf4, sf5]
    bits = np.empty(FRAME_BITS, dtype=np.uint8)
    d29s = d30s = 0
    for k, body in enumerate(bodies):
        tow_k = (tow0 + 6.0 * k) % WEEK_S
        tlm, how = _tlm_how_words(tow_k, k + 1, alert, anti_spoof)
        body[0], body[1] = tlm, how
        bits[k * 300:(k + 1) * 300], d29s, d30s = _encode_subframe(body, d29s, d30s)
    return bits


def encode_frames(eph: Ephemeris, iono_utc: IonoUtc | None, tow_s_of_first_frame: float, week: int,
                  n_frames: int, page18_every_frame: bool = False) -> np.ndarray:
    """n consecutive frames (n * 1500 bits), handling the end-of-week rollover."""
    out = []
    for k in range(n_frames):
        tow = tow_s_of_first_frame + 30.0 * k
        wk = week + int(tow // WEEK_S)
        out.append(encode_subframes(eph, iono_utc, tow % WEEK_S, wk, page18_every_frame))
    return np.concatenate(out) if out else np.zeros(0, dtype=np.uint8)


# ----------------------------------------------------------------------------- decoder

@dataclass
class SubframeEvent:
    """A subframe with valid TLM/HOW. bit_index: first preamble bit (bits since bit sync);
    tow_s: GPS seconds of week at the start of that subframe; polarity: +1 when positive
    soft values are 0 bits."""
    bit_index: int
    tow_s: float
    subframe_id: int
    polarity: int


@dataclass
class EphemerisEvent:
    """A new complete (IODE/IODC consistent) ephemeris was decoded."""
    bit_index: int
    ephemeris: Ephemeris


@dataclass
class IonoUtcEvent:
    """Subframe 4 page 18 (ionosphere / UTC) decoded."""
    bit_index: int
    iono_utc: IonoUtc


def correct_word(word30, d29s: int, d30s: int):
    """Single-bit error correction of a transmitted word that fails parity: the 30 one-bit flips are
    tried; the parity code (an extended Hamming code shortened to 30 bits, minimum distance 4) makes the
    flip that satisfies the parity unique when one bit is wrong, and no flip succeeds when two are.
    Returns (corrected word D1..D30, flipped bit index 0..29) or None."""
    w = np.asarray(word30, dtype=np.uint8).reshape(30)
    hits = []
    for k in range(30):
        v = w.copy()
        v[k] ^= 1
        if decode_word(v, d29s, d30s)[1]:
            hits.append((v, k))
    return hits[0] if len(hits) == 1 else None


def _decode_subframe_bits(b300: np.ndarray, correct: bool = False):
    """Polarity-corrected 300 bits -> (list of 10 data words (int) or None, list of ok flags).

    The TLM word is checked with D29* = D30* = 0 (word 10 of the previous subframe always
    ends with 00), so each subframe is decodable on its own.  ``correct``: a word failing parity is
    corrected when one flipped bit explains it (:func:`correct_word`; its ok flag is then True and the
    corrected D29/D30 feed the next word); the number of corrected words is the third value returned.
    """
    words, oks = [], []
    d29s = d30s = 0
    n_corr = 0
    fixed = np.array(b300, dtype=np.uint8) if correct else None
    for k in range(10):
        w = b300[k * 30:(k + 1) * 30]
        d, ok = decode_word(w, d29s, d30s)
        if not ok and correct:
            fix = correct_word(w, d29s, d30s)
            if fix is not None:
                w = fix[0]
                fixed[k * 30:(k + 1) * 30] = w
                d, ok = decode_word(w, d29s, d30s)
                n_corr += 1
        words.append(bits_to_int(d) if ok else None)
        oks.append(ok)
        d29s, d30s = int(w[28]), int(w[29])
    if correct:
        return words, oks, n_corr, fixed
    return words, oks


def _check_tlm_how(b: np.ndarray):
    """First 60 polarity-corrected bits of a candidate subframe -> (tow_count, sfid) or None."""
    if not np.array_equal(b[:8], PREAMBLE):
        return None
    tlm, ok1 = decode_word(b[:30], 0, 0)
    if not ok1:
        return None
    how_bits, ok2 = decode_word(b[30:60], int(b[28]), int(b[29]))
    if not ok2 or b[58] or b[59]:
        return None
    how = bits_to_int(how_bits)
    count, sfid = how >> 7, (how >> 2) & 7
    if not 1 <= sfid <= 5 or count >= TOW_COUNT_MAX:
        return None
    return count, sfid


def _tow_from_count(count: int) -> float:
    return float((count * 6 - 6) % int(WEEK_S))


class HeldSet:
    """A suspect ephemeris set waiting for a second reception (the LNAV and BeiDou D1/D2 decoders).
    ``offer(eph, src, same)`` with the reception numbers ``src`` (e.g. bit indices) of the parts the set was
    assembled from: True when the set may be used now — it is the held set again (``same(held, eph)``),
    assembled only from parts received after those of the held one (the next subframe completing the held
    set again with the same corrupted part is no second reception); otherwise ``eph`` is held (a new set:
    ``count`` + 1) or kept waiting, and False is returned.  ``clear()`` once a set is used."""

    def __init__(self):
        self.eph = None
        self.src = -1
        self.count = 0

    def offer(self, eph, src, same) -> bool:
        """True when `eph` may be used now (see the class docstring); otherwise it is held or kept waiting."""
        if self.eph is None or not same(self.eph, eph):
            self.eph, self.src = eph, max(src)
            self.count += 1
            return False
        return min(src) > self.src

    def clear(self) -> None:
        """Forget the held set (once a set is used)."""
        self.eph = None


class LnavDecoder:
    """Per-channel LNAV decoder.

    ``feed(bits, first_bit_index)`` with soft (float, sign = bit) or hard (uint8/bool 0/1)
    bits; ``first_bit_index`` counts 20-ms bits since the channel's bit synchronisation.
    Returns a list of events (SubframeEvent, EphemerisEvent, IonoUtcEvent).  State:
    ``ephemeris`` (latest complete set), ``iono_utc``, ``week`` (full GPS week of the latest
    subframe 1), ``synced``, ``polarity``, ``parity_failures`` (count of words that failed
    parity once in sync and could not be corrected; such words are never used), ``words_corrected``
    (words with one wrong bit, corrected by the parity: weak signals).

    Once in frame sync a word that fails parity is corrected when a single flipped bit explains it
    (:func:`correct_word`), and subframes 1-3 are assembled word by word: the good words of a subframe
    with bad ones are kept and completed by the same subframe of later frames carrying the same issue
    of data (IODC / IODE), so an ephemeris is decoded even when no frame arrives without an error.

    A new ephemeris that puts the satellite more than ``JUMP_M`` away from the current one (position plus
    c x clock, at the new subframe 1's time), or that has the current issue of data (IODE and IODC) with
    other contents, replaces it only when a second reception decodes the same set
    (``ephemerides_held`` counts the held ones): single-bit correction "corrects" any odd-weight error
    pattern, so at low C/N0 a corrupted set can pass parity with the current issue of data (seen at
    27-29 dB-Hz: Omega0 off 2.6 mrad, positions off 73-9866 km; and from the noise a coasting vector
    channel demodulates during a total outage: subframe 2 words after a good IODE word, a satellite
    82 000 km off); a genuine update moves it by metres and comes with a new issue of data.  A second
    reception means subframes 1, 2 and 3 all received after those the held set was built from: the held set
    assembled again when the next subframe 1 or 3 arrives (with the same corrupted subframe 2) is not one.
    A satellite's *first* ephemeris has no set to compare with: ``first_check`` (set by the user, e.g. the
    navigation engine: ``first_check(ephemeris, tow_s, bit_index)`` with the TOW and bit index of the start
    of the subframe that completed it) returning False holds it the same way until a second reception
    decodes the same set (e.g. its range disagrees with the current fix); True or None uses it at once.
    """

    JUMP_M = 300.0              # a replacement ephemeris further than this from the current one needs a repeat

    MAX_MISSES = 3              # consecutive bad TLM/HOW before frame sync is dropped
    KEEP_BITS = 1200            # buffer kept while searching

    def __init__(self, prn: int = 0, week_hint: int | None = None):
        self.prn = int(prn)
        self.week_hint = week_hint
        self.ephemeris: Ephemeris | None = None
        self.iono_utc: IonoUtc | None = None
        self.week: int | None = None
        self.parity_failures = 0
        self.words_ok = 0
        self.synced = False
        self.polarity = 0
        self.last_tow: float | None = None
        self._last_tow_index: int | None = None
        self._bits = np.zeros(0, dtype=np.uint8)
        self._start = 0                 # bit index of self._bits[0]
        self._next: int | None = None   # expected next bit index
        self._search_from = 0
        self._sf_start = 0              # bit index of the next subframe to decode (synced)
        self._misses = 0
        self._sub = {}                  # sfid -> (words, tow, bit_index) of last good subframe 1..3
        self._partial = {}              # sfid -> (issue of data, words with None) of an incomplete 1..3
        self.words_corrected = 0
        self._held = HeldSet()                # a suspect replacement waiting for a second reception
        self.first_check = None               # callable(eph, tow_s, bit_index) -> bool | None (see above)

    @property
    def ephemerides_held(self) -> int:
        """Number of suspect ephemeris sets held for a second reception so far."""
        return self._held.count

    # -- input ---------------------------------------------------------------------------
    def feed(self, bits, first_bit_index: int) -> list:
        """Add bits (soft or hard) starting at bit index `first_bit_index`; returns the events decoded from them.
        Bits already fed are dropped; a gap restarts the buffer (in frame sync the subframe grid is kept)."""
        hard = hard_bits(bits)
        first = int(first_bit_index)
        if self._next is not None and first != self._next:
            if first < self._next:                      # overlap: drop what we already have
                skip = self._next - first
                if skip >= len(hard):
                    return []
                hard, first = hard[skip:], self._next
            else:                                       # gap: restart the buffer
                self._bits = np.zeros(0, dtype=np.uint8)
                self._start = first
                self._search_from = first
                if self.synced:
                    k = -(-(first - self._sf_start) // SUBFRAME_BITS)
                    self._sf_start += max(k, 0) * SUBFRAME_BITS
        if self._next is None:
            self._start = self._search_from = first
        self._bits = np.concatenate([self._bits, hard])
        self._next = first + len(hard)

        events: list = []
        for _ in range(1000):
            if not self.synced and not self._search():
                break
            if self.synced and not self._process(events):
                break
        self._trim()
        return events

    # -- frame synchronisation -----------------------------------------------------------
    def _end(self):
        return self._start + len(self._bits)

    def _slice(self, a, n):
        i = a - self._start
        return self._bits[i:i + n]

    def _search(self) -> bool:
        """Look for a confirmed preamble; True when sync is acquired."""
        b = self._bits
        i0 = max(self._search_from - self._start, 0)
        if len(b) - i0 < 8:
            return False
        win = np.lib.stride_tricks.sliding_window_view(b[i0:], 8)
        pos_match = np.all(win == PREAMBLE, axis=1)
        neg_match = np.all(win == (1 - PREAMBLE), axis=1)
        cands = np.nonzero(pos_match | neg_match)[0]
        end = self._end()
        for c in cands:
            p = self._start + i0 + int(c)
            pol = 1 if pos_match[c] else -1
            if p + 60 > end:
                self._search_from = p
                return False
            sub = self._polar(self._slice(p, 360), pol)
            first = _check_tlm_how(sub[:60])
            if first is None:
                continue
            if len(sub) >= 300 and all(_decode_subframe_bits(sub[:300])[1]):
                return self._acquire(p, pol)
            if len(sub) < 360:
                self._search_from = p
                return False
            second = _check_tlm_how(sub[300:360])
            if second is not None and second[0] == (first[0] + 1) % TOW_COUNT_MAX \
                    and second[1] == first[1] % 5 + 1:
                return self._acquire(p, pol)
        self._search_from = max(self._search_from, end - 7)
        return False

    @staticmethod
    def _polar(b, pol):
        return b if pol > 0 else (1 - b).astype(np.uint8)

    def _acquire(self, p, pol) -> bool:
        self.synced = True
        self.polarity = pol
        self._sf_start = p
        self._misses = 0
        return True

    def _lose_sync(self, failed_start: int):
        self.synced = False
        self.polarity = 0
        self._search_from = failed_start + 1
        self.last_tow = None

    # -- subframe decoding -----------------------------------------------------------------
    def _process(self, events) -> bool:
        """Decode the subframes available in the buffer. False when waiting for bits."""
        while self.synced:
            s = self._sf_start
            if s < self._start:                 # (should not happen) skip what is gone
                self._sf_start += SUBFRAME_BITS * (-(-(self._start - s) // SUBFRAME_BITS))
                continue
            if s + SUBFRAME_BITS > self._end():
                return False
            raw = self._slice(s, SUBFRAME_BITS)
            pol = self.polarity
            b = self._polar(raw, pol)
            if not np.array_equal(b[:8], PREAMBLE) and np.array_equal(b[:8], 1 - PREAMBLE):
                b2 = self._polar(raw, -pol)
                if _check_tlm_how(b2[:60]) is not None:  # half-cycle slip: polarity flipped
                    pol, b = -pol, b2
                    self.polarity = pol
            self._sf_start += SUBFRAME_BITS
            # words with one wrong bit are corrected; TLM/HOW are checked on the corrected bits
            words, oks, n_corr, b = _decode_subframe_bits(b, correct=True)
            self.words_corrected += n_corr
            self.parity_failures += oks.count(False)
            self.words_ok += oks.count(True)
            head = _check_tlm_how(b[:60])
            if head is None:
                self._misses += 1
                if self._misses >= self.MAX_MISSES:
                    self._lose_sync(s)
                    return True
                continue
            self._misses = 0
            count, sfid = head
            tow = _tow_from_count(count)
            if self.last_tow is not None:
                n_sf = (s - self._last_tow_index) // SUBFRAME_BITS
                if float(wrap_week_seconds(tow - self.last_tow - 6.0 * n_sf)) != 0.0:
                    # parity-valid but inconsistent TOW: distrust it and re-anchor on the next
                    self.last_tow = None
                    continue
            self.last_tow, self._last_tow_index = tow, s
            events.append(SubframeEvent(bit_index=s, tow_s=tow, subframe_id=sfid, polarity=pol))
            if all(oks):
                self._partial.pop(sfid, None)
                self._parse(words, sfid, tow, s, events)
            elif sfid in (1, 2, 3):
                merged = self._merge(sfid, words)
                if merged is not None:
                    self._parse(merged, sfid, tow, s, events)
        return True

    def _merge(self, sfid, words):
        """Word-by-word assembly of subframe ``sfid`` (1-3) across frames: ``words`` (None = bad) joins
        the kept partial subframe of the same issue of data; the complete word list, or None."""
        key_fld = _IOD_KEY[sfid]
        if words[key_fld.chunks[0][0] - 1] is None:
            return None                             # no issue of data: nothing to join safely
        iod = _get(words, key_fld)
        prev = self._partial.get(sfid)
        if prev is not None and prev[0] == iod:
            words = [w if w is not None else p for w, p in zip(words, prev[1])]
        if all(w is not None for w in words):
            self._partial.pop(sfid, None)
            return words
        self._partial[sfid] = (iod, words)
        return None

    def _trim(self):
        keep_from = self._sf_start if self.synced else max(self._search_from, self._end() - self.KEEP_BITS)
        keep_from = min(keep_from, self._end())
        cut = keep_from - self._start
        if cut > 0:
            self._bits = self._bits[cut:]
            self._start = keep_from

    # -- parsing -------------------------------------------------------------------------
    def _full_week(self, wn10: int) -> int:
        if self.week_hint is not None:
            base = int(self.week_hint)
            return base + ((wn10 - base + 512) % 1024) - 512
        return 2048 + wn10

    @staticmethod
    def _nearest_week(mod_value: int, modulus: int, ref: int) -> int:
        return ref + ((mod_value - ref + modulus // 2) % modulus) - modulus // 2

    def _parse(self, words, sfid, tow, bit_index, events):
        if sfid in (1, 2, 3):
            self._sub[sfid] = (words, tow, bit_index)
            if sfid == 1:
                self.week = self._full_week(_get(words, _SF1[0]))
            self._assemble(bit_index, events, tow)
        elif sfid == 4:
            data_id = _get(words, _P18[0])
            sv_id = _get(words, _P18[1])
            if data_id == 1 and sv_id == 56:
                iono = self._parse_page18(words)
                if iono != self.iono_utc:
                    self.iono_utc = iono
                    events.append(IonoUtcEvent(bit_index, iono))

    def _parse_page18(self, words) -> IonoUtc:
        v = {f.name: (_get(words, f) if f.lsb == 1.0 else _value(f, words)) for f in _P18}
        ref = self.week if self.week is not None else self.week_hint
        wnt, wn_lsf = v["wnt"], v["wn_lsf"]
        if ref is not None:
            wnt = self._nearest_week(wnt, 256, ref)
            wn_lsf = self._nearest_week(wn_lsf, 256, ref)
        return IonoUtc(alpha=tuple(v[f"alpha{k}"] for k in range(4)),
                       beta=tuple(v[f"beta{k}"] for k in range(4)),
                       a0=v["a0"], a1=v["a1"], tot=v["tot"], wnt=int(wnt), dt_ls=int(v["dt_ls"]),
                       wn_lsf=int(wn_lsf), dn=int(v["dn"]), dt_lsf=int(v["dt_lsf"]))

    def _assemble(self, bit_index, events, tow=None):
        if not all(k in self._sub for k in (1, 2, 3)) or self.week is None:
            return
        w1, tow1, _ = self._sub[1]
        w2, _, _ = self._sub[2]
        w3, _, _ = self._sub[3]
        iodc = _get(w1, _SF1[4])
        iode2 = _get(w2, _SF2[0])
        iode3 = _get(w3, _SF3[7])
        if not (iode2 == iode3 == (iodc & 0xFF)):
            return
        vals = {}
        for fields, w in ((_SF1[1:], w1), (_SF2, w2), (_SF3, w3)):
            for f in fields:
                vals[f.name] = _get(w, f) if f.lsb == 1.0 else _value(f, w)
        toe = vals["toe"]
        week = self.week
        dt = toe - tow1
        if dt < -HALF_WEEK:
            week += 1
        elif dt > HALF_WEEK:
            week -= 1
        eph = Ephemeris(
            prn=self.prn, week=week, toe=toe, toc=vals["toc"], af0=vals["af0"], af1=vals["af1"],
            af2=vals["af2"], tgd=vals["tgd"], iode=int(iode2), iodc=int(iodc),
            sqrt_a=vals["sqrt_a"], e=vals["e"], i0=vals["i0"], omega0=vals["omega0"],
            omega=vals["omega"], m0=vals["m0"], delta_n=vals["delta_n"], idot=vals["idot"],
            omega_dot=vals["omega_dot"], cuc=vals["cuc"], cus=vals["cus"], crc=vals["crc"],
            crs=vals["crs"], cic=vals["cic"], cis=vals["cis"], health=int(vals["health"]),
            ura_index=int(vals["ura_index"]), fit_interval=int(vals["fit_interval"]),
            code_on_l2=int(vals["code_on_l2"]), l2p_flag=int(vals["l2p_flag"]),
            aodo=int(round(vals["aodo"])), tx_time=tow1)
        if eph != self.ephemeris:
            cur = self.ephemeris
            src = [self._sub[k][2] for k in (1, 2, 3)]      # bit indices of the subframes it was built from
            if cur is not None:
                # the same issue of data with other contents is a decoding error in one of the two (the
                # control segment changes IODE / IODC with every upload); a far one is suspect too
                same_iod = eph.iode == cur.iode and eph.iodc == cur.iodc
                suspect = (same_iod and replace(eph, tx_time=cur.tx_time) != cur) or \
                    not self._near(cur, eph, tow1)
            else:
                suspect = self.first_check is not None and self.first_check(eph, tow, bit_index) is False
            if suspect and not self._held.offer(eph, src, lambda h, e: replace(h, tx_time=e.tx_time) == e):
                return
            self._held.clear()
            self.ephemeris = eph
            events.append(EphemerisEvent(bit_index, eph))

    def _near(self, old: Ephemeris, new: Ephemeris, t: float) -> bool:
        from .ephemeris import sat_state
        from .signals import C_LIGHT
        p0, _, c0, _ = sat_state(old, t)
        p1, _, c1, _ = sat_state(new, t)
        return float(np.linalg.norm(p1 - p0)) + C_LIGHT * abs(float(c1 - c0)) <= self.JUMP_M
