"""Galileo I/NAV navigation message on E1-B (Galileo OS SIS ICD issue 1.1, sections 4.1, 4.3 and 5.1):
encoder (for the simulator and round-trip tests) and decoder.  The page coding (sync, CRC-24Q, convolutional
code and Viterbi decoder, interleaver, page parts) is receiver.gnss.gal_pages, re-exported here.

Page part (ICD 4.3.2, Table 38): 10 sync symbols ``0101100000`` (not encoded) + 240 symbols = 250 symbols,
1 s at 250 sym/s.  The 240 symbols are 114 information bits + 6 zero tail bits, convolutionally encoded
(K = 7, rate 1/2, G1 = 171o then G2 = 133o, the G2 output inverted; ICD Table 27 / Figure 13) and block
interleaved (30 columns x 8 rows, ICD Table 28: written column by column, read row by row).  The encoder
starts each page part in the zero state and the tail returns it there.

Nominal page (ICD Table 39, E1-B): an even part (even/odd = 0, page type 0, word bits 1-112) followed one
second later by an odd part (even/odd = 1, page type 0, word bits 113-128, reserved 1 (40), SAR (22), spare
(2), CRC (24), reserved 2 (8)).  The CRC-24Q (ICD 5.1.9.4: G(X) = (1 + X) P(X)) covers the 196 bits
even part bits 1-114 + odd part bits 1-82.  A word is 128 bits, its first 6 bits the word type.

Word types decoded (ICD 4.3.5): 1-4 ephemeris, clock, SISA, SVID; 5 NeQuick-G coefficients ai0..ai2 and
storm flags, BGDs, health and data validity, WN and TOW; 6 GST-UTC and TOW; 10 GST-GPS offset (GGTO);
0 spare word (WN and TOW when its Time field is 2).  Almanacs (7-9 and the almanac half of 10) are not
decoded; the encoder sends spare words in the slots of words 7-9 and zero almanac fields in word 10.

Sub-frame (ICD Table 41, E1-B column; T0 = GST seconds modulo 30 at the start of the page): pages start at
odd seconds: 1 word 2, 3 word 4, 5 word 6, 7 word 7 or 9, 9 word 8 or 10, 11-19 reserved (spare words
here), 21 word 1, 23 word 3, 25 word 5, 27 and 29 spare words.  Words 7/8 in the even sub-frames of the
720-s frame (GST TOW / 30 even), 9/10 in the odd ones (ICD Table 42).

Time (ICD 5.1.2): the TOW of a page is the GST at the first symbol of the page (the first sync symbol of its
even part).  GST week 0 began at GPS week 1024 (1999-08-22) and GST seconds of week run with GPS seconds of
week; the GGTO (word 10) is the nanosecond-level offset t_GST - t_GPS (ICD Eq. 21).

Why this module is long: the word layouts and scale factors, the ephemeris and time records, the sub-frame
schedule, the encoder (the simulator's) and the decoder are one ICD chapter (4.3) and share the same tables;
split apart, each part would import the others' (as receiver.gnss.lnav and receiver.gnss.bds_nav).
"""
from __future__ import annotations

import operator
from dataclasses import dataclass, field, replace

import numpy as np

from .ephemeris import Ephemeris
from .lnav import HeldSet, SubframeEvent, bits_to_int, hard_bits, int_to_bits
from .time import HALF_WEEK, WEEK_S
# the page coding (receiver.gnss.gal_pages) is part of the I/NAV API: re-exported here
from .gal_pages import (_SYNC_ARR, CODED_SYMBOLS, CRC24_POLY, CRC_BITS, G1, G2, INFO_BITS, K,  # noqa: F401
                        N_COLS, N_ROWS, PART_BITS, PART_SYMBOLS, SYNC, SYNC_LEN, TAIL_BITS,  # noqa: F401
                        WORD_BITS, conv_encode, crc24q, decode_part, deinterleave, encode_part,  # noqa: F401
                        interleave, page_parts, page_word, viterbi_decode)  # noqa: F401

