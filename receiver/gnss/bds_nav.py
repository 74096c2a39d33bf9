"""BeiDou B1I navigation message (BDS-SIS-ICD-B1I): D1 (MEO/IGSO, 50 bps) and D2 (GEO, 500 bps).

Structure (ICD section 5)
-------------------------
* A subframe is 300 bits = 10 words of 30 bits.  Word 1 holds the preamble 11100010010 (11 bits) and 4
  reserved bits unencoded, then 11 information bits + 4 BCH(15,11) parity bits.  Words 2..10 hold 22
  information bits each: two 11-bit blocks, each BCH(15,11)-encoded (generator g(X) = X^4 + X + 1,
  systematic: 11 information bits then 4 parity bits) and interleaved bit by bit
  (A1 B1 A2 B2 ... A15 B15).  So a subframe carries 224 information bits including the 15 of the
  preamble and the reserved bits.
* After the preamble and 4 reserved bits every subframe has FraID (3 bits, subframe number 1..5) and
  SOW (20 bits, seconds of BDT week).
* D1: frame = 5 subframes = 30 s (6 s per subframe, SOW at the start of each subframe).  Subframes 1..3
  carry the clock, Klobuchar and ephemeris parameters of the satellite (fields below); 4 and 5 carry 24
  almanac pages each (here: page number only, the rest zero: almanac and UTC not modelled).
* D2: frame = 5 subframes = 3 s (0.6 s per subframe); SOW counts at the start of the frame (all five
  subframes carry the same SOW).  Subframe 1 carries the ephemeris over 10 pages (one page per frame,
  Pnum 1..10, 30 s for the whole set); subframes 2..5 (integrity, differential, almanac) are not modelled
  (page number only).

Field order and widths of D1 subframes 1-3 and of D2 subframe 1 pages 1-10 follow the ICD's tables; the
reserved bits that the ICD places between fields of a D2 page are gathered at the end of the page here
(the simulator and this decoder share the layout; a real D2 stream would need those gaps checked against
the ICD tables).  Scale factors (LSBs) are the ICD's.

Time: BDT = GPST - 14 s; BDT week 0 began at GPS week 1356 (2006-01-01).  Decoded SOW values are turned
into GPS time of week for the navigation engine.

Why this module is long: D1 and D2 stay in one module; their BCH coding, interleaving, page layouts and
scale factors are one ICD chapter, shared by the encoder (the simulator's) and the decoder.
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass, field

import numpy as np

from .bds_ephemeris import BDS_PI, BdsEphemeris, BDT_GPS_OFFSET_S, BDT_WEEK_OFFSET, bds_sat_state
from .ephemeris import IonoUtc
from .signals_bds import B1I_HZ
from .lnav import HeldSet, SubframeEvent, hard_bits
from .time import WEEK_S

PREAMBLE = (1, 1, 1, 0, 0, 0, 1, 0, 0, 1, 0)
SUBFRAME_BITS = 300
GPS_UTC_LEAP_S = 18         # GPS-UTC (BDT-UTC 4 s + 14 s) since 2017; subframe 5 UTC page not decoded

# (name, bits, LSB, signed); parts of split fields carry "name@hi" / "name@lo" with their own widths
_HEAD = [("pre", 11, 1, False), ("rev0", 4, 1, False), ("fraid", 3, 1, False), ("sow", 20, 1, False)]
P = math.pi
D1_SF1 = _HEAD + [
    ("sath1", 1, 1, False), ("aodc", 5, 1, False), ("urai", 4, 1, False), ("wn", 13, 1, False),
    ("toc", 17, 2.0 ** 3, False), ("tgd1", 10, 1e-10, True), ("tgd2", 10, 1e-10, True),
    ("alpha0", 8, 2.0 ** -30, True), ("alpha1", 8, 2.0 ** -27, True), ("alpha2", 8, 2.0 ** -24, True),
    ("alpha3", 8, 2.0 ** -24, True), ("beta0", 8, 2.0 ** 11, True), ("beta1", 8, 2.0 ** 14, True),
    ("beta2", 8, 2.0 ** 16, True), ("beta3", 8, 2.0 ** 16, True), ("a2", 11, 2.0 ** -66, True),
    ("a0", 24, 2.0 ** -33, True), ("a1", 22, 2.0 ** -50, True), ("aode", 5, 1, False)]
D1_SF2 = _HEAD + [
    ("delta_n", 16, 2.0 ** -43, True), ("cuc", 18, 2.0 ** -31, True), ("m0", 32, 2.0 ** -31, True),
    ("e", 32, 2.0 ** -33, False), ("cus", 18, 2.0 ** -31, True), ("crc", 18, 2.0 ** -6, True),
    ("crs", 18, 2.0 ** -6, True), ("sqrt_a", 32, 2.0 ** -19, False), ("toe@hi", 2, None, False)]
D1_SF3 = _HEAD + [
    ("toe@lo", 15, None, False), ("i0", 32, 2.0 ** -31, True), ("cic", 18, 2.0 ** -31, True),
    ("omega_dot", 24, 2.0 ** -43, True), ("cis", 18, 2.0 ** -31, True), ("idot", 14, 2.0 ** -43, True),
    ("omega0", 32, 2.0 ** -31, True), ("omega", 32, 2.0 ** -31, True), ("rev1", 1, 1, False)]
D1_SF45 = _HEAD + [("rev1", 1, 1, False), ("pnum", 7, 1, False)]
D2_PAGES = {
    1: [("sath1", 1, 1, False), ("aodc", 5, 1, False), ("urai", 4, 1, False), ("wn", 13, 1, False),
        ("toc", 17, 2.0 ** 3, False), ("tgd1", 10, 1e-10, True), ("tgd2", 10, 1e-10, True)],
    2: [("alpha0", 8, 2.0 ** -30, True), ("alpha1", 8, 2.0 ** -27, True), ("alpha2", 8, 2.0 ** -24, True),
        ("alpha3", 8, 2.0 ** -24, True), ("beta0", 8, 2.0 ** 11, True), ("beta1", 8, 2.0 ** 14, True),
        ("beta2", 8, 2.0 ** 16, True), ("beta3", 8, 2.0 ** 16, True)],
    3: [("a0", 24, 2.0 ** -33, True), ("a1@hi", 4, None, True)],
    4: [("a1@lo", 18, None, True), ("a2", 11, 2.0 ** -66, True), ("aode", 5, 1, False),
        ("delta_n", 16, 2.0 ** -43, True), ("cuc@hi", 14, None, True)],
    5: [("cuc@lo", 4, None, True), ("m0", 32, 2.0 ** -31, True), ("cus", 18, 2.0 ** -31, True),
        ("e@hi", 10, None, False)],
    6: [("e@lo", 22, None, False), ("sqrt_a", 32, 2.0 ** -19, False), ("cic@hi", 10, None, True)],
    7: [("cic@lo", 8, None, True), ("cis", 18, 2.0 ** -31, True), ("toe", 17, 2.0 ** 3, False),
        ("i0@hi", 21, None, True)],
    8: [("i0@lo", 11, None, True), ("crc", 18, 2.0 ** -6, True), ("crs", 18, 2.0 ** -6, True),
        ("omega_dot@hi", 19, None, True)],
    9: [("omega_dot@lo", 5, None, True), ("omega0", 32, 2.0 ** -31, True), ("omega@hi", 14, None, True)],
    10: [("omega@lo", 18, None, True), ("idot", 14, 2.0 ** -43, True)],
}
#: the scale and width of split fields (the whole value)
SPLIT = {"toe": (17, 2.0 ** 3, False), "a1": (22, 2.0 ** -50, True), "cuc": (18, 2.0 ** -31, True),
         "e": (32, 2.0 ** -33, False), "cic": (18, 2.0 ** -31, True), "i0": (32, 2.0 ** -31, True),
         "omega_dot": (24, 2.0 ** -43, True), "omega": (32, 2.0 ** -31, True)}
_SEMICIRCLE = {"delta_n", "m0", "i0", "omega_dot", "idot", "omega0", "omega"}   # x pi (rad)

#: broadcast name -> (BdsEphemeris attribute, LSB in SI units: rad for the semicircle fields)
EPH_LSB = {
    "toc": ("toc", 2.0 ** 3), "toe": ("toe", 2.0 ** 3), "tgd1": ("tgd", 1e-10), "tgd2": ("tgd2", 1e-10),
    "a0": ("af0", 2.0 ** -33), "a1": ("af1", 2.0 ** -50), "a2": ("af2", 2.0 ** -66),
    "delta_n": ("delta_n", 2.0 ** -43 * BDS_PI), "cuc": ("cuc", 2.0 ** -31), "m0": ("m0", 2.0 ** -31 * BDS_PI),
    "e": ("e", 2.0 ** -33), "cus": ("cus", 2.0 ** -31), "crc": ("crc", 2.0 ** -6), "crs": ("crs", 2.0 ** -6),
    "sqrt_a": ("sqrt_a", 2.0 ** -19), "i0": ("i0", 2.0 ** -31 * BDS_PI), "cic": ("cic", 2.0 ** -31),
    "omega_dot": ("omega_dot", 2.0 ** -43 * BDS_PI), "cis": ("cis", 2.0 ** -31),
    "idot": ("idot", 2.0 ** -43 * BDS_PI), "omega0": ("omega0", 2.0 ** -31 * BDS_PI),
    "omega": ("omega", 2.0 ** -31 * BDS_PI)}


def d2_page_fields(page: int):
    """Field layout (name, bits, LSB, signed) of D2 subframe 1, page `page`: head, Pnum, then the page's fields."""
    return _HEAD + [("pnum", 4, 1, False)] + D2_PAGES[page]


