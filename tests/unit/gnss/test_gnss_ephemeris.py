"""Broadcast ephemeris: RINEX reading/writing and satellite state computation."""
import math
from dataclasses import fields, replace

import numpy as np
import pytest

from receiver.errors import UserError
from receiver.gnss.ephemeris import (Ephemeris, earth_rotation, sat_state,
                                    select)
from receiver.gnss.rinex import (gps_time_from_calendar, read_rinex_nav, ura_index_from_m,
                                write_rinex_nav)
from receiver.gnss.signals import F_REL, MU_GPS, OMEGA_E

from repo_paths import SHARED_DATA as DATA
BRDC = DATA / "brdc0010.22n"


@pytest.fixture(scope="module")
def brdc():
    if not BRDC.exists():
        pytest.skip(f"shared test data absent: {BRDC}")
    return read_rinex_nav(BRDC)


# ------------------------------------------------------------------ RINEX

def test_read_rinex2(brdc):
    ephs, iono = brdc
    assert sorted(ephs) == list(range(1, 33))
    assert sum(len(v) for v in ephs.values()) == 422
    e = ephs[1][0]
    assert (e.week, e.toe, e.toc) == (2190, 518400.0, 518400.0)
    assert e.af0 == pytest.approx(0.469126738608e-03, rel=1e-12)
    assert e.sqrt_a == pytest.approx(0.515367499542e+04, rel=1e-12)
    assert e.crs == -141.125 and e.iode == 39 and e.iodc == 39
    assert e.m0 == pytest.approx(-0.624294238235, rel=1e-12)
    assert e.tgd == pytest.approx(0.512227416039e-08) and e.tx_time == 511218.0
    assert e.ura_index == 0 and e.health == 0 and e.fit_interval == 0 and e.code_on_l2 == 1
    assert iono.alpha == pytest.approx((0.1211e-07, -0.7451e-08, -0.5960e-07, 0.1192e-06))
    assert iono.beta == pytest.approx((0.1167e6, -0.2458e6, -0.6554e5, 0.1114e7))
    assert iono.a0 == pytest.approx(0.279396772385e-08) and iono.tot == 147456 and iono.wnt == 2191
    assert iono.dt_ls == 18
    for lst in ephs.values():
        assert all(a.week * 604800 + a.toe <= b.week * 604800 + b.toe for a, b in zip(lst, lst[1:]))


def test_gps_time_from_calendar():
    assert gps_time_from_calendar(1980, 1, 6, 0, 0, 0.0) == (0, 0.0)
    assert gps_time_from_calendar(2022, 1, 1, 0, 0, 0.0) == (2190, 518400.0)
    assert gps_time_from_calendar(2022, 1, 2, 0, 0, 30.5) == (2191, 30.5)


def test_ura_index():
    assert [ura_index_from_m(v) for v in (2.0, 2.8, 4.0, 5.7, 8.0, 11.3, 16, 32, 6144, 1e5)] == \
        [0, 1, 2, 3, 4, 5, 6, 7, 14, 15]


def test_rinex3_round_trip(brdc, tmp_path):
    ephs, iono = brdc
    iono = replace(iono, dt_lsf=18, wn_lsf=1929, dn=7)
    out = tmp_path / "nav.rnx"
    write_rinex_nav(out, ephs, iono)
    back, iono2 = read_rinex_nav(out)
    assert sorted(back) == sorted(ephs)
    for prn in ephs:
        assert len(back[prn]) == len(ephs[prn])
        for a, b in zip(ephs[prn], back[prn]):
            for f in fields(Ephemeris):
                va, vb = getattr(a, f.name), getattr(b, f.name)
                if f.name == "aodo":
                    continue
                assert vb == pytest.approx(va, rel=1e-11, abs=1e-20), (prn, f.name)
    assert iono2.alpha == pytest.approx(iono.alpha, rel=1e-3)
    assert iono2.beta == pytest.approx(iono.beta, rel=1e-3)
    assert iono2.a0 == pytest.approx(iono.a0, rel=1e-9) and iono2.a1 == pytest.approx(iono.a1, rel=1e-8)
    assert (iono2.tot, iono2.wnt, iono2.dt_ls, iono2.dt_lsf, iono2.wn_lsf, iono2.dn) == \
        (147456, 2191, 18, 18, 1929, 7)


