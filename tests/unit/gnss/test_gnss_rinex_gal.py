"""RINEX 3 Galileo navigation records (receiver.gnss.rinex_gal through read_rinex_nav / write_rinex_nav):
round trip within the format's precision, the same orbits and clocks from the read records, the fields at
the positions of the RINEX 3.04 Galileo record, F/NAV and repeated records, mixed files, header lines."""
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

from receiver.errors import UserError
from receiver.gnss.ephemeris import sat_state
from receiver.gnss.gal_inav import GalEphemeris, Ggto, NequickG, quantize_gal
from receiver.gnss.rinex import read_rinex_nav, write_rinex_nav
from receiver.gnss.rinex_gal import (GAL_INAV_E1B_SOURCE, full_week, read_gal_header, sisa_index_from_m,
                                     sisa_m_from_index)
from receiver.sim.gal_constellation import gal_nominal_content

REPO = Path(__file__).resolve().parents[3]
WEEK, TOW = 2190, 345600.0 + 1234.0


@pytest.fixture(scope="module")
def gal():
    """Quantised nominal Galileo ephemerides with non-trivial values in the fields the nominal file leaves
    at zero (harmonics, rates, af2, BGDs, health bits, SISA, transmission time)."""
    content = gal_nominal_content(REPO / "data/gal_nominal_constellation.yaml", WEEK, TOW)
    rng = np.random.default_rng(33)
    out = {}
    for k, (prn, c) in enumerate(sorted(content.items())):
        e = c.eph
        e = replace(e, cuc=rng.normal(0, 3e-6), cus=rng.normal(0, 3e-6), crc=rng.normal(0, 200),
                    crs=rng.normal(0, 80), cic=rng.normal(0, 1e-7), cis=rng.normal(0, 1e-7),
                    delta_n=rng.normal(0, 3e-9), idot=rng.normal(0, 3e-10), af0=rng.normal(0, 5e-4),
                    af1=rng.normal(0, 5e-12), af2=1e-19 * (k % 3), tgd=rng.normal(0, 5e-9),
                    bgd_e1e5a=rng.normal(0, 5e-9), health=k % 8, e5b_hs=k % 4, e5b_dvs=(k // 4) % 2,
                    ura_index=(0, 49, 50, 74, 75, 99, 100, 107, 125, 255)[k % 10])
        out[prn] = replace(quantize_gal(e), tx_time=e.toe + 30.0 * (k % 5))
    return out, content


def test_sisa_table():
    """SISA index -> metres as the ICD's SISA table defines it, and back."""
    assert [sisa_m_from_index(i) for i in (0, 1, 49, 50, 51, 74, 75, 76, 99, 100, 101, 107, 125)] == \
        pytest.approx([0.0, 0.01, 0.49, 0.50, 0.52, 0.98, 1.00, 1.04, 1.96, 2.00, 2.16, 3.12, 6.00])
    assert sisa_m_from_index(255) == -1.0 and sisa_m_from_index(200) == -1.0
    for i in range(126):
        assert sisa_index_from_m(float(f"{sisa_m_from_index(i):.12E}")) == i
    assert sisa_index_from_m(-1.0) == 255 and sisa_index_from_m(float("nan")) == 255
    assert sisa_index_from_m(50.0) == 255


def test_full_week():
    """The continuous week nearest the reference with the broadcast 8-bit / 6-bit value."""
    assert full_week(2190 % 256, 256, 2190) == 2190
    assert full_week(5, 256, 2300) == 2309                        # 2309 = 9 * 256 + 5, 9 weeks ahead
    assert full_week(250, 256, 2309) == 2298                      # 11 weeks back, not 245 ahead
    assert full_week(2, 64, 1190) == 1218                         # 1190 % 64 = 38: 28 ahead, not 36 back


def test_galileo_round_trip_and_orbits(gal, tmp_path):
    """Written then read: every field within the 13 significant digits of the format (integers exact),
    and the satellite positions / clocks from the read records equal the original ones."""
    ephs, _ = gal
    out = tmp_path / "gal.rnx"
    write_rinex_nav(out, list(ephs.values()))
    lines = out.read_text().splitlines()
    assert lines[0][20:60] == "N: GNSS NAV DATA    E: Galileo".ljust(40)
    back, iono = read_rinex_nav(out, systems=("E",))
    assert iono is None and sorted(back) == sorted(ephs)
    for prn, e in ephs.items():
        assert len(back[prn]) == 1
        b = back[prn][0]
        assert isinstance(b, GalEphemeris) and b.system == "E"
        for f in fields(GalEphemeris):
            va, vb = getattr(e, f.name), getattr(b, f.name)
            if isinstance(va, (int, str)):
                assert vb == va, (prn, f.name)
            else:
                assert vb == pytest.approx(va, rel=1e-12, abs=1e-24), (prn, f.name)
        t = e.toe + np.array([-3600.0, 0.0, 1800.0, 7200.0])
        p0, v0, c0, d0 = sat_state(e, t)
        p1, v1, c1, d1 = sat_state(b, t)
        np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-4)       # 0.1 mm
        np.testing.assert_allclose(v1, v0, rtol=0, atol=1e-7)
        np.testing.assert_allclose(c1, c0, rtol=0, atol=1e-14)      # 3 micrometres


