"""Galileo I/NAV (E1-B): CRC-24Q, FEC, interleaving, page layout, word packing, and the round trip
encoder -> channel errors -> decoder (ephemeris, NeQuick-G, UTC, GGTO, GST)."""
import math

import numpy as np
import pytest

from receiver.gnss import gal_inav as I


# ------------------------------------------------------------------------------------------- CRC
def _g_of_x():
    """G(X) = (1 + X) P(X) of ICD Eqs. 22-23 as an integer (bit k = coefficient of X^k)."""
    p = 0
    for k in (23, 17, 13, 12, 11, 9, 8, 7, 5, 3, 0):
        p |= 1 << k
    return p ^ (p << 1)


def _crc_by_division(bits):
    """CRC of ICD 5.1.9.4 by the definition: R(X) = m(X) X^24 mod G(X), with plain integer polynomial
    arithmetic over GF(2)."""
    g = _g_of_x()
    m = 0
    for b in bits:
        m = (m << 1) | int(b)
    r = m << 24
    while r.bit_length() > 24:
        r ^= g << (r.bit_length() - 25)
    return r


def test_crc24q_against_the_polynomial_definition():
    assert I.CRC24_POLY == _g_of_x() == 0x1864CFB
    rng = np.random.default_rng(3)
    for n in (1, 7, 24, 196, 500):
        for _ in range(5):
            bits = rng.integers(0, 2, n)
            assert I.crc24q(bits) == _crc_by_division(bits)
    # the CRC-24Q catalogue check value ("123456789", poly 0x864CFB, init 0) follows from the same definition
    msg = np.unpackbits(np.frombuffer(b"123456789", np.uint8))
    assert _crc_by_division(msg) == 0xCDE703
    assert I.crc24q(msg) == 0xCDE703


# ---------------------------------------------------------------------------------- FEC, interleaver
def test_encoder_definition():
    """G1 = 171o, G2 = 133o (inverted), G1 first: an impulse gives the generator taps in time order."""
    out = I.conv_encode([1, 0, 0, 0, 0, 0, 0])
    g1 = [int(c) for c in f"{0o171:07b}"]            # 1111001: taps of the current and 6 previous bits
    g2 = [1 - int(c) for c in f"{0o133:07b}"]        # 1011011, inverted
    assert list(out[0::2]) == g1 and list(out[1::2]) == g2
    assert list(I.conv_encode([0, 0, 0])) == [0, 1] * 3          # all-zero input: G2 inverted -> 01 01 ...


def test_interleaver_is_30_columns_by_8_rows():
    x = np.arange(240)
    y = I.interleave(x)
    # written column by column (8 symbols each), read row by row (30 each): neighbours 30 apart on air
    assert list(y[:4]) == [0, 8, 16, 24] and y[30] == 1 and y[239] == 239
    assert np.array_equal(I.deinterleave(y), x)


def test_page_part_round_trip_with_errors():
    rng = np.random.default_rng(7)
    worst = 0
    for _ in range(20):
        b = rng.integers(0, 2, 114).astype(np.uint8)
        s = I.encode_part(b)
        assert len(s) == 250 and tuple(s[:10]) == I.SYNC
        assert np.array_equal(I.decode_part(s), b)
        soft = (1.0 - 2.0 * s) + rng.normal(0.0, 0.75, 250)     # Es/N0 ~ 2.5 dB: ~9 % raw symbol errors
        worst = max(worst, int(((soft[10:] < 0) != (s[10:] == 1)).sum()))
        assert np.array_equal(I.decode_part(soft), b)
    assert worst >= 15                                           # the channel did make errors
    # a burst of 8 consecutive symbol errors on air (spread over 8 rows by the interleaver) is corrected
    b = rng.integers(0, 2, 114).astype(np.uint8)
    s = I.encode_part(b).astype(np.float64)
    soft = 1.0 - 2.0 * s
    soft[100:108] *= -1
    assert np.array_equal(I.decode_part(soft), b)


# --------------------------------------------------------------------------------------- page, words
def test_page_layout_and_crc():
    rng = np.random.default_rng(1)
    w = rng.integers(0, 2, 128).astype(np.uint8)
    even, odd = I.page_parts(w, reserved1=0x12345, sar=0x2AAAA, spare=1, reserved2=0xA5)
    assert len(even) == len(odd) == 114
    assert even[0] == 0 and odd[0] == 1 and even[1] == 0 and odd[1] == 0
    word, ok = I.page_word(even, odd)
    assert ok and np.array_equal(word, w)
    assert I.bits_to_int(odd[106:114]) == 0xA5                   # reserved 2 after the CRC
    bad = odd.copy()
    bad[50] ^= 1                                                 # SAR field: covered by the CRC
    assert not I.page_word(even, bad)[1]
    bad = odd.copy()
    bad[110] ^= 1                                                # reserved 2: not covered (ICD Table 39)
    assert I.page_word(even, bad)[1]
    assert I.page_word(odd, even) is None