GST_WEEK_OFFSET = 1024       # GPS week of GST week 0
GAL_PI = 3.1415926535898     # ICD Table 62
MU_GAL = 3.986004418e14
OMEGA_E_GAL = 7.2921151467e-5
F_REL_GAL = -4.442807309e-10

# -------------------------------------------------------------------------------------------- words
# (name, bits, LSB, signed); "" = reserved / spare (zero); angles in semicircles
_SC = "semicircle"
WORD_LAYOUT = {
    1: [("iodnav", 10, 1, False), ("toe", 14, 60, False), ("m0", 32, 2.0 ** -31, True),
        ("e", 32, 2.0 ** -33, False), ("sqrt_a", 32, 2.0 ** -19, False), ("", 2, 1, False)],
    2: [("iodnav", 10, 1, False), ("omega0", 32, 2.0 ** -31, True), ("i0", 32, 2.0 ** -31, True),
        ("omega", 32, 2.0 ** -31, True), ("idot", 14, 2.0 ** -43, True), ("", 2, 1, False)],
    3: [("iodnav", 10, 1, False), ("omega_dot", 24, 2.0 ** -43, True), ("delta_n", 16, 2.0 ** -43, True),
        ("cuc", 16, 2.0 ** -29, True), ("cus", 16, 2.0 ** -29, True), ("crc", 16, 2.0 ** -5, True),
        ("crs", 16, 2.0 ** -5, True), ("sisa", 8, 1, False)],
    4: [("iodnav", 10, 1, False), ("svid", 6, 1, False), ("cic", 16, 2.0 ** -29, True),
        ("cis", 16, 2.0 ** -29, True), ("toc", 14, 60, False), ("af0", 31, 2.0 ** -34, True),
        ("af1", 21, 2.0 ** -46, True), ("af2", 6, 2.0 ** -59, True), ("", 2, 1, False)],
    5: [("ai0", 11, 2.0 ** -2, False), ("ai1", 11, 2.0 ** -8, True), ("ai2", 14, 2.0 ** -15, True),
        ("sf1", 1, 1, False), ("sf2", 1, 1, False), ("sf3", 1, 1, False), ("sf4", 1, 1, False),
        ("sf5", 1, 1, False), ("bgd_e1e5a", 10, 2.0 ** -32, True), ("bgd_e1e5b", 10, 2.0 ** -32, True),
        ("e5b_hs", 2, 1, False), ("e1b_hs", 2, 1, False), ("e5b_dvs", 1, 1, False), ("e1b_dvs", 1, 1, False),
        ("wn", 12, 1, False), ("tow", 20, 1, False), ("", 23, 1, False)],
    6: [("a0", 32, 2.0 ** -30, True), ("a1", 24, 2.0 ** -50, True), ("dt_ls", 8, 1, True),
        ("tot", 8, 3600, False), ("wnot", 8, 1, False), ("wn_lsf", 8, 1, False), ("dn", 3, 1, False),
        ("dt_lsf", 8, 1, True), ("tow", 20, 1, False), ("", 3, 1, False)],
    10: [("iod_a", 4, 1, False), ("", 16 + 11 + 16 + 16 + 13 + 2 + 2, 1, False),   # almanac SVID3 (2/2)
         ("a0g", 16, 2.0 ** -35, True), ("a1g", 12, 2.0 ** -51, True), ("t0g", 8, 3600, False),
         ("wn0g", 6, 1, False)],
    0: [("time", 2, 1, False), ("", 88, 1, False), ("wn", 12, 1, False), ("tow", 20, 1, False)],
}
for _t, _lay in WORD_LAYOUT.items():
    assert 6 + sum(n for _, n, _, _ in _lay) == WORD_BITS, _t
SEMICIRCLE_FIELDS = ("m0", "omega0", "i0", "omega", "idot", "omega_dot", "delta_n")
#: the LSB of each ephemeris / clock field in the units of :class:`GalEphemeris` (rad for the angles)
EPH_LSB = {name: lsb * (GAL_PI if name in SEMICIRCLE_FIELDS else 1.0)
           for t in (1, 2, 3, 4) for name, n, lsb, _ in WORD_LAYOUT[t] if name not in ("", "iodnav", "svid",
                                                                                        "sisa")}


