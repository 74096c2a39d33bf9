"""LNAV parity, frame encoder and decoder (IS-GPS-200)."""
import itertools
from dataclasses import replace

import numpy as np
import pytest

from receiver.gnss.ephemeris import Ephemeris
from receiver.gnss.lnav import (EPH_LSB, IONO_LSB, PREAMBLE, EphemerisEvent, IonoUtcEvent,
                               LnavDecoder, SubframeEvent, correct_word, decode_word, encode_frames,
                               encode_subframes, encode_word, parity_bits, subframe45_page,
                               word_parity_ok)
from receiver.gnss.rinex import read_rinex_nav

from repo_paths import SHARED_DATA as DATA
BRDC = DATA / "brdc0010.22n"


def _need_brdc():
    if not BRDC.exists():
        pytest.skip(f"shared test data absent: {BRDC}")
    return read_rinex_nav(BRDC)


def _bits(s):
    return np.array([int(c) for c in s.replace(" ", "")], dtype=np.uint8)


# ------------------------------------------------------------------ parity

def _icd_parity(d, p29, p30):
    """Parity written out literally from the ICD equations (1-based d)."""
    x = lambda *idx: sum(d[i - 1] for i in idx) % 2  # noqa: E731
    return [
        (p29 + x(1, 2, 3, 5, 6, 10, 11, 12, 13, 14, 17, 18, 20, 23)) % 2,
        (p30 + x(2, 3, 4, 6, 7, 11, 12, 13, 14, 15, 18, 19, 21, 24)) % 2,
        (p29 + x(1, 3, 4, 5, 7, 8, 12, 13, 14, 15, 16, 19, 20, 22)) % 2,
        (p30 + x(2, 4, 5, 6, 8, 9, 13, 14, 15, 16, 17, 20, 21, 23)) % 2,
        (p30 + x(1, 3, 5, 6, 7, 9, 10, 14, 15, 16, 17, 18, 21, 22, 24)) % 2,
        (p29 + x(3, 5, 6, 8, 9, 10, 11, 13, 15, 19, 22, 23, 24)) % 2,
    ]


def test_parity_of_a_tlm_word_by_hand():
    # TLM: preamble 10001011, 16 zero bits; previous D29*=D30*=0.
    d = _bits("10001011 00000000 00000000")
    # by hand, nonzero source bits are d1, d5, d7, d8:
    # D25 = d1^d5 = 0 ; D26 = d7 = 1 ; D27 = d1^d5^d7^d8 = 0 ; D28 = d5^d8 = 0
    # D29 = d1^d5^d7 = 1 ; D30 = d5^d8 = 0
    assert list(parity_bits(d, 0, 0)) == [0, 1, 0, 0, 1, 0]
    w = encode_word(d, 0, 0)
    assert list(w[:8]) == list(PREAMBLE)
    assert word_parity_ok(w, 0, 0)


def test_parity_matches_icd_equations_random_words():
    rng = np.random.default_rng(1)
    for _ in range(200):
        d = rng.integers(0, 2, 24).astype(np.uint8)
        p29, p30 = (int(v) for v in rng.integers(0, 2, 2))
        assert list(parity_bits(d, p29, p30)) == _icd_parity(d, p29, p30)
        w = encode_word(d, p29, p30)
        # data bits are sent inverted when D30* = 1
        assert np.array_equal(w[:24], d ^ p30)
        data, ok = decode_word(w, p29, p30)
        assert ok and np.array_equal(data, d)


def test_single_and_double_bit_errors_detected():
    rng = np.random.default_rng(2)
    d = rng.integers(0, 2, 24).astype(np.uint8)
    for p29, p30 in itertools.product((0, 1), repeat=2):
        w = encode_word(d, p29, p30)
        assert word_parity_ok(w, p29, p30)
        for i in range(30):
            bad = w.copy()
            bad[i] ^= 1
            assert not word_parity_ok(bad, p29, p30)
        for i, j in itertools.combinations(range(30), 2):
            bad = w.copy()
            bad[i] ^= 1
            bad[j] ^= 1
            assert not word_parity_ok(bad, p29, p30)