def _ephemeris(prn=11):
    return I.GalEphemeris(
        prn=prn, week=2190, toe=518400.0, toc=518400.0, af0=-3.1e-4, af1=-5.5e-12, af2=0.0, tgd=-1.2e-9,
        iode=97, iodc=97, sqrt_a=5440.6123, e=1.9e-4, i0=0.9712, omega0=-2.0121, omega=-0.5512, m0=2.8101,
        delta_n=3.1e-9, idot=-1.9e-10, omega_dot=-5.6e-9, cuc=-1.7e-6, cus=8.1e-6, crc=181.3, crs=-33.1,
        cic=2.2e-8, cis=-4.1e-8, health=0, ura_index=107, bgd_e1e5a=-1.3e-9)


@pytest.mark.parametrize("wtype", [0, 1, 2, 3, 4, 5, 6, 10])
def test_word_pack_unpack_within_one_lsb(wtype):
    c = I.InavContent(_ephemeris(), I.NequickG(ai0=63.75, ai1=0.2344, ai2=0.0049, storm_flags=(0, 1, 0, 0, 1)),
                      I.GstUtc(a0=-9.3e-10, a1=-8.9e-16, dt_ls=18, tot=345600, wnot=142, wn_lsf=137, dn=7,
                               dt_lsf=18),
                      I.Ggto(a0g=2.9e-9, a1g=-4.4e-15, t0g=349200, wn0g=27))
    w = I.encode_word(c, wtype, 1166, 518425)
    assert len(w) == 128 and I.word_type(w) == wtype
    f = I.unpack_word(w)
    v = I.eph_values(c.eph)
    v.update(ai0=63.75, ai1=0.2344, ai2=0.0049, a0=-9.3e-10, a1=-8.9e-16, a0g=2.9e-9, a1g=-4.4e-15)
    for name, n, lsb, signed in I.WORD_LAYOUT[wtype]:
        if name and name in v:
            assert abs(f[name] - v[name]) <= lsb / 2 * (1 + 1e-9), name
    if wtype in (0, 5):
        assert f["wn"] == 1166 and f["tow"] == 518425
    if wtype == 5:
        assert f["sf2"] == 1 and f["sf5"] == 1 and f["sf1"] == 0


def test_subframe_schedule_is_table_41():
    # E1-B pages start at odd seconds of the 30-s sub-frame: 1 -> word 2, 21 -> 1, 25 -> 5, 5 -> 6
    assert [I.subframe_word(t) for t in (1, 3, 5, 21, 23, 25)] == [2, 4, 6, 1, 3, 5]
    assert I.subframe_word(30 + 9) == 10 and I.subframe_word(9) == 0       # word 10 in every other sub-frame
    assert I.subframe_word(27) == 0 and I.subframe_word(13) == 0


def test_gst_gps_time():
    g = I.Ggto(a0g=5e-9, a1g=1e-14, t0g=3600.0, wn0g=1166 % 64)
    wk, tow = I.gst_from_gps(2190, 7200.0, g)
    assert wk == 1166 and tow == pytest.approx(7200.0 + 5e-9 + 1e-14 * 3600.0, abs=1e-12)
    assert I.gps_from_gst(wk, tow, g) == (2190, pytest.approx(7200.0, abs=1e-12))
    assert I.gps_from_gst(1166, 604799.5) == (2190, 604799.5)
    assert I.gst_from_gps(2190, 0.0, I.Ggto(a0g=-1e-6, valid=True)) == (1165, pytest.approx(WEEK - 1e-6))
    assert I.Ggto(a0g=1.0, valid=False).offset_s(1166, 0.0) == 0.0


WEEK = 604800.0


# ------------------------------------------------------------------------------------- round trip
def _stream_soft(content, gst_week, first_sym, n_sym, sigma, seed):
    st = I.InavStream(content, gst_week)
    clean = st.signs(first_sym, n_sym).astype(np.float64)
    rng = np.random.default_rng(seed)
    return clean, clean + rng.normal(0.0, sigma, n_sym)