def _raw(value, n: int, lsb: float, signed: bool, name: str) -> int:
    r = int(round(float(value) / lsb))
    lo, hi = (-(1 << (n - 1)), (1 << (n - 1)) - 1) if signed else (0, (1 << n) - 1)
    if not lo <= r <= hi:
        raise ValueError(f"I/NAV field {name} = {value!r} does not fit {n} bits of LSB {lsb:g}")
    return r & ((1 << n) - 1)


def pack_word(wtype: int, values: dict) -> np.ndarray:
    """Word type + field values (ICD units, angles in semicircles; missing fields zero) -> 128 bits."""
    bits = [int_to_bits(wtype, 6)]
    for name, n, lsb, signed in WORD_LAYOUT[wtype]:
        v = _raw(values.get(name, 0), n, lsb, signed, name) if name else 0
        bits.append(int_to_bits(v, n))
    return np.concatenate(bits).astype(np.uint8)


def word_type(word128) -> int:
    """The word type of a 128-bit I/NAV word (its first 6 bits)."""
    return bits_to_int(np.asarray(word128)[:6])


def unpack_word(word128) -> dict:
    """128 bits -> {"type": t, field: value in ICD units}; a type without a layout gives the type alone."""
    w = np.asarray(word128, np.uint8)
    t = bits_to_int(w[:6])
    out = {"type": t}
    k = 6
    for name, n, lsb, signed in WORD_LAYOUT.get(t, []):
        raw = bits_to_int(w[k:k + n])
        k += n
        if not name:
            continue
        if signed and raw >> (n - 1):
            raw -= 1 << n
        out[name] = raw * lsb if lsb != 1 else raw
    return out


# ------------------------------------------------------------------------------------- data classes
@dataclass
class GalEphemeris(Ephemeris):
    """A Galileo I/NAV ephemeris + clock set (E1,E5b clock model).  ``week`` is the GPS week of ``toe``
    (GST week + 1024: GST seconds of week run with GPS seconds of week), ``toe``/``toc`` GST seconds of
    week, ``iode`` = ``iodc`` = IODnav, ``tgd`` = BGD(E1,E5b) (the single-frequency E1 correction, ICD
    Eq. 15), ``health`` = E1-B HS x 2 + E1-B DVS (0 = healthy and valid), ``ura_index`` = SISA."""
    bgd_e1e5a: float = 0.0
    e5b_hs: int = 0
    e5b_dvs: int = 0
    system: str = "E"

    @property
    def gst_week(self) -> int:
        """The Galileo system time week of the ephemeris (GPS week minus the GST week offset)."""
        return self.week - GST_WEEK_OFFSET

    @staticmethod
    def state(ephs, t_tx):
        """receiver.gnss.ephemeris.sat_state hands Galileo ephemerides here: the GPS algorithm with the
        Galileo mu and F (ICD Table 62, Eq. 13), BGD(E1,E5b) as the group delay (Eq. 15).  ``t_tx`` is taken
        as GST seconds of week (= GPS seconds of week when the GGTO is zero; a GGTO of a few ns is not
        applied here)."""
        from .ephemeris import _params, kepler_state
        return kepler_state(_params(ephs), t_tx, MU_GAL, F_REL_GAL)

    @property
    def e1b_hs(self) -> int:
        """E1-B signal health status (2 bits; 0: signal OK)."""
        return self.health >> 1

    @property
    def e1b_dvs(self) -> int:
        """E1-B data validity status (0: navigation data valid, 1: working without guarantee)."""
        return self.health & 1


@dataclass
class NequickG:
    """NeQuick-G broadcast coefficients (word 5, ICD Table 68): Az = ai0 + ai1 mu + ai2 mu^2 (sfu, mu =
    MODIP in degrees) and the ionospheric disturbance flags of the five MODIP regions."""
    ai0: float = 0.0
    ai1: float = 0.0
    ai2: float = 0.0
    storm_flags: tuple = (0, 0, 0, 0, 0)