def test_record_fields_at_the_standard_positions(gal, tmp_path):
    """The values sit where the RINEX 3.04 Galileo record puts them: 4-character indent, 19-character
    fields; line 5 IDOT, data sources, GAL week; line 6 SISA (m), health, BGD E5a/E1, BGD E5b/E1."""
    ephs, _ = gal
    e = replace(ephs[3], health=0b101, e5b_hs=2, e5b_dvs=1, ura_index=107)
    out = tmp_path / "one.rnx"
    write_rinex_nav(out, [e])
    lines = out.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    rec = lines[k:k + 8]
    assert len(lines) == k + 8 and rec[0][:3] == "E03"
    num = [[float(ln[4 + 19 * j:4 + 19 * (j + 1)].replace("D", "E") or 0) for j in range(4)] for ln in rec[1:7]]
    assert num[0][0] == e.iode and num[2][0] == e.toe
    assert num[4][1] == GAL_INAV_E1B_SOURCE == 513 and num[4][2] == e.week == WEEK
    assert num[5][0] == pytest.approx(3.12) and num[5][1] == 0b101 | 1 << 6 | 2 << 7
    assert num[5][2] == pytest.approx(e.bgd_e1e5a, rel=1e-12) and num[5][3] == pytest.approx(e.tgd, rel=1e-12)
    y, mo, d, hh, mm, ss = (int(v) for v in rec[0][4:23].split())
    from receiver.gnss.time import gps_time_from_calendar
    assert gps_time_from_calendar(y, mo, d, hh, mm, ss) == (WEEK, e.toc)


def test_fnav_and_repeated_records(gal, tmp_path):
    """An F/NAV record (data sources 258: the E5a clock) is not an E1 user's; a batch repeated from E5b
    (data sources 516) is read once."""
    ephs, _ = gal
    out = tmp_path / "gal.rnx"
    write_rinex_nav(out, [ephs[1], ephs[2]])
    text = out.read_text()
    lines = text.splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    rec1, rec2 = lines[k:k + 8], lines[k + 8:k + 16]
    assert rec1[0][:3] == "E01"
    field = f"{float(GAL_INAV_E1B_SOURCE): .12E}".rjust(19)
    fnav = [ln.replace(field, f"{258.0: .12E}".rjust(19)) for ln in rec2]
    e5b = [ln.replace(field, f"{516.0: .12E}".rjust(19)) for ln in rec1]
    assert fnav != rec2 and e5b != rec1
    odd = tmp_path / "odd.rnx"
    odd.write_text("".join(lines[:k] + rec1 + e5b + fnav))
    back, _ = read_rinex_nav(odd, systems=("E",))
    plain, _ = read_rinex_nav(out, systems=("E",))
    assert sorted(back) == [1] and back[1] == plain[1]
    only_fnav = tmp_path / "fnav.rnx"
    only_fnav.write_text("".join(lines[:k] + fnav))
    with pytest.raises(UserError, match="no usable Galileo navigation records"):
        read_rinex_nav(only_fnav, systems=("E",))