# ------------------------------------------------------------------------------------------------ BCH
_G = 0b10011                 # g(X) = X^4 + X + 1


def _bch_parity(info11: int) -> int:
    r = info11 << 4
    for k in range(14, 3, -1):
        if r >> k & 1:
            r ^= _G << (k - 4)
    return r & 0xF


#: syndrome -> bit position (0 = first transmitted bit of the 15) of a single error
_SYNDROME = {}
for _pos in range(15):
    _cw = 1 << (14 - _pos)
    _r = _cw
    for _k in range(14, 3, -1):
        if _r >> _k & 1:
            _r ^= _G << (_k - 4)
    _SYNDROME[_r & 0xF] = _pos


def bch_encode(info11: int) -> int:
    """15-bit codeword (info in the 11 high bits, parity in the 4 low bits)."""
    return (info11 << 4) | _bch_parity(info11)


def bch_decode(cw15: int) -> tuple[int, bool]:
    """(11 information bits, corrected) of a received 15-bit word; one bit error is corrected."""
    s = _bch_parity(cw15 >> 4) ^ (cw15 & 0xF)
    if s:
        cw15 ^= 1 << (14 - _SYNDROME[s])
    return cw15 >> 4, bool(s)


def _to_int(bits) -> int:
    v = 0
    for b in bits:
        v = (v << 1) | int(b)
    return v