@dataclass
class GstUtc:
    """GST-UTC parameters (word 6, ICD Table 69); ``wnot`` / ``wn_lsf`` are the broadcast 8-bit weeks."""
    a0: float = 0.0
    a1: float = 0.0
    dt_ls: int = 0
    tot: float = 0.0
    wnot: int = 0
    wn_lsf: int = 0
    dn: int = 0
    dt_lsf: int = 0


@dataclass
class Ggto:
    """GST-GPS time offset (word 10, ICD Table 70): t_GST - t_GPS = a0g + a1g (TOW - t0g + 604800
    ((WN - wn0g) mod 64)).  ``valid`` False when all four fields are all ones (ICD 5.1.8)."""
    a0g: float = 0.0
    a1g: float = 0.0
    t0g: float = 0.0
    wn0g: int = 0
    valid: bool = True

    def offset_s(self, gst_week: int, gst_tow: float) -> float:
        """The broadcast GST - GPS time offset (s) at GST week / time of week (0 when not valid)."""
        if not self.valid:
            return 0.0
        return self.a0g + self.a1g * (gst_tow - self.t0g + WEEK_S * ((gst_week - self.wn0g) % 64))


# ------------------------------------------------------------------------------------------- time
def gst_from_gps(gps_week: int, gps_tow: float, ggto: Ggto | None = None) -> tuple[int, float]:
    """(GST week, GST seconds of week) of a GPS time (the GGTO added when given)."""
    wk, t = gps_week - GST_WEEK_OFFSET, float(gps_tow)
    if ggto is not None:
        t += ggto.offset_s(wk, t)
    if t >= WEEK_S:
        wk, t = wk + 1, t - WEEK_S
    elif t < 0:
        wk, t = wk - 1, t + WEEK_S
    return wk, t


def gps_from_gst(gst_week: int, gst_tow: float, ggto: Ggto | None = None) -> tuple[int, float]:
    """(GPS week, GPS seconds of week) of a GST time: t_GPS = t_GST - GGTO (ICD Eq. 21)."""
    t = float(gst_tow) - (ggto.offset_s(gst_week, gst_tow) if ggto is not None else 0.0)
    wk = gst_week + GST_WEEK_OFFSET
    if t >= WEEK_S:
        wk, t = wk + 1, t - WEEK_S
    elif t < 0:
        wk, t = wk - 1, t + WEEK_S
    return wk, t


# -------------------------------------------------------------------------------- ephemeris <-> words
def eph_values(eph: GalEphemeris) -> dict:
    """The broadcast values (ICD units, angles in semicircles) of words 1-4 and the satellite part of 5."""
    v = {name: getattr(eph, name) for name in ("toe", "toc", "e", "sqrt_a", "cuc", "cus", "crc", "crs", "cic",
                                               "cis", "af0", "af1", "af2")}
    for name in SEMICIRCLE_FIELDS:
        v[name] = getattr(eph, name) / GAL_PI
    for name in ("m0", "omega0", "i0", "omega"):                  # 32-bit semicircles: [-1, 1)
        v[name] = (v[name] + 1.0) % 2.0 - 1.0
    v.update(iodnav=eph.iode, svid=eph.prn, sisa=eph.ura_index, bgd_e1e5b=eph.tgd, bgd_e1e5a=eph.bgd_e1e5a,
             e1b_hs=eph.e1b_hs, e1b_dvs=eph.e1b_dvs, e5b_hs=eph.e5b_hs, e5b_dvs=eph.e5b_dvs)
    return v


