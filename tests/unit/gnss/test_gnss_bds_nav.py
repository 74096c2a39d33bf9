"""BeiDou B1I navigation: BCH(15,11) + interleaving, D1/D2 subframes encoded by the simulator's
BdsNavBits and decoded by BdsDecoder (ephemerides equal to the broadcast ones), BDT <-> GPST, and the
BDS orbit algorithm (GEO case with the -5 deg rotation)."""
import math
from dataclasses import fields

import numpy as np
import pytest

from receiver.gnss.bds_ephemeris import BdsEphemeris, bds_sat_state
from receiver.gnss.bds_nav import (EPH_LSB, PREAMBLE, BdsDecoder, BdsNavBits, bch_decode, bch_encode,
                                   bdt_from_gps, decode_words, encode_words, gps_from_bdt)
from receiver.gnss.ephemeris import sat_state
from receiver.gnss.geodesy import ecef2lla
from receiver.gnss.signals_bds import nh_signs
from receiver.sim.bds_constellation import bds_nominal_ephemerides

from repo_paths import ROOT as REPO
WEEK, TOW = 2300, 345600.0


@pytest.fixture(scope="module")
def nominal():
    return bds_nominal_ephemerides(REPO / "data/bds_nominal_constellation.yaml", WEEK, TOW)


def _poly_mod(v, n=15):
    for k in range(n - 1, 3, -1):
        if v >> k & 1:
            v ^= 0b10011 << (k - 4)
    return v


def test_bch_codewords_are_multiples_of_g_and_correct_one_error():
    rng = np.random.default_rng(1)
    for info in list(rng.integers(0, 2048, 200)) + [0, 2047, 1]:
        cw = bch_encode(int(info))
        assert cw >> 4 == info and _poly_mod(cw) == 0            # systematic, divisible by X^4 + X + 1
        assert bch_decode(cw) == (info, False)
        for pos in range(15):
            assert bch_decode(cw ^ (1 << pos)) == (info, True)


def test_words_2_to_10_interleave_two_codewords_bit_by_bit():
    rng = np.random.default_rng(2)
    info = [int(b) for b in rng.integers(0, 2, 224)]
    info[:11] = PREAMBLE
    bits = encode_words(info)
    assert len(bits) == 300 and tuple(bits[:11]) == PREAMBLE
    w2 = bits[30:60]
    a, b = w2[0::2], w2[1::2]
    assert int("".join(map(str, a[:11])), 2) == int("".join(map(str, info[26:37])), 2)
    assert int("".join(map(str, b[:11])), 2) == int("".join(map(str, info[37:48])), 2)
    back, fixed = decode_words(bits)
    assert back == info and fixed == 0
    noisy = bits.copy()
    for w in range(10):                      # one error in every BCH block
        noisy[30 * w + 20] ^= 1
        if w:
            noisy[30 * w + 3] ^= 1
    back, fixed = decode_words(noisy)
    assert back == info and fixed == 19


def test_bdt_gpst():
    assert bdt_from_gps(2300, 345600.0) == (944, 345586.0)
    assert bdt_from_gps(2300, 5.0) == (943, 604791.0)              # GPS week start is still BDT week 943
    assert gps_from_bdt(943, 604791.0) == (2300, 5.0)
    assert gps_from_bdt(944, 345586.0) == (2300, 345600.0)