def _to_bits(v: int, n: int):
    return [(v >> (n - 1 - k)) & 1 for k in range(n)]


def encode_words(info224) -> np.ndarray:
    """224 information bits -> the 300 transmitted bits of a subframe."""
    info = list(info224)
    assert len(info) == 224
    out = info[:15] + _to_bits(bch_encode(_to_int(info[15:26])), 15)
    for w in range(9):
        blk = info[26 + 22 * w: 48 + 22 * w]
        a = _to_bits(bch_encode(_to_int(blk[:11])), 15)
        b = _to_bits(bch_encode(_to_int(blk[11:])), 15)
        out += [x for pair in zip(a, b) for x in pair]
    return np.array(out, np.uint8)


def decode_words(bits300) -> tuple[list, int]:
    """300 received hard bits -> (224 information bits, number of corrected BCH blocks)."""
    b = [int(x) for x in bits300]
    info, fixed = b[:15], 0
    v, c = bch_decode(_to_int(b[15:30]))
    info += _to_bits(v, 11)
    fixed += c
    for w in range(9):
        word = b[30 + 30 * w: 60 + 30 * w]
        for blk in (word[0::2], word[1::2]):
            v, c = bch_decode(_to_int(blk))
            info += _to_bits(v, 11)
            fixed += c
    return info, fixed