def test_inverted_stream_passes_parity_with_inverted_previous_bits():
    rng = np.random.default_rng(3)
    d = rng.integers(0, 2, 24).astype(np.uint8)
    w = encode_word(d, 0, 1)                 # D30* = 1: data sent inverted
    assert np.array_equal(w[:24], 1 - d)
    inv = 1 - w                              # whole stream inverted (180 deg carrier ambiguity)
    data, ok = decode_word(inv, 1, 0)        # the previous word's D29/D30 are inverted too
    assert ok and np.array_equal(data, d)
    assert not word_parity_ok(inv, 0, 1)


def test_t_bits_solved():
    rng = np.random.default_rng(4)
    for _ in range(50):
        d = rng.integers(0, 2, 24).astype(np.uint8)
        p29, p30 = (int(v) for v in rng.integers(0, 2, 2))
        w = encode_word(d, p29, p30, solve_t=True)
        assert w[28] == 0 and w[29] == 0
        assert word_parity_ok(w, p29, p30)
        assert np.array_equal(w[:22], d[:22] ^ p30)   # only the t bits may change


# ------------------------------------------------------------------ encoder structure

def test_frame_structure():
    ephs, iono = _need_brdc()
    eph = ephs[1][0]
    tow0 = 518400.0 + 17 * 30                       # page (17280+17) % 25 + 1
    bits = encode_subframes(eph, iono, tow0, 2190)
    assert bits.shape == (1500,) and bits.dtype == np.uint8
    d29 = d30 = 0
    for k in range(5):
        sf = bits[k * 300:(k + 1) * 300]
        assert np.array_equal(sf[:8], PREAMBLE)
        words = []
        for w in range(10):
            data, ok = decode_word(sf[w * 30:(w + 1) * 30], d29, d30)
            assert ok, (k, w)
            d29, d30 = int(sf[w * 30 + 28]), int(sf[w * 30 + 29])
            words.append(data)
        assert sf[58] == 0 and sf[59] == 0 and sf[298] == 0 and sf[299] == 0
        how = words[1]
        tow_count = int("".join(map(str, how[:17])), 2)
        assert tow_count * 6 == tow0 + 6 * (k + 1)
        assert int("".join(map(str, how[19:22])), 2) == k + 1
    assert subframe45_page(tow0) == (int(tow0 // 30) % 25) + 1


def test_page18_placement():
    ephs, iono = _need_brdc()
    eph = ephs[1][0]
    tow18 = 0.0
    while subframe45_page(tow18) != 18:
        tow18 += 30.0
    def sf4_svid(bits):
        sf4 = bits[900:1200]
        d, ok = decode_word(sf4[60:90], int(sf4[58]), int(sf4[59]))
        assert ok
        return int("".join(map(str, d[2:8])), 2)
    assert sf4_svid(encode_subframes(eph, iono, tow18, 2190)) == 56
    assert sf4_svid(encode_subframes(eph, iono, tow18 + 30, 2190)) != 56
    assert sf4_svid(encode_subframes(eph, iono, tow18 + 30, 2190, page18_every_frame=True)) == 56
    assert sf4_svid(encode_subframes(eph, None, tow18, 2190)) != 56


def test_encoder_rejects_bad_input():
    ephs, iono = _need_brdc()
    eph = ephs[1][0]
    with pytest.raises(ValueError):
        encode_subframes(eph, iono, 518401.0, 2190)
    with pytest.raises(ValueError):
        encode_subframes(replace(eph, af0=0.01), iono, 518400.0, 2190)


# ------------------------------------------------------------------ decoder

def _soft(bits, polarity=1, noise=0.0, rng=None):
    x = (1.0 - 2.0 * bits.astype(float)) * polarity
    if noise:
        x = x + noise * rng.standard_normal(len(x))
    return x


def _decode(bits, start=0, chunk=None, polarity=1, **kw):
    dec = LnavDecoder(**kw)
    soft = _soft(bits, polarity)
    events = []
    chunk = chunk or len(soft)
    for i in range(start, len(soft), chunk):
        events += dec.feed(soft[i:i + chunk], i)
    return dec, events


def _assert_eph_close(dec: Ephemeris, ref: Ephemeris):
    for name, lsb in EPH_LSB.items():
        got, want = getattr(dec, name), getattr(ref, name)
        if name in ("aodo",):
            continue
        assert abs(got - want) <= 0.5 * lsb * (1 + 1e-9) + 1e-15 * abs(want), (ref.prn, name, got, want)
    for name in ("prn", "week", "iode", "iodc", "health", "ura_index", "fit_interval",
                 "code_on_l2", "l2p_flag"):
        assert getattr(dec, name) == getattr(ref, name), name


@pytest.mark.slow
def test_round_trip_all_rinex_ephemerides():
    ephs, iono = _need_brdc()
    n = 0
    for prn in range(1, 33):
        for eph in ephs.get(prn, []):
            t0 = (eph.toe // 30) * 30 - 30 * 7          # broadcast a bit before toe
            tow0, week = t0 % 604800, eph.week + int(t0 // 604800)
            bits = encode_frames(eph, iono, tow0, week, 1, page18_every_frame=True)
            dec, events = _decode(np.concatenate([bits, bits[:60]]), prn=prn)
            assert dec.parity_failures == 0
            assert dec.ephemeris is not None, prn
            _assert_eph_close(dec.ephemeris, eph)
            assert dec.ephemeris.tx_time == tow0
            n += 1
    assert n > 300
    # IonoUtc
    got = dec.iono_utc
    for k in range(4):
        assert abs(got.alpha[k] - iono.alpha[k]) <= 0.5 * IONO_LSB[f"alpha{k}"]
        assert abs(got.beta[k] - iono.beta[k]) <= 0.5 * IONO_LSB[f"beta{k}"]
    assert abs(got.a0 - iono.a0) <= 0.5 * IONO_LSB["a0"]
    assert abs(got.a1 - iono.a1) <= 0.5 * IONO_LSB["a1"]
    assert got.tot == iono.tot and got.wnt == iono.wnt and got.dt_ls == iono.dt_ls


def test_decoder_events_and_chunked_feed():
    ephs, iono = _need_brdc()
    eph = ephs[7][0]
    tow0 = 518400.0 - 600
    bits = encode_frames(eph, iono, tow0, 2190, 3)
    dec, events = _decode(bits, start=113, chunk=37, prn=7)
    sfe = [e for e in events if isinstance(e, SubframeEvent)]
    # the first complete subframe after bit 113 starts at bit 300
    assert sfe[0].bit_index == 300
    for e in sfe:
        assert e.tow_s == tow0 + 6 * (e.bit_index // 300)
        assert e.subframe_id == (e.bit_index // 300) % 5 + 1
        assert e.polarity == 1
    assert len(sfe) == 14
    assert any(isinstance(e, EphemerisEvent) for e in events)
    _assert_eph_close(dec.ephemeris, eph)
    assert dec.week == 2190


def test_decoder_inverted_polarity():
    ephs, iono = _need_brdc()
    eph = ephs[12][0]
    bits = encode_frames(eph, iono, 518400.0 - 300, 2190, 2, page18_every_frame=True)
    dec, events = _decode(bits, start=5, polarity=-1, prn=12)
    sfe = [e for e in events if isinstance(e, SubframeEvent)]
    assert sfe and all(e.polarity == -1 for e in sfe)
    assert dec.parity_failures == 0
    _assert_eph_close(dec.ephemeris, eph)
    assert any(isinstance(e, IonoUtcEvent) for e in events)


def test_decoder_polarity_flip_midstream():
    ephs, iono = _need_brdc()
    eph = ephs[12][0]
    bits = encode_frames(eph, iono, 518400.0 - 300, 2190, 3)
    soft = _soft(bits)
    soft[1200:] *= -1                      # half-cycle slip at a subframe boundary
    dec = LnavDecoder(prn=12)
    events = dec.feed(soft, 0)
    pols = [e.polarity for e in events if isinstance(e, SubframeEvent)]
    assert pols[:4] == [1, 1, 1, 1] and set(pols[4:]) == {-1} and len(pols) == 15


def test_decoder_bit_errors_never_give_wrong_ephemeris():
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    bits = encode_frames(eph, iono, 518400.0 - 600, 2190, 4)
    rng = np.random.default_rng(5)
    for trial in range(20):
        bad = bits.copy()
        idx = rng.choice(len(bad), size=6, replace=False)
        bad[idx] ^= 1
        dec, events = _decode(bad, prn=3)
        assert dec.parity_failures + dec.words_corrected > 0
        if dec.ephemeris is not None:
            _assert_eph_close(dec.ephemeris, eph)
        for e in events:
            if isinstance(e, SubframeEvent):
                assert e.tow_s == 518400.0 - 600 + 6 * (e.bit_index // 300)


def test_decoder_noise_only_gives_nothing():
    rng = np.random.default_rng(6)
    dec = LnavDecoder()
    events = dec.feed(rng.standard_normal(6000), 0)
    assert events == [] and not dec.synced and dec.ephemeris is None


def test_week_resolution_and_rollover():
    ephs, iono = _need_brdc()
    eph = ephs[1][0]
    # frames around the end of week 2190 (toe 518400 of 2190 is fine for the encoder)
    bits = encode_frames(eph, iono, 604800.0 - 60, 2190, 4)
    dec, events = _decode(bits, prn=1)
    tows = [e.tow_s for e in events if isinstance(e, SubframeEvent)]
    assert tows[:12] == [604740.0 + 6 * k for k in range(10)] + [0.0, 6.0]
    assert dec.week == 2191                         # latest subframe 1 was sent in week 2191
    # a hint in the 1024-week era before
    dec2, _ = _decode(encode_frames(eph, iono, 518400.0 - 300, 2190, 2), prn=1, week_hint=1170)
    assert dec2.week == 2190 - 1024


def test_decoder_loses_and_regains_sync():
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    a = encode_frames(eph, iono, 518400.0 - 600, 2190, 1)
    rng = np.random.default_rng(8)
    junk = rng.integers(0, 2, 1037).astype(np.uint8)
    b = encode_frames(eph, iono, 518400.0 - 300, 2190, 2)
    stream = np.concatenate([a, junk, b])
    dec = LnavDecoder(prn=3)
    events = []
    for i in range(0, len(stream), 50):
        events += dec.feed(_soft(stream[i:i + 50]), i)
    sfe = [e for e in events if isinstance(e, SubframeEvent)]
    first_b = len(a) + len(junk)
    after = [e for e in sfe if e.bit_index >= first_b]
    assert [e.bit_index for e in sfe if e.bit_index < first_b] == [0, 300, 600, 900, 1200]
    assert after and after[0].bit_index == first_b
    for e in after:
        assert e.tow_s == 518400.0 - 300 + 6 * (e.bit_index - first_b) // 300
    assert dec.synced


def test_decoder_gap_in_bit_indices():
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    bits = encode_frames(eph, iono, 518400.0 - 600, 2190, 3)
    soft = _soft(bits)
    dec = LnavDecoder(prn=3)
    ev = dec.feed(soft[:700], 0)
    ev += dec.feed(soft[1650:], 1650)          # bits 700..1649 lost
    sfe = [e for e in ev if isinstance(e, SubframeEvent)]
    assert [e.bit_index for e in sfe][:3] == [0, 300, 1800]
    assert all(e.tow_s == 518400.0 - 600 + 6 * (e.bit_index // 300) for e in sfe)
    _assert_eph_close(dec.ephemeris, eph)
    # overlapping re-feed is ignored
    assert dec.feed(soft[4000:4200], 4000) == []


# ------------------------------------------------------------------ low C/N0: correction, assembly

@pytest.mark.slow
def test_single_bit_errors_corrected_double_errors_never_miscorrected():
    rng = np.random.default_rng(11)
    for _ in range(3):
        d = rng.integers(0, 2, 24).astype(np.uint8)
        p29, p30 = (int(v) for v in rng.integers(0, 2, 2))
        w = encode_word(d, p29, p30)
        for k in range(30):
            bad = w.copy()
            bad[k] ^= 1
            fix = correct_word(bad, p29, p30)
            assert fix is not None and fix[1] == k and np.array_equal(fix[0], w)
        for i, j in itertools.combinations(range(30), 2):
            bad = w.copy()
            bad[[i, j]] ^= 1
            assert correct_word(bad, p29, p30) is None      # detected, not "corrected" into a wrong word


def _flip_in_word(bits, sf_start, word, positions):
    for p in positions:
        bits[sf_start + 30 * (word - 1) + p] ^= 1


def test_one_error_in_every_word_still_decodes_exactly():
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    bits = encode_frames(eph, iono, 518400.0 - 600, 2190, 2)
    rng = np.random.default_rng(12)
    bad = bits.copy()
    for sf in range(1, 10):                  # after the first subframe (frame sync needs a clean one)
        for w in range(1, 11):
            _flip_in_word(bad, 300 * sf, w, [int(rng.integers(0, 30))])
    dec, events = _decode(bad, prn=3)
    assert dec.words_corrected == 90 and dec.parity_failures == 0
    _assert_eph_close(dec.ephemeris, eph)
    tows = [e.tow_s for e in events if isinstance(e, SubframeEvent)]
    assert tows == [518400.0 - 600 + 6 * k for k in range(10)]


def test_ephemeris_assembled_word_by_word_across_frames():
    """Two uncorrectable words in each of subframes 1-3, at different places in each of three frames:
    no frame carries a clean subframe 1, 2 or 3, but together they hold every word."""
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    bits = encode_frames(eph, iono, 518400.0 - 600, 2190, 4)
    bad = bits.copy()
    broken = {0: (4, 5), 1: (6, 7), 2: (9, 10)}          # frame -> words with two bit errors
    for frame, words in broken.items():
        for sf in (0, 1, 2):
            for w in words:
                _flip_in_word(bad, 1500 * frame + 300 * sf, w, [3, 17])
    # frame 0 subframe 1 must still give frame sync: keep its TLM/HOW (words 1-2) intact (they are)
    dec, events = _decode(bad[:1500 * 3], prn=3)
    assert dec.parity_failures == 3 * 3 * 2
    assert dec.ephemeris is not None
    _assert_eph_close(dec.ephemeris, eph)
    # the old rule (a subframe used only when all its words pass) would have had nothing: check the
    # frames really carry no clean subframe 1-3
    from receiver.gnss.lnav import _decode_subframe_bits
    for frame in range(3):
        for sf in range(3):
            s0 = 1500 * frame + 300 * sf
            assert not all(_decode_subframe_bits(bad[s0:s0 + 300])[1])


def test_assembly_never_mixes_issues_of_data():
    """Subframe 2 words from an old issue of data must not complete a subframe 2 of a new one."""
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    new = replace(eph, iode=(eph.iode + 1) % 256, iodc=(eph.iodc + 1) % 1024, crs=eph.crs + 10.0)
    a = encode_frames(eph, iono, 518400.0 - 600, 2190, 1)
    b = encode_frames(new, iono, 518400.0 - 570, 2190, 2)
    bad = np.concatenate([a, b])
    _flip_in_word(bad, 0 + 300, 5, [3, 17])          # old frame: subframe 2 word 5 bad
    _flip_in_word(bad, 1500 + 300, 3, [3, 17])       # new frame 1: subframe 2 word 3 (crs) bad
    dec, events = _decode(bad[:3000], prn=3)
    ephs_out = [e.ephemeris for e in events if isinstance(e, EphemerisEvent)]
    for e in ephs_out:                                # whatever is decoded is one consistent set
        ref = new if e.iode == new.iode else eph
        _assert_eph_close(e, ref)


def test_far_replacement_ephemeris_needs_a_second_reception():
    """A set with the current issue of data that moves the satellite by kilometres (a miscorrected word at
    low C/N0: Omega0 off 2.6 mrad, ~70 km) replaces the current one only when received twice; a genuine
    update (new issue of data, metres) replaces it at once."""
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    bad = replace(eph, omega0=eph.omega0 + 2.6e-3)
    upd = replace(eph, iode=(eph.iode + 1) % 256, iodc=(eph.iodc + 1) % 1024, crs=eph.crs + 10.0)
    t0 = 518400.0 - 600
    bits = np.concatenate([encode_frames(eph, iono, t0, 2190, 2), encode_frames(bad, iono, t0 + 60, 2190, 1)])
    dec, _ = _decode(bits, prn=3)
    _assert_eph_close(dec.ephemeris, eph)                     # held after one reception
    assert dec.ephemerides_held == 1
    dec, _ = _decode(np.concatenate([bits, encode_frames(bad, iono, t0 + 90, 2190, 1)]), prn=3)
    _assert_eph_close(dec.ephemeris, bad)                     # the same set twice: used
    dec, events = _decode(np.concatenate([encode_frames(eph, iono, t0, 2190, 2),
                                          encode_frames(upd, iono, t0 + 60, 2190, 1)]), prn=3)
    _assert_eph_close(dec.ephemeris, upd)
    assert dec.ephemerides_held == 0


def test_first_ephemeris_refused_by_the_check_needs_a_second_reception():
    """A satellite's first ephemeris has no earlier set to compare with: when ``first_check`` refuses it (the
    navigation engine: its range disagrees with the current fix) it is held until a second reception decodes
    the same set; a check with no objection (True / None) uses it at once.  The check sees the TOW and bit
    index of the subframe that completed the set."""
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    bad = replace(eph, omega0=eph.omega0 + 2.6e-3)
    t0 = 518400.0 - 600
    calls = []

    def refuse(e, tow, bit_index):
        calls.append((e.omega0, tow, bit_index))
        return False

    one = encode_frames(bad, iono, t0, 2190, 1)
    dec = LnavDecoder(prn=3)
    dec.first_check = refuse
    dec.feed(_soft(one), 0)
    assert dec.ephemeris is None and dec.ephemerides_held == 1
    assert calls == [(pytest.approx(bad.omega0, abs=EPH_LSB["omega0"]), t0 + 12.0, 600)]
    events = dec.feed(_soft(encode_frames(bad, iono, t0 + 30, 2190, 1)), len(one))
    _assert_eph_close(dec.ephemeris, bad)                       # received twice: used
    assert any(isinstance(e, EphemerisEvent) for e in events)
    for verdict in (True, None):
        dec = LnavDecoder(prn=3)
        dec.first_check = lambda e, tow, bit_index: verdict
        dec.feed(_soft(one), 0)
        _assert_eph_close(dec.ephemeris, bad)
        assert dec.ephemerides_held == 0


def test_corrupted_subframe_2_reassembled_with_the_next_subframe_is_not_a_second_reception():
    """A vector channel coasting through a total outage demodulates noise: words of subframe 2 after its (good)
    IODE word pass parity by chance (single-bit correction accepts ~half of random words) and the set built
    from them has the current issue of data.  Far (the satellite ~20 000 km off) it is held; the next subframe
    3 assembles the same set again from the same subframe 2 - before, that counted as the second reception
    and the corrupted set replaced the good one (run with seed 2 of configs/scenarios/outage_fig8.yaml,
    vector adaptive_r: G30 82 000 km off, every later fix refused).  Near (3 m) with the current issue of
    data it is a decoding error too.  Neither replaces the current set; two genuine receptions still do."""
    ephs, iono = _need_brdc()
    eph = ephs[3][0]
    t0 = 518400.0 - 600
    for bad in (replace(eph, sqrt_a=eph.sqrt_a * 1.3), replace(eph, crs=eph.crs + 3.0)):
        good = encode_frames(eph, iono, t0, 2190, 4)
        wrong = encode_frames(bad, iono, t0, 2190, 4)
        bits = good.copy()
        bits[2 * 1500 + 300:2 * 1500 + 600] = wrong[2 * 1500 + 300:2 * 1500 + 600]    # frame 2: its subframe 2
        for end in (2 * 1500 + 900, 3 * 1500 + 300, 4 * 1500):     # after subframe 3, next subframe 1, the end
            dec, _ = _decode(bits[:end], prn=3)
            _assert_eph_close(dec.ephemeris, eph)
            assert dec.ephemerides_held == 1
        # the same set received twice (two whole frames): used
        dec, _ = _decode(np.concatenate([good[:3000], wrong[3000:]]), prn=3)
        _assert_eph_close(dec.ephemeris, bad)