def test_mixed_file_keeps_systems_apart(gal, tmp_path):
    """GPS + BeiDou + Galileo records in one mixed file: each reader call gets its own system's records,
    and the Galileo header lines come back."""
    from receiver.sim.bds_constellation import bds_nominal_ephemerides
    from receiver.sim.constellation import nominal_ephemerides
    ephs, content = gal
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", WEEK, TOW)
    bds, bio = bds_nominal_ephemerides(REPO / "data/bds_nominal_constellation.yaml", WEEK, TOW)
    c = content[1]
    params = {"nequick": NequickG(ai0=63.75, ai1=0.25, ai2=-0.0078125),
              "utc": replace(c.utc, a0=2.0 ** -30 * 3, a1=-2.0 ** -50), "ggto": Ggto(3e-9, -2e-14, 345600.0, 2),
              "gst_week": c.eph.gst_week}
    out = tmp_path / "mixed.rnx"
    write_rinex_nav(out, list(ephs.values()) + [gps[3], gps[7]] + [bds[11]], bio, gal=params)
    head = out.read_text().splitlines()
    assert head[0][40:60].strip() == "M: MIXED"
    assert sum(1 for ln in head if ln[60:].strip() == "TIME SYSTEM CORR") == 3
    g, _ = read_rinex_nav(out)
    b, _ = read_rinex_nav(out, systems=("C",))
    e, io = read_rinex_nav(out, systems=("E",))
    assert sorted(g) == [3, 7] and (g[3][0].iodc, g[3][0].toe) == (gps[3].iodc, gps[3].toe)
    assert sorted(b) == [11] and b[11][0].tgd2 == pytest.approx(bds[11].tgd2, rel=1e-12)
    assert sorted(e) == sorted(ephs) and all(isinstance(v[0], GalEphemeris) for v in e.values())
    assert io.alpha == pytest.approx(bio.alpha, rel=1e-3)
    h = read_gal_header(out)
    assert (h["nequick"].ai0, h["nequick"].ai1, h["nequick"].ai2) == pytest.approx((63.75, 0.25, -0.0078125))
    u = params["utc"]
    assert h["utc"].a0 == pytest.approx(u.a0, rel=1e-9) and h["utc"].a1 == pytest.approx(u.a1, rel=1e-8)
    assert (h["utc"].tot, h["utc"].wnot) == (u.tot, u.wnot)
    gg = h["ggto"]
    assert (gg.a0g, gg.a1g, gg.t0g, gg.wn0g) == pytest.approx((3e-9, -2e-14, 345600.0, 2))


def test_galileo_reader_errors(tmp_path, gal):
    """One clear line for a GPS-only file, a RINEX 2 file and a malformed Galileo record."""
    ephs, _ = gal
    gps_only = tmp_path / "gps.rnx"
    from receiver.sim.constellation import nominal_ephemerides
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", WEEK, TOW)
    write_rinex_nav(gps_only, [gps[3]])
    with pytest.raises(UserError, match="for system 'G', not Galileo"):
        read_rinex_nav(gps_only, systems=("E",))
    with pytest.raises(UserError, match="Galileo needs RINEX 3"):
        read_rinex_nav(_rinex2(tmp_path), systems=("E",))
    out = tmp_path / "gal.rnx"
    write_rinex_nav(out, [ephs[5]])
    lines = out.read_text().splitlines(keepends=True)
    lines[-3] = lines[-3][:10] + "X" + lines[-3][11:]
    out.write_text("".join(lines))
    with pytest.raises(UserError, match="bad Galileo navigation record 'E05"):
        read_rinex_nav(out, systems=("E",))


def _rinex2(tmp_path):
    p = tmp_path / "nav.22n"
    p.write_text("     2              NAVIGATION DATA                         RINEX VERSION / TYPE\n"
                 "                                                            END OF HEADER\n")
    return p