def _stream(eph, iono, geo, ms0, n, invert=True):
    """Soft symbols as the tracking loop delivers them (NH wiped off for D1), and the GPS ms of symbol 0."""
    sg = BdsNavBits(eph, iono, WEEK, geo).signs(ms0, n)
    bdt = ms0 + np.arange(n) - 14000
    if not geo:
        sg = sg * nh_signs()[bdt % 20]
    sym = 2 if geo else 20
    start = int((-bdt[0]) % sym)
    soft = sg[start:start + (n - start) // sym * sym:sym].astype(float)
    return (-soft if invert else soft), ms0 + start


@pytest.mark.parametrize("prn,geo", [(11, False), (8, False), (1, True), (3, True)])
def test_decoded_ephemeris_equals_the_broadcast_one(nominal, prn, geo):
    ephs, iono = nominal
    n = 40000 if not geo else 33000          # D1: ephemeris in subframes 1-3 (30 s frame); D2: 10 pages
    soft, ms_first = _stream(ephs[prn], iono, geo, int(TOW * 1000) + 137, n)
    rng = np.random.default_rng(prn)
    noisy = soft * (1.0 + 0.3 * rng.standard_normal(soft.size))
    dec = BdsDecoder(prn, geo=geo)
    evs = dec.feed(noisy, 0)
    assert dec.polarity == -1 and evs
    for ev in evs:                           # GPS time of the subframe start = its first bit's time
        assert ev.tow_s == pytest.approx((ms_first + ev.bit_index * (2 if geo else 20)) / 1000.0, abs=1e-9)
    assert dec.week == WEEK
    e = dec.ephemeris
    assert isinstance(e, BdsEphemeris)
    for f in fields(BdsEphemeris):
        if f.compare:
            assert getattr(e, f.name) == getattr(ephs[prn], f.name), f.name
    assert dec.iono_utc.alpha == pytest.approx(iono.alpha, abs=2.0 ** -30)


def test_decoder_needs_two_consistent_subframes_and_survives_gaps(nominal):
    ephs, iono = nominal
    soft, _ = _stream(ephs[11], iono, False, int(TOW * 1000), 20000, invert=False)
    dec = BdsDecoder(11)
    assert dec.feed(soft[:200], 0) == [] and not dec.synced
    evs = dec.feed(soft[200:], 200)
    assert dec.synced and dec.polarity == 1 and len(evs) >= 1
    assert dec.feed(soft[:10], 5000) == [] and not dec.synced       # a gap: frame sync again


def test_quantisation_grid(nominal):
    ephs, _ = nominal
    for e in ephs.values():
        for name, (attr, lsb) in EPH_LSB.items():
            v = getattr(e, attr) / lsb
            assert v == pytest.approx(round(v), abs=1e-6), (e.prn, name)


def test_geo_algorithm_keeps_a_geostationary_satellite_fixed(nominal):
    """The nominal GEO at 140 E, broadcast in the ICD's -5 deg GEO frame, stays over 140 E on the equator."""
    ephs, _ = nominal
    t = TOW + np.linspace(0.0, 12 * 3600.0, 25)
    pos, vel, clk, drift = sat_state(ephs[1], t)
    lla = np.array([ecef2lla(p) for p in pos])
    assert np.all(np.abs(lla[:, 0]) < 0.05) and np.all(np.abs(lla[:, 1] - 140.0) < 0.05)
    assert np.all(np.abs(np.linalg.norm(pos, axis=1) - 42164.2e3) < 20e3)
    assert np.all(np.linalg.norm(vel, axis=1) < 5.0)          # ECEF velocity of a GEO: ~0
    # a sign error in either rotation would swing the satellite through +/-5 deg of latitude daily
    e = ephs[1]
    wrong = BdsEphemeris(**{**{f.name: getattr(e, f.name) for f in fields(e)}, "prn": 11})   # MEO formula
    lat_wrong = [ecef2lla(p)[0] for p in sat_state(wrong, t)[0]]
    assert np.ptp(lat_wrong) > 5.0


def test_meo_state_is_consistent(nominal):
    ephs, _ = nominal
    t = TOW + 100.0
    p0, v0, c0, d0 = sat_state(ephs[11], t)
    p1, _, c1, _ = sat_state(ephs[11], t + 1.0)
    np.testing.assert_allclose(p1 - p0, sat_state(ephs[11], t + 0.5)[1], atol=0.01)   # mid-point velocity
    assert abs(np.linalg.norm(p0) - 27906.1e3) < 100e3
    period = 2 * math.pi / math.sqrt(3.986004418e14 / ephs[11].sqrt_a ** 6)
    assert period / 3600 == pytest.approx(12.87, abs=0.02)     # 7 revolutions in 7 sidereal days
    # a list mixing GPS and BeiDou ephemerides gives each its own algorithm
    from receiver.sim.constellation import nominal_ephemerides
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", WEEK, TOW)
    mixed = [gps[3], ephs[11], ephs[1]]
    pm, vm, cm, dm = sat_state(mixed, np.array([t, t, t]))
    for k, e in enumerate(mixed):
        ps, vs, cs, ds = sat_state(e, t)
        np.testing.assert_allclose(pm[k], ps, atol=1e-6)
        assert cm[k] == pytest.approx(cs, abs=1e-15)
    np.testing.assert_allclose(bds_sat_state([ephs[11]], [t])[0][0], p0, atol=1e-6)


def test_rinex3_beidou_records_round_trip(nominal, tmp_path):
    """Our BeiDou RINEX 3 records read back as the same ephemerides (RTKLIB reads the same files:
    scripts/bench/accuracy_bds.py), and a mixed file keeps GPS and BeiDou apart."""
    from receiver.gnss.rinex import read_rinex_nav, write_rinex_nav
    from receiver.sim.bds_constellation import bds_rinex_ephemerides
    from receiver.sim.constellation import nominal_ephemerides
    ephs, iono = nominal
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", WEEK, TOW)
    out = tmp_path / "mixed.rnx"
    write_rinex_nav(out, list(ephs.values()) + [gps[3]], iono)
    assert "M: MIXED" in out.read_text().splitlines()[0]
    back, iono2 = read_rinex_nav(out, systems=("C",))
    assert sorted(back) == sorted(ephs)
    for prn, e in ephs.items():
        b = back[prn][0]
        assert isinstance(b, BdsEphemeris)
        for f in fields(BdsEphemeris):
            if f.compare and f.name != "system":
                assert getattr(b, f.name) == pytest.approx(getattr(e, f.name), rel=1e-11, abs=1e-20), f.name
    assert iono2.alpha == pytest.approx(iono.alpha, rel=1e-3)
    g, _ = read_rinex_nav(out)                          # default: GPS/QZSS records only
    assert sorted(g) == [3] and not isinstance(g[3][0], BdsEphemeris)
    sim, _ = bds_rinex_ephemerides(out, WEEK, TOW + 20.0)   # the simulator's bds_rinex source
    assert sim == {p: e for p, e in ephs.items() if p <= 37}


def test_far_replacement_ephemeris_needs_a_second_reception(nominal):
    """A BCH block with two errors is 'corrected' into a wrong codeword, so a corrupted set can decode:
    a replacement that moves the satellite by more than JUMP_M is used only when a second reception
    decodes the same set; a genuine update (metres, new AODE) replaces at once."""
    from dataclasses import replace

    from receiver.gnss.bds_nav import quantize_bds
    ephs, iono = nominal
    good = ephs[11]
    far = quantize_bds(replace(good, omega0=good.omega0 + 1e-3))           # ~ 27 km along the orbit
    # a genuine update: metres, and a new issue of data (the same AODE with other contents is held too)
    near = quantize_bds(replace(far, af0=far.af0 + 2e-9, iode=far.iode + 1, iodc=far.iodc + 1))
    ms0 = int(TOW * 1000)                                                  # a D1 bit edge (BDT ms % 20 == 0)
    dec = BdsDecoder(11)
    pieces = [(good, 40000), (far, 30000), (far, 30000), (near, 30000)]
    seen, idx, ms = [], 0, ms0
    for eph, n in pieces:
        soft, first = _stream(eph, iono, False, ms, n, invert=False)
        assert first == ms
        dec.feed(soft, idx)
        idx += len(soft)
        ms += n
        seen.append((dec.ephemeris, dec.ephemerides_held))
    assert seen[0] == (good, 0)
    assert seen[1] == (good, 1)          # first reception of the far set: held
    assert seen[2] == (far, 1)           # the same set again: used
    assert seen[3] == (near, 1)          # a near update: at once


def test_held_set_assembled_again_with_the_same_corrupted_subframe_is_not_a_second_reception(nominal):
    """A subframe 2 corrupted into a valid-looking one (two errors in a BCH block) gives a far set when the
    next subframe 3 completes it; the next frame's subframe 1 completes the *same* set again from the same
    corrupted subframe 2 — that is not a second reception: the set must never be used."""
    from dataclasses import replace

    from receiver.gnss.bds_nav import quantize_bds
    ephs, iono = nominal
    good = ephs[11]
    bad = quantize_bds(replace(good, m0=good.m0 + 1e-3))           # subframe 2 field: ~27 km along the orbit
    ms0 = int(TOW * 1000)
    n = 100000
    soft_good, _ = _stream(good, iono, False, ms0, n, invert=False)
    soft_bad, _ = _stream(bad, iono, False, ms0, n, invert=False)
    evs = BdsDecoder(11).feed(soft_good, 0)
    sf2 = [e.bit_index for e in evs if e.subframe_id == 2]
    assert len(sf2) >= 2
    b = sf2[1]                                        # the second frame's subframe 2 (the first set is good)
    mixed = soft_good.copy()
    mixed[b:b + 300] = soft_bad[b:b + 300]
    dec = BdsDecoder(11)
    used = []
    for i in range(0, mixed.size, 50):                # fed in 1-s pieces, as the navigation engine does
        dec.feed(mixed[i:i + 50], i)
        used.append(dec.ephemeris)
    mixed_set = quantize_bds(replace(good, m0=bad.m0))
    assert dec.ephemerides_held >= 1                  # the corrupted set was seen ...
    assert all(e is None or e == good for e in used)  # ... and never used
    assert used[-1] == good and mixed_set != good