def test_rinex3_mixed_file_skips_other_systems(brdc, tmp_path):
    ephs, iono = brdc
    out = tmp_path / "gps.rnx"
    write_rinex_nav(out, {1: ephs[1][:2], 2: ephs[2][:1]}, iono)
    lines = out.read_text().splitlines(keepends=True)
    hdr_end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    lines[0] = lines[0][:40] + "M: MIXED".ljust(20) + lines[0][60:]
    glo = ["R05 2022 01 01 00 15 00 0.1D-04 0.0D+00 0.0D+00\n"] + ["     0.1D+01 0.0D+00 0.0D+00 0.0D+00\n"] * 3
    gal = ["E11 2022 01 01 00 10 00 0.1D-03 0.0D+00 0.0D+00\n"] + ["     0.1D+01 0.0D+00 0.0D+00 0.0D+00\n"] * 7
    mixed = tmp_path / "mixed.rnx"
    mixed.write_text("".join(lines[:hdr_end] + glo + lines[hdr_end:hdr_end + 8] + gal + lines[hdr_end + 8:]))
    back, _ = read_rinex_nav(mixed)
    assert sorted(back) == [1, 2] and len(back[1]) == 2
    assert back[1][0] == ephs[1][0]


def test_rinex_errors(tmp_path):
    with pytest.raises(UserError):
        read_rinex_nav(tmp_path / "missing.22n")
    bad = tmp_path / "bad.22n"
    bad.write_text("hello\n")
    with pytest.raises(UserError):
        read_rinex_nav(bad)
    glo = tmp_path / "glo.22g"
    glo.write_text("     2.11           G: GLONASS NAV DATA                     RINEX VERSION / TYPE\n"
                   "                                                            END OF HEADER\n")
    with pytest.raises(UserError):
        read_rinex_nav(glo)
    trunc = tmp_path / "trunc.22n"
    text = ("     2              NAVIGATION DATA                         RINEX VERSION / TYPE\n"
            "                                                            END OF HEADER\n"
            " 1 22  1  1  0  0  0.0 0.469126738608D-03-0.100044417195D-10 0.000000000000D+00\n"
            "    0.390000000000D+02-0.141125000000D+03 0.398838041777D-08-0.624294238235D+00\n")
    trunc.write_text(text)
    with pytest.raises(UserError):
        read_rinex_nav(trunc)


# ------------------------------------------------------------------ satellite state

def _reference_orbit(eph: Ephemeris, t):
    """Independent formulation: fixed-point Kepler, rotation matrices (ECEF at time t)."""
    t = np.atleast_1d(np.asarray(t, float))
    a = eph.sqrt_a ** 2
    tk = t - eph.toe
    tk = np.where(tk > 302400, tk - 604800, np.where(tk < -302400, tk + 604800, tk))
    mean_motion = math.sqrt(MU_GPS) / eph.sqrt_a ** 3 + eph.delta_n
    m = eph.m0 + mean_motion * tk
    e_anom = m.copy()
    for _ in range(60):                                  # fixed point E = M + e sin E
        e_anom = m + eph.e * np.sin(e_anom)
    true_anom = 2.0 * np.arctan(np.sqrt((1 + eph.e) / (1 - eph.e)) * np.tan(e_anom / 2))
    arg_lat = true_anom + eph.omega
    harm = np.stack([np.sin(2 * arg_lat), np.cos(2 * arg_lat)])
    u = arg_lat + np.array([eph.cus, eph.cuc]) @ harm
    r = a * (1 - eph.e * np.cos(e_anom)) + np.array([eph.crs, eph.crc]) @ harm
    inc = eph.i0 + eph.idot * tk + np.array([eph.cis, eph.cic]) @ harm
    node = eph.omega0 + (eph.omega_dot - OMEGA_E) * tk - OMEGA_E * eph.toe
    out = []
    for k in range(len(t)):
        in_plane = np.array([r[k] * np.cos(u[k]), r[k] * np.sin(u[k]), 0.0])
        ci, si = np.cos(inc[k]), np.sin(inc[k])
        cn, sn = np.cos(node[k]), np.sin(node[k])
        rot_x = np.array([[1, 0, 0], [0, ci, -si], [0, si, ci]])
        rot_z = np.array([[cn, -sn, 0], [sn, cn, 0], [0, 0, 1]])
        out.append(rot_z @ rot_x @ in_plane)
    clk = (eph.af0 + eph.af1 * (t - eph.toc) + eph.af2 * (t - eph.toc) ** 2
           + F_REL * eph.e * eph.sqrt_a * np.sin(e_anom) - eph.tgd)
    return np.array(out), clk