@pytest.mark.parametrize("polarity", [1, -1])
def test_round_trip_stream_with_channel_errors(polarity):
    """72 s of E1-B symbols (starting mid-page), Es/N0 ~ 3.5 dB (~5 % raw symbol errors), either carrier
    polarity: every page's CRC passes, the ephemeris equals the broadcast one within one LSB, the NeQuick-G,
    UTC and GGTO parameters and the time of each page come out."""
    eph = _ephemeris()
    content = I.InavContent(eph, I.NequickG(ai0=63.75, ai1=0.2344, ai2=0.0049),
                            I.GstUtc(a0=-9.3e-10, a1=-8.9e-16, dt_ls=18, tot=345600, wnot=142, wn_lsf=137, dn=7,
                                     dt_lsf=18),
                            I.Ggto(a0g=2.9e-9, a1g=-4.4e-15, t0g=518400, wn0g=1166 % 64))
    gst_week, t0 = 1166, 518400 + 0.6                       # GST of the first symbol
    first = int(round(t0 * 250))
    clean, soft = _stream_soft(content, gst_week, first, 72 * 250, 0.67, seed=5)
    raw_err = int(((soft < 0) != (clean < 0)).sum())
    assert raw_err > 500
    dec = I.InavDecoder(11)
    events = []
    for k in range(0, len(soft), 1000):                     # fed in 4-s blocks
        events += dec.feed(polarity * soft[k:k + 1000], k)
    assert dec.synced and dec.polarity == polarity
    assert dec.crc_failures == 0 and dec.pages_ok >= 34
    e = dec.ephemeris
    assert e is not None and e.prn == 11 and e.week == 2190 and e.gst_week == 1166
    for name, lsb in I.EPH_LSB.items():
        assert abs(getattr(e, name) - getattr(eph, name)) <= lsb / 2 * (1 + 1e-9), name
    assert e == I.quantize_gal(eph)
    assert abs(e.tgd - eph.tgd) <= 2.0 ** -33 and e.iode == 97 and e.ura_index == 107 and e.health == 0
    assert dec.nequick.ai0 == 63.75 and abs(dec.nequick.ai1 - 0.2344) <= 2 ** -9
    assert abs(dec.nequick.ai2 - 0.0049) <= 2 ** -16
    assert dec.utc.dt_ls == 18 and dec.utc.dn == 7 and abs(dec.utc.a0 + 9.3e-10) <= 2 ** -31
    assert dec.ggto.valid and abs(dec.ggto.a0g - 2.9e-9) <= 2 ** -36
    # every event's time is the GPS time of its page start (pages start at odd GST seconds)
    # (GST until word 10 brought the GGTO, then GST - GGTO)
    assert len(events) >= 30
    ggto_known = False
    for ev in events:
        t_sym = (first + ev.bit_index) / 250.0              # GST of that symbol
        assert abs(t_sym - round(t_sym)) < 1e-9 and round(t_sym) % 2 == 1
        ggto_known |= ev.subframe_id == 10
        ggto = dec.ggto.offset_s(1166, t_sym) if ggto_known else 0.0
        assert ev.tow_s == pytest.approx(t_sym - ggto, abs=1e-10)
        assert ev.subframe_id == I.subframe_word(round(t_sym))


def test_corrupted_pages_are_rejected_not_used():
    """At Es/N0 ~ 1.4 dB the Viterbi decoder leaves errors in many pages: those fail the CRC and are not used;
    the pages that pass carry the broadcast words, and the ephemeris comes out right from them."""
    content = I.InavContent(_ephemeris())
    first = 518401 * 250 - 10
    clean, soft = _stream_soft(content, 1166, first, 120 * 250, 0.85, seed=2)
    dec = I.InavDecoder(11)
    sync = (np.arange(len(clean)) - 10) % 250 < 10                      # the sync symbols clean: sync holds
    events = dec.feed(np.where(sync, clean, soft), 0)
    assert dec.crc_failures > 15 and dec.pages_ok > 15
    assert dec.ephemeris == I.quantize_gal(content.eph)
    for ev in events:
        assert ev.subframe_id == I.subframe_word(round((first + ev.bit_index) / 250.0))


def test_ggto_not_available():
    content = I.InavContent(_ephemeris(), ggto=I.Ggto(valid=False))
    w = I.encode_word(content, 10, 1166, 518439)
    assert w[-42:].all()
    clean, _ = _stream_soft(content, 1166, 518437 * 250, 6 * 250, 0.1, 0)
    dec = I.InavDecoder(11)
    dec.feed(clean, 0)
    assert dec.ggto is not None and not dec.ggto.valid


def test_satellite_state_uses_the_galileo_constants():
    from receiver.gnss.ephemeris import Ephemeris, sat_state
    e = _ephemeris()
    t = e.toe + 3600.0
    p, v, clk, drift = sat_state(e, t)                        # dispatched to GalEphemeris.state
    assert 29.5e6 < np.linalg.norm(p) < 29.7e6                 # MEO radius ~ 29 600 km
    assert 2.5e3 < np.linalg.norm(v) < 4.5e3
    assert clk == pytest.approx(e.af0 + e.af1 * 3600.0 - e.tgd, abs=5e-8)
    # the same numbers as a GPS ephemeris but mu = 3.986004418e14 instead of 3.986005e14: after an hour the
    # mean motion difference (-0.73 ppm) has moved the satellite by ~10 m along track
    g = Ephemeris(**{f: getattr(e, f) for f in ("prn", "week", "toe", "toc", "af0", "af1", "af2", "tgd", "iode",
                                                 "iodc", "sqrt_a", "e", "i0", "omega0", "omega", "m0", "delta_n",
                                                 "idot", "omega_dot", "cuc", "cus", "crc", "crs", "cic", "cis")})
    pg = sat_state(g, t)[0]
    n = math.sqrt(I.MU_GAL / e.sqrt_a ** 6)
    expect = np.linalg.norm(p) * n * 3600.0 * (1 - math.sqrt(3.986005e14 / I.MU_GAL))
    assert np.linalg.norm(p - pg) == pytest.approx(abs(expect), rel=0.05)