# -------------------------------------------------------------------------------------- field packing
def _raw(value: float, n: int, lsb: float, signed: bool) -> int:
    r = int(round(value / lsb))
    lo, hi = (-(1 << (n - 1)), (1 << (n - 1)) - 1) if signed else (0, (1 << n) - 1)
    if not lo <= r <= hi:
        raise ValueError(f"value {value!r} does not fit {n} bits of LSB {lsb:g}")
    return r & ((1 << n) - 1)


def _pack(layout, values: dict) -> list:
    bits = []
    for name, n, lsb, signed in layout:
        if "@" in name:
            base, part = name.split("@")
            nn, l2, sg = SPLIT[base]
            full = _raw(values[base], nn, l2, sg)
            lo_bits = nn - n if part == "hi" else n
            v = full >> lo_bits if part == "hi" else full & ((1 << n) - 1)
        elif name == "pre":
            v = _to_int(PREAMBLE)
        elif name in values:
            v = _raw(values[name], n, lsb, signed)
        else:
            v = 0                                   # reserved
        bits += _to_bits(v, n)
    bits += [0] * (224 - len(bits))
    return bits


def _unpack(layout, info) -> dict:
    out, parts, k = {}, {}, 0
    for name, n, lsb, signed in layout:
        raw = _to_int(info[k:k + n])
        k += n
        if "@" in name:
            base, part = name.split("@")
            parts.setdefault(base, {})[part] = (raw, n)
            continue
        if signed and raw >> (n - 1):
            raw -= 1 << n
        out[name] = raw * lsb if lsb not in (None, 1) else raw
    for base, pp in parts.items():
        out["_part_" + base] = pp
    return out


def _join(parts_hi, parts_lo, base):
    nn, lsb, signed = SPLIT[base]
    (hi, _), (lo, nl) = parts_hi, parts_lo
    raw = (hi << nl) | lo
    if signed and raw >> (nn - 1):
        raw -= 1 << nn
    return raw * lsb


def eph_values(eph: BdsEphemeris, iono: IonoUtc | None) -> dict:
    """Broadcast values (ICD units: semicircles for the angles) of an ephemeris and Klobuchar set."""
    v = {"sath1": eph.health, "aodc": eph.iodc, "urai": eph.ura_index, "wn": eph.week % 8192,
         "toc": eph.toc, "toe": eph.toe, "tgd1": eph.tgd, "tgd2": eph.tgd2, "a0": eph.af0, "a1": eph.af1,
         "a2": eph.af2, "aode": eph.iode, "e": eph.e, "sqrt_a": eph.sqrt_a, "cuc": eph.cuc, "cus": eph.cus,
         "crc": eph.crc, "crs": eph.crs, "cic": eph.cic, "cis": eph.cis}
    for name in _SEMICIRCLE:
        v[name] = getattr(eph, name) / BDS_PI
    if iono is not None:
        for k in range(4):
            v[f"alpha{k}"] = iono.alpha[k]
            v[f"beta{k}"] = iono.beta[k]
    return v


def quantize_bds(eph: BdsEphemeris) -> BdsEphemeris:
    """The ephemeris as decoded from the message (every field on its LSB grid, the 32-bit angles wrapped
    into [-1, 1) semicircle as the message holds them)."""
    from dataclasses import replace
    vals = {}
    for attr, lsb in EPH_LSB.values():
        raw = int(np.round(float(getattr(eph, attr)) / lsb))
        if attr in ("m0", "omega0", "omega", "i0"):            # 32-bit semicircles: [-1, 1) semicircle
            raw = (raw + (1 << 31)) % (1 << 32) - (1 << 31)
        vals[attr] = float(raw * lsb)
    return replace(eph, **vals)