def test_sat_state_against_reference(brdc):
    ephs, _ = brdc
    for prn in (1, 7, 13, 24, 32):
        for eph in ephs[prn][:3]:
            t_sv = eph.toe + np.array([-7200.0, -1800.0, 0.0, 900.0, 7199.0])
            pos, vel, clk, drift = sat_state(eph, t_sv)
            t_true = t_sv - clk
            ref_pos, ref_clk = _reference_orbit(eph, t_true)
            assert np.max(np.linalg.norm(pos - ref_pos, axis=1)) < 0.01
            assert np.max(np.abs(clk - ref_clk)) < 1e-12
            # velocity and drift vs centred differences of the reference
            p_plus, c_plus = _reference_orbit(eph, t_true + 0.5)
            p_minus, c_minus = _reference_orbit(eph, t_true - 0.5)
            assert np.max(np.abs(vel - (p_plus - p_minus))) < 1e-4
            assert np.max(np.abs(drift - (c_plus - c_minus))) < 1e-15


def test_sat_state_physics(brdc):
    ephs, _ = brdc
    allephs = [e for lst in ephs.values() for e in lst]
    t = np.array([e.toe + 1234.0 for e in allephs])
    pos, vel, clk, drift = sat_state(allephs, t)            # vectorised over satellites
    assert pos.shape == (len(allephs), 3) and clk.shape == (len(allephs),)
    a = np.array([e.sqrt_a ** 2 for e in allephs])
    ecc = np.array([e.e for e in allephs])
    r = np.linalg.norm(pos, axis=1)
    assert np.all(r > a * (1 - ecc) - 2000) and np.all(r < a * (1 + ecc) + 2000)
    assert np.all(np.abs(r - 26560e3) < 26560e3 * 0.03)
    v_inertial = vel + np.cross([0, 0, OMEGA_E], pos)
    speed = np.linalg.norm(v_inertial, axis=1)
    assert np.all(np.abs(speed - 3874) < 3874 * (ecc + 0.002))        # ~3.87 km/s, e-dependent
    vis_viva = np.sqrt(MU_GPS * (2 / r - 1 / a))
    assert np.max(np.abs(speed - vis_viva) / vis_viva) < 5e-4
    assert np.all(np.abs(clk) < 1e-3) and np.all(np.abs(drift) < 1e-9)
    # same result one satellite at a time
    p0, v0, c0, d0 = sat_state(allephs[5], t[5])
    assert np.allclose(p0, pos[5], atol=1e-6) and np.isclose(c0, clk[5], atol=1e-15)


def test_sat_state_week_crossover(brdc):
    ephs, _ = brdc
    eph = replace(ephs[4][0], toe=0.0, toc=0.0, week=2191)
    p1, v1, c1, _ = sat_state(eph, 604800.0 - 10.0)
    p2, v2, c2, _ = sat_state(eph, -10.0)
    assert np.allclose(p1, p2, atol=1e-6) and np.isclose(c1, c2, atol=1e-15)
    p3, *_ = sat_state(eph, 10.0)
    assert 50e3 < np.linalg.norm(p3 - p1) < 100e3                # ~20 s of flight, not a week


def test_relativistic_and_tgd_terms(brdc):
    ephs, _ = brdc
    eph = ephs[9][0]
    base = replace(eph, e=1e-12, tgd=0.0)
    _, _, c_full, _ = sat_state(eph, eph.toc)
    _, _, c_base, _ = sat_state(base, eph.toc)
    pos, *_ = sat_state(eph, eph.toc)
    # the F e sqrt(A) sin E term is at most ~ F e sqrt(A)
    assert abs(c_full - c_base + eph.tgd) <= abs(F_REL) * eph.e * eph.sqrt_a * 1.0001
    assert c_base == pytest.approx(eph.af0, abs=1e-13)


def test_earth_rotation():
    pos = np.array([26000e3, 0.0, 5000e3])
    tau = 0.075
    rot = earth_rotation(pos, tau)
    assert np.isclose(np.linalg.norm(rot), np.linalg.norm(pos))
    assert rot[2] == pos[2]
    # the satellite appears rotated clockwise (seen from +z) by omega*tau
    assert rot[1] == pytest.approx(-OMEGA_E * tau * pos[0], rel=1e-9)
    many = earth_rotation(np.tile(pos, (4, 1)), np.full(4, tau))
    assert np.allclose(many, rot)


def test_select(brdc):
    ephs, _ = brdc
    lst = ephs[1]
    e = select(lst, lst[1].toe + 600.0)
    assert e is lst[1]
    assert select(lst, lst[0].toe + 5 * 86400.0) is None
    assert select(lst, lst[0].toe, week=lst[0].week + 1) is None
    assert select([replace(lst[0], health=1)], lst[0].toe) is None
    assert select([], 0.0) is None