def quantize_gal(eph: GalEphemeris) -> GalEphemeris:
    """The ephemeris as the message carries it: every field on its LSB grid, the 32-bit angles wrapped into
    [-pi, pi)."""
    vals = {}
    for name, lsb in EPH_LSB.items():
        raw = int(np.round(float(getattr(eph, name)) / lsb))
        if name in ("m0", "omega0", "i0", "omega"):
            raw = (raw + (1 << 31)) % (1 << 32) - (1 << 31)
        vals[name] = float(raw * lsb)
    vals["tgd"] = float(np.round(eph.tgd / 2.0 ** -32) * 2.0 ** -32)
    vals["bgd_e1e5a"] = float(np.round(eph.bgd_e1e5a / 2.0 ** -32) * 2.0 ** -32)
    return replace(eph, **vals)


@dataclass
class InavContent:
    """Everything one satellite's I/NAV stream carries here: its ephemeris and the system parameters."""
    eph: GalEphemeris
    nequick: NequickG = field(default_factory=NequickG)
    utc: GstUtc = field(default_factory=GstUtc)
    ggto: Ggto = field(default_factory=Ggto)


def subframe_word(gst_tow_page: int) -> int:
    """Word type sent on E1-B in the page that starts at GST second ``gst_tow_page`` (odd; ICD Tables 41 and
    42); 0 = spare word (also in the slots of the almanac words 7-9 and of the reserved pages)."""
    t0 = int(gst_tow_page) % 30
    odd_subframe = (int(gst_tow_page) // 30) % 2 == 1
    return {1: 2, 3: 4, 5: 6, 7: 0, 9: 10 if odd_subframe else 0, 21: 1, 23: 3, 25: 5}.get(t0, 0)


def encode_word(content: InavContent, wtype: int, gst_week: int, gst_tow_page: int) -> np.ndarray:
    """The 128-bit word of type ``wtype`` for the page starting at (gst_week, gst_tow_page)."""
    v = eph_values(content.eph)
    n, u, g = content.nequick, content.utc, content.ggto
    v.update(ai0=n.ai0, ai1=n.ai1, ai2=n.ai2, **{f"sf{k + 1}": int(f) for k, f in enumerate(n.storm_flags)})
    v.update(a0=u.a0, a1=u.a1, dt_ls=u.dt_ls, tot=u.tot, wnot=u.wnot, wn_lsf=u.wn_lsf, dn=u.dn, dt_lsf=u.dt_lsf)
    if g.valid:
        v.update(a0g=g.a0g, a1g=g.a1g, t0g=g.t0g, wn0g=g.wn0g)
    v.update(wn=gst_week % 4096, tow=int(gst_tow_page), time=2)
    w = pack_word(wtype, v)
    if wtype == 10 and not g.valid:                          # all ones: GGTO not available
        w[-42:] = 1
    return w


class InavStream:
    """The simulator's E1-B symbol stream of one satellite: +/-1 per 4-ms code period (one I/NAV symbol)
    for a span of GST, from its :class:`InavContent`.  Symbol k of GST week ``gst_week`` starts at
    k x 4 ms; page parts are cached per second."""

    def __init__(self, content: InavContent, gst_week: int):
        self.content = content
        self.gst_week = gst_week
        self._cache: dict[int, np.ndarray] = {}

    def part_symbols(self, second: int) -> np.ndarray:
        """The 250 symbols (0/1) of the page part transmitted in GST second ``second`` of the week (may run
        past the week: the week is carried)."""
        sym = self._cache.get(second)
        if sym is None:
            start = second if second % 2 == 1 else second - 1          # pages start at odd seconds
            wk, tow = self.gst_week + start // int(WEEK_S), start % int(WEEK_S)
            even, odd = page_parts(encode_word(self.content, subframe_word(tow), wk, tow))
            if len(self._cache) > 16:
                self._cache.clear()
            self._cache[start] = encode_part(even)
            self._cache[start + 1] = encode_part(odd)
            sym = self._cache[second]
        return sym

    def signs(self, first_symbol: int, count: int) -> np.ndarray:
        """+/-1 (float32) per symbol first_symbol .. first_symbol + count - 1 (symbols of the GST week)."""
        k = np.int64(first_symbol) + np.arange(count, dtype=np.int64)
        sec = k // PART_SYMBOLS
        out = np.empty(count, np.uint8)
        for s in np.unique(sec):
            sel = sec == s
            out[sel] = self.part_symbols(int(s))[k[sel] - s * PART_SYMBOLS]
        return (1.0 - 2.0 * out).astype(np.float32)


# ------------------------------------------------------------------------------------------ decoding
@dataclass
class PageEvent:
    """A nominal page whose CRC passed: ``symbol_index`` of its first symbol (the even part's first sync
    symbol), its word type, and the GPS time of week of that symbol when the GST is known (else None)."""
    symbol_index: int
    word_type: int
    tow_s: float | None
    polarity: int


class InavDecoder:
    """Per-channel E1-B I/NAV decoder.

    ``feed(symbols, first_symbol_index)``: soft symbols (float, negative = logic 1, e.g. E1-B prompt sums
    of 4 ms) or hard ones (0/1), indices counting 4-ms code periods.  Page-part sync: the sync pattern (either
    polarity, ``SEARCH_ERRORS`` wrong symbols tolerated) at two positions 250 symbols apart; then every part is
    de-interleaved and Viterbi-decoded,
    an even part followed by an odd part is a page, and a page whose CRC-24Q passes is used.  A part whose sync
    pattern has more than ``SYNC_ERRORS`` wrong symbols is decoded all the same; sync is dropped after
    ``MAX_MISSES`` such parts in a row.  A sync pattern of the other polarity (a half-cycle slip of the carrier
    loop) switches the polarity.

    Events: :class:`receiver.gnss.lnav.SubframeEvent` per good page once the GST is known (``bit_index`` =
    symbol index of the page start, ``tow_s`` = GPS seconds of week there, ``subframe_id`` = word type).
    State: ``ephemeris`` (:class:`GalEphemeris`, from words 1-4 of one IODnav and word 5), ``nequick``,
    ``utc``, ``ggto``, ``gst_week``, ``week`` (GPS week), ``crc_failures``, ``pages_ok``, ``synced``,
    ``polarity``.  A new ephemeris with the current IODnav but other contents, or one that moves the satellite
    by more than ``JUMP_M``, is held until a second reception decodes it again (as the LNAV decoder does;
    CRC-24Q makes a false pass rare: 2^-24 per corrupted page).
    """
    MAX_MISSES = 3
    SEARCH_ERRORS = 1           # wrong sync symbols tolerated in each of the two patterns of the search
    SYNC_ERRORS = 2             # wrong sync symbols tolerated once in sync
    JUMP_M = 300.0

    def __init__(self, prn: int, week_hint: int | None = None):
        self.prn = int(prn)
        self.week_hint = week_hint
        self.ephemeris: GalEphemeris | None = None
        self.nequick: NequickG | None = None
        self.utc: GstUtc | None = None
        self.ggto: Ggto | None = None
        self.gst_week: int | None = None
        self.crc_failures = 0
        self.pages_ok = 0
        self.synced = False
        self.polarity = 0
        self._sym = np.zeros(0, np.float64)
        self._start = 0
        self._next = None
        self._part_at = None            # symbol index of the next part to decode (synced)
        self._misses = 0
        self._even = None               # (symbol index, 114 bits) of a pending even part
        self._tow_ref = None            # (symbol index, GST week, GST TOW) of a page start
        self._words: dict = {}          # word type -> (fields, reception number)
        self._seq = 0
        self._held = HeldSet()
        # the navigation engine's decoder interface (receiver.navigation.channel): I/NAV carries no Klobuchar
        # set (NeQuick-G instead: ``nequick``); first_check is set by the engine, not used here (CRC-24Q)
        self.iono_utc = None
        self.first_check = None

    @property
    def parity_failures(self) -> int:
        """Pages whose CRC-24Q failed (the navigation engine's name for corrupted words)."""
        return self.crc_failures

    @property
    def week(self) -> int | None:
        """The GPS week of the decoded GST week, or None before word 5 has been decoded."""
        return None if self.gst_week is None else self.gst_week + GST_WEEK_OFFSET

    @property
    def ephemerides_held(self) -> int:
        """How many suspect ephemeris sets were held back for a second reception (lnav.HeldSet.count)."""
        return self._held.count

    def feed(self, symbols, first_symbol_index: int) -> list:
        """Add symbols starting at 4-ms code period ``first_symbol_index`` (a gap restarts the page
        synchronisation); returns the events of the pages completed by them."""
        a = np.asarray(symbols).ravel()
        if a.dtype == bool or np.issubdtype(a.dtype, np.unsignedinteger):
            a = 1.0 - 2.0 * (a != 0)
        a = a.astype(np.float64)
        if self._next is not None and first_symbol_index != self._next:
            self._sym = np.zeros(0, np.float64)           # gap: start over
            self.synced = False
            self._even = None
        if len(self._sym) == 0:
            self._start = first_symbol_index
        self._sym = np.concatenate([self._sym, a])
        self._next = first_symbol_index + len(a)
        events = []
        while True:
            if not self.synced and not self._search():
                break
            done, ev = self._decode_next()
            if ev is not None:
                events.append(ev)
            if not done:
                break
        keep = (self._part_at - self._start) if self.synced else max(0, len(self._sym) - 2 * PART_SYMBOLS)
        if keep > 0:
            self._sym = self._sym[keep:]
            self._start += keep
        return events

    def _sync_sign(self, k: int, tolerate: int = 0) -> int:
        """+1 / -1 when the 10 symbols at buffer offset k are the sync pattern in that polarity with at most
        ``tolerate`` wrong symbols, else 0."""
        seg = hard_bits(self._sym[k:k + SYNC_LEN])
        if len(seg) < SYNC_LEN:
            return 0
        wrong = int(np.count_nonzero(seg != _SYNC_ARR))
        if wrong <= tolerate:
            return 1
        if SYNC_LEN - wrong <= tolerate:
            return -1
        return 0

    def _search(self) -> bool:
        n = len(self._sym)
        for k in range(0, n - PART_SYMBOLS - SYNC_LEN + 1):
            pol = self._sync_sign(k, self.SEARCH_ERRORS)
            if pol and self._sync_sign(k + PART_SYMBOLS, self.SEARCH_ERRORS) == pol:
                self.synced, self.polarity, self._misses = True, pol, 0
                self._part_at = self._start + k
                self._even = None
                return True
        return False

    def _decode_next(self):
        """(more may follow, event or None)."""
        k = self._part_at - self._start
        if k + PART_SYMBOLS > len(self._sym):
            return False, None
        at = self._part_at
        self._part_at += PART_SYMBOLS
        pol = self._sync_sign(k, self.SYNC_ERRORS)
        if pol == 0:                      # decoded all the same (the CRC decides), sync lost after a few
            self._misses += 1
            if self._misses >= self.MAX_MISSES:
                self.synced = False
                self._even = None
                return False, None
            pol = self.polarity
        else:
            self._misses = 0
        if pol != self.polarity:                         # a half-cycle slip: the pattern says which way
            self.polarity = pol
            self._even = None
        bits = decode_part(self.polarity * self._sym[k:k + PART_SYMBOLS])
        if bits[0] == 0:
            self._even = (at, bits)
            return True, None
        even, self._even = self._even, None
        if even is None or even[0] != at - PART_SYMBOLS:
            return True, None
        res = page_word(even[1], bits)
        if res is None:
            return True, None
        word, ok = res
        if not ok:
            self.crc_failures += 1
            return True, None
        self.pages_ok += 1
        return True, self._use(even[0], word)

    def _use(self, page_at: int, word):
        f = unpack_word(word)
        t = f["type"]
        if t in (5, 6) or (t == 0 and f.get("time") == 2):
            if t != 6:
                self.gst_week = int(f["wn"])
            wk = self.gst_week
            if wk is None and self.week_hint is not None:
                wk = int(self.week_hint) - GST_WEEK_OFFSET
            self._tow_ref = (page_at, wk, int(f["tow"]))     # word 6 has no WN: the week may be unknown
        self._seq += 1
        if t in (1, 2, 3, 4, 5):
            self._words[t] = (f, self._seq)
            self._assemble()
        elif t == 6:
            self.utc = GstUtc(a0=f["a0"], a1=f["a1"], dt_ls=f["dt_ls"], tot=f["tot"], wnot=f["wnot"],
                              wn_lsf=f["wn_lsf"], dn=f["dn"], dt_lsf=f["dt_lsf"])
        elif t == 10:
            raw = word[-42:]
            self.ggto = Ggto(a0g=f["a0g"], a1g=f["a1g"], t0g=f["t0g"], wn0g=f["wn0g"], valid=not bool(raw.all()))
        if t == 5:
            self.nequick = NequickG(ai0=f["ai0"], ai1=f["ai1"], ai2=f["ai2"],
                                    storm_flags=tuple(int(f[f"sf{k}"]) for k in range(1, 6)))
        if self._tow_ref is None:
            return None
        ref_at, wk, tow = self._tow_ref
        gst = tow + (page_at - ref_at) / 250.0
        if wk is None:                                   # no week yet: the GGTO (ns) is left out
            gps_tow = gst % WEEK_S
        else:
            _, gps_tow = gps_from_gst(wk + int(gst // WEEK_S), gst % WEEK_S, self.ggto)
        return SubframeEvent(bit_index=int(page_at), tow_s=float(gps_tow), subframe_id=int(t),
                             polarity=self.polarity)

    def _assemble(self):
        w = self._words
        if not all(t in w for t in (1, 2, 3, 4, 5)) or self.gst_week is None:
            return
        iod = {w[t][0]["iodnav"] for t in (1, 2, 3, 4)}
        if len(iod) != 1 or w[4][0]["svid"] != self.prn:
            return
        f = {}
        for t in (1, 2, 3, 4, 5):
            f.update(w[t][0])
        week = self.gst_week
        now = self._tow_ref[2] if self._tow_ref is not None else f["toe"]
        if f["toe"] - now > HALF_WEEK:
            week -= 1
        elif now - f["toe"] > HALF_WEEK:
            week += 1
        eph = GalEphemeris(
            prn=self.prn, week=week + GST_WEEK_OFFSET, toe=float(f["toe"]), toc=float(f["toc"]),
            af0=f["af0"], af1=f["af1"], af2=f["af2"], tgd=f["bgd_e1e5b"], iode=int(f["iodnav"]),
            iodc=int(f["iodnav"]), sqrt_a=f["sqrt_a"], e=f["e"], i0=f["i0"] * GAL_PI,
            omega0=f["omega0"] * GAL_PI, omega=f["omega"] * GAL_PI, m0=f["m0"] * GAL_PI,
            delta_n=f["delta_n"] * GAL_PI, idot=f["idot"] * GAL_PI, omega_dot=f["omega_dot"] * GAL_PI,
            cuc=f["cuc"], cus=f["cus"], crc=f["crc"], crs=f["crs"], cic=f["cic"], cis=f["cis"],
            health=int(f["e1b_hs"]) * 2 + int(f["e1b_dvs"]), ura_index=int(f["sisa"]),
            bgd_e1e5a=f["bgd_e1e5a"], e5b_hs=int(f["e5b_hs"]), e5b_dvs=int(f["e5b_dvs"]))
        if eph == self.ephemeris:
            return
        cur = self.ephemeris
        src = [w[t][1] for t in (1, 2, 3, 4)]
        suspect = cur is not None and (eph.iode == cur.iode or not self._near(cur, eph))
        if suspect and not self._held.offer(eph, src, operator.eq):
            return
        self._held.clear()
        self.ephemeris = eph

    @staticmethod
    def _near(old: GalEphemeris, new: GalEphemeris) -> bool:
        from .signals import C_LIGHT
        t = float(new.toe)
        p0, _, c0, _ = GalEphemeris.state(old, t)
        p1, _, c1, _ = GalEphemeris.state(new, t)
        return float(np.linalg.norm(p1 - p0)) + C_LIGHT * abs(float(c1 - c0)) <= InavDecoder.JUMP_M