# ---------------------------------------------------------------------------------------- subframes
def bdt_from_gps(gps_week: int, gps_tow: float) -> tuple[int, float]:
    """(BDT week, BDT seconds of week) of a GPS time."""
    t = gps_tow - BDT_GPS_OFFSET_S
    wk = gps_week - BDT_WEEK_OFFSET
    while t < 0:
        t += WEEK_S
        wk -= 1
    while t >= WEEK_S:
        t -= WEEK_S
        wk += 1
    return wk, t


def gps_from_bdt(bdt_week: int, sow: float) -> tuple[int, float]:
    """(GPS week, GPS seconds of week) of a BDT time."""
    t = sow + BDT_GPS_OFFSET_S
    wk = bdt_week + BDT_WEEK_OFFSET
    if t >= WEEK_S:
        t -= WEEK_S
        wk += 1
    return wk, t


def d1_subframe(values: dict, fraid: int, sow: int, page: int = 1) -> np.ndarray:
    """The 300 transmitted bits of D1 subframe `fraid` at SOW `sow` (s) from the broadcast `values` (field name ->
    value in ICD units, see :func:`eph_values`); subframes 4 and 5 carry only page number `page`."""
    layout = {1: D1_SF1, 2: D1_SF2, 3: D1_SF3}.get(fraid, D1_SF45)
    return encode_words(_pack(layout, {**values, "fraid": fraid, "sow": sow, "pnum": page}))


def d2_subframe(values: dict, fraid: int, sow: int, page: int) -> np.ndarray:
    """The 300 transmitted bits of D2 subframe `fraid`, page `page`, at SOW `sow` (s) from the broadcast
    `values` (as for :func:`d1_subframe`); subframes 2-5 carry only the page number."""
    layout = d2_page_fields(page) if fraid == 1 else _HEAD + [("pnum", 4, 1, False)]
    return encode_words(_pack(layout, {**values, "fraid": fraid, "sow": sow, "pnum": page}))


class BdsNavBits:
    """The simulator's D1 or D2 stream of one satellite: +/-1 per 1-ms code period (NH x D1 bit, or D2
    symbol) for a span of satellite time, from its (quantised) ephemeris and the Klobuchar set."""

    def __init__(self, eph: BdsEphemeris, iono: IonoUtc | None, gps_week: int, geo: bool, data: bool = True):
        self.values = eph_values(eph, iono)
        self.gps_week = gps_week
        self.geo = geo
        self.data = data
        self._cache: dict[int, np.ndarray] = {}

    def _subframe(self, k: int) -> np.ndarray:
        """Bits of subframe k (counted from BDT week 0 of the scenario's week)."""
        sf = self._cache.get(k)
        if sf is None:
            if self.geo:                       # 0.6 s subframes, frame of 5 = 3 s, SOW at the frame start
                frame = k // 5
                fraid = k % 5 + 1
                sf = d2_subframe(self.values, fraid, int((frame * 3) % WEEK_S), frame % 10 + 1)
            else:                              # 6 s subframes, frame of 5 = 30 s
                frame = k // 5
                fraid = k % 5 + 1
                sf = d1_subframe(self.values, fraid, int((k * 6) % WEEK_S), frame % 24 + 1)
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[k] = sf
        return sf

    def signs(self, first_ms: int, count: int) -> np.ndarray:
        """+/-1 per code period of satellite (GPS) time first_ms .. first_ms+count-1, ms of the GPS week
        of the scenario (may run past the week)."""
        ms = np.int64(first_ms) + np.arange(count, dtype=np.int64)
        bdt_ms = ms - BDT_GPS_OFFSET_S * 1000           # ms since the start of the BDT week
        out = np.ones(count, np.float32)
        if self.data:
            sym_ms = 2 if self.geo else 20
            sf_ms = 600 if self.geo else 6000
            sym = bdt_ms // sym_ms
            k = bdt_ms // sf_ms
            bit_in = (sym - k * (sf_ms // sym_ms)).astype(np.int64)
            bits = np.empty(count, np.uint8)
            for kk in np.unique(k):
                sel = k == kk
                bits[sel] = self._subframe(int(kk))[bit_in[sel]]
            out *= (1.0 - 2.0 * bits).astype(np.float32)
        if not self.geo:
            from .signals_bds import nh_signs
            out *= nh_signs()[bdt_ms % 20]
        return out


# ------------------------------------------------------------------------------------------ decoding
@dataclass
class _Frame:
    fraid: int
    sow: int
    fields: dict = field(default_factory=dict)


class BdsDecoder:
    """Per-channel D1 / D2 decoder with the LnavDecoder interface used by the navigation engine.

    ``feed(bits, first_bit_index)``: soft (float, negative = 1) or hard bits, indices counting data bits
    (D1, 20 ms) or symbols (D2, 2 ms) since bit synchronisation.  Frame sync: the preamble (either
    polarity) followed 300 bits later by the next subframe's preamble with a consistent FraID and SOW.
    Events: :class:`receiver.gnss.lnav.SubframeEvent` with the GPS time of week of the subframe start.
    State: ``ephemeris`` (BdsEphemeris, BDT toe/toc/week), ``iono_utc`` (Klobuchar), ``week`` (GPS week),
    ``parity_failures`` (BCH blocks corrected), ``synced``, ``polarity``, ``ephemerides_held``.

    A new ephemeris that puts the satellite more than ``JUMP_M`` away from the current one (position plus
    c x clock, at the new set's toe) replaces it only when a second reception decodes the same set: the
    BCH(15,11) decoder corrects one error per block, so two errors in a block are "corrected" into a third
    and a corrupted set can pass at low C/N0 (as with GPS LNAV's single-bit correction); a genuine update
    moves the satellite by metres.  A set with the current issue of data (toe, AODE, AODC) and other contents
    is held the same way (the data is uploaded with a new toe).  A second reception means every subframe
    (D1) or page (D2) of the set received after those the held set was built from: the held set assembled
    again when the next subframe completes it with the same corrupted part is not one.
    """
    MAX_MISSES = 3
    JUMP_M = 300.0

    def __init__(self, prn: int, week_hint: int | None = None, geo: bool = False):
        self.prn = int(prn)
        self.geo = geo
        self.week_hint = week_hint
        self.ephemeris: BdsEphemeris | None = None
        self.iono_utc: IonoUtc | None = None
        self.week: int | None = None
        self.parity_failures = 0
        self._held = HeldSet()                   # a suspect replacement waiting for a second reception
        self._seq = 0                            # reception number of the last stored subframe / page
        self.synced = False
        self.polarity = 0
        self._bits = np.zeros(0, np.uint8)
        self._start = 0
        self._next = None
        self._misses = 0
        self._sf_start = None
        self._sub: dict = {}          # D1: fraid -> fields; D2: page -> fields
        self._sub_sow: dict = {}
        self._sub_seq: dict = {}      # its reception number (self._seq)

    @property
    def ephemerides_held(self) -> int:
        """Number of suspect ephemeris sets held for a second reception so far."""
        return self._held.count

    def feed(self, bits, first_bit_index: int) -> list:
        """Add bits (D1) or symbols (D2), soft or hard, starting at index `first_bit_index`; returns the events
        decoded from them.  A gap drops the buffer and frame sync."""
        hard = hard_bits(bits)
        if self._next is not None and first_bit_index != self._next:
            self._bits = np.zeros(0, np.uint8)        # gap: start over (sync kept only with continuity)
            self._start = first_bit_index
            self.synced = False
            self._sf_start = None
        if len(self._bits) == 0:
            self._start = first_bit_index
        self._bits = np.concatenate([self._bits, hard])
        self._next = first_bit_index + len(hard)
        events = []
        while True:
            if not self.synced:
                if not self._search():
                    break
            ev = self._decode_next()
            if ev is None:
                break
            events.append(ev)
        # keep a bounded buffer
        keep_from = (self._sf_start - self._start) if self.synced else max(0, len(self._bits) - 2 * SUBFRAME_BITS)
        if keep_from > 0:
            self._bits = self._bits[keep_from:]
            self._start += keep_from
        return events

    def _header(self, k: int, pol: int):
        """(fraid, sow, info) of the subframe at buffer offset k read with polarity pol, or None."""
        seg = self._bits[k:k + SUBFRAME_BITS]
        if len(seg) < SUBFRAME_BITS:
            return None
        if pol < 0:
            seg = 1 - seg
        if tuple(seg[:11]) != PREAMBLE:
            return None
        info, fixed = decode_words(seg)
        fraid = _to_int(info[15:18])
        sow = _to_int(info[18:38])
        if not 1 <= fraid <= 5 or sow >= WEEK_S:
            return None
        return fraid, sow, info, fixed

    def _consistent(self, a, b) -> bool:
        fa, sa = a[0], a[1]
        fb, sb = b[0], b[1]
        if fb != fa % 5 + 1:
            return False
        if self.geo:
            return sb == (sa + 3) % WEEK_S if fa == 5 else sb == sa
        return sb == (sa + 6) % WEEK_S

    def _search(self) -> bool:
        n = len(self._bits)
        pre = np.array(PREAMBLE, np.uint8)
        for k in range(0, n - 2 * SUBFRAME_BITS + 11 + 1):
            seg = self._bits[k:k + 11]
            for pol in (1, -1):
                if not np.array_equal(seg if pol > 0 else 1 - seg, pre):
                    continue
                a = self._header(k, pol)
                if a is None:
                    continue
                nxt = self._bits[k + SUBFRAME_BITS:k + SUBFRAME_BITS + 11]
                if not np.array_equal(nxt if pol > 0 else 1 - nxt, pre):
                    continue
                if k + 2 * SUBFRAME_BITS > n:
                    # the next preamble is there but its header is not complete yet: wait
                    self._bits = self._bits[k:]
                    self._start += k
                    return False
                b = self._header(k + SUBFRAME_BITS, pol)
                if b is None or not self._consistent(a, b):
                    continue
                self.synced, self.polarity, self._misses = True, pol, 0
                self._sf_start = self._start + k
                return True
        return False

    def _decode_next(self):
        k = self._sf_start - self._start
        if k + SUBFRAME_BITS > len(self._bits):
            return None
        h = self._header(k, self.polarity)
        self._sf_start += SUBFRAME_BITS
        if h is None:
            self._misses += 1
            if self._misses >= self.MAX_MISSES:
                self.synced = False
                self._sf_start = None
            return None if not self.synced else self._decode_next()
        self._misses = 0
        fraid, sow, info, fixed = h
        self.parity_failures += fixed
        start_bdt = sow + (0.6 * (fraid - 1) if self.geo else 0.0)
        self._store(fraid, sow, info)
        tow = (start_bdt + BDT_GPS_OFFSET_S) % WEEK_S
        return SubframeEvent(bit_index=self._sf_start - SUBFRAME_BITS, tow_s=float(tow),
                             subframe_id=fraid, polarity=self.polarity)

    def _store(self, fraid, sow, info):
        if self.geo:
            if fraid != 1:
                return
            page = _to_int(info[38:42])
            if page not in D2_PAGES:
                return
            self._sub[page] = _unpack(d2_page_fields(page), info)
            self._sub_sow[page] = sow
            self._seq += 1
            self._sub_seq[page] = self._seq
            if page == 2:
                self._set_iono(self._sub[2])
            if len(self._sub) == 10:
                self._assemble_d2()
        else:
            if fraid > 3:
                return
            self._sub[fraid] = _unpack({1: D1_SF1, 2: D1_SF2, 3: D1_SF3}[fraid], info)
            self._sub_sow[fraid] = sow
            self._seq += 1
            self._sub_seq[fraid] = self._seq
            if fraid == 1:
                self._set_iono(self._sub[1])
            if len(self._sub) == 3:
                self._assemble_d1()

    @staticmethod
    def _near(old: BdsEphemeris, new: BdsEphemeris) -> bool:
        from .signals import C_LIGHT
        t = np.array([new.toe + BDT_GPS_OFFSET_S])     # GPS seconds of week of the new set's toe
        p0, _, c0, _ = bds_sat_state([old], t)
        p1, _, c1, _ = bds_sat_state([new], t)
        return float(np.linalg.norm(p1[0] - p0[0])) + C_LIGHT * abs(float(c1[0] - c0[0])) <= BdsDecoder.JUMP_M

    def _set_iono(self, f):
        self.iono_utc = IonoUtc(alpha=tuple(f[f"alpha{k}"] for k in range(4)),
                                beta=tuple(f[f"beta{k}"] for k in range(4)),
                                wnt=self.week or 0, dt_ls=GPS_UTC_LEAP_S, ref_hz=B1I_HZ)

    def _assemble_d1(self):
        s1, s2, s3 = self._sub[1], self._sub[2], self._sub[3]
        if self._sub_sow[3] - self._sub_sow[2] != 6:      # toe is split over subframes 2 and 3
            return
        toe = _join(s2["_part_toe"]["hi"], s3["_part_toe"]["lo"], "toe")
        if toe != s1["toc"]:
            return
        self._make(s1, {**s2, **s3, "toe": toe})

    def _assemble_d2(self):
        p = self._sub
        f = {}
        for page in range(1, 11):
            f.update({k: v for k, v in p[page].items() if not k.startswith("_")})
        parts = {}
        for page in range(1, 11):
            for k, v in p[page].items():
                if k.startswith("_part_"):
                    parts.setdefault(k[6:], {}).update(v)
        for base, pp in parts.items():
            if "hi" in pp and "lo" in pp:
                f[base] = _join(pp["hi"], pp["lo"], base)
        if f.get("toe") != f.get("toc"):
            return
        self._make(f, f)

    def _make(self, clk, orb):
        wn = int(clk["wn"])
        semi = {k: orb[k] * BDS_PI for k in _SEMICIRCLE}
        eph = BdsEphemeris(
            prn=self.prn, week=wn, toe=float(orb["toe"]), toc=float(clk["toc"]), af0=clk["a0"], af1=clk["a1"],
            af2=clk["a2"], tgd=clk["tgd1"], iode=int(clk["aode"]), iodc=int(clk["aodc"]),
            sqrt_a=orb["sqrt_a"], e=orb["e"], i0=semi["i0"], omega0=semi["omega0"], omega=semi["omega"],
            m0=semi["m0"], delta_n=semi["delta_n"], idot=semi["idot"], omega_dot=semi["omega_dot"],
            cuc=orb["cuc"], cus=orb["cus"], crc=orb["crc"], crs=orb["crs"], cic=orb["cic"], cis=orb["cis"],
            health=int(clk["sath1"]), ura_index=int(clk["urai"]), tgd2=clk["tgd2"])
        if eph == self.ephemeris:
            return
        cur = self.ephemeris
        src = list(self._sub_seq.values())           # reception numbers of the parts it was built from
        suspect = cur is not None and ((eph.toe, eph.iode, eph.iodc) == (cur.toe, cur.iode, cur.iodc)
                                       or not self._near(cur, eph))
        if suspect and not self._held.offer(eph, src, operator.eq):
            return
        self._held.clear()
        self.week = wn + BDT_WEEK_OFFSET
        self.ephemeris = eph
        if self.iono_utc is not None:
            self.iono_utc.wnt = self.week
