"""Galileo E1 outputs on a synthetic Galileo-only run (run-file system E): RINEX 3 observation header and
labels (E, C1C L1C D1C S1C: the E1-C pilot), NMEA talker GA with the NMEA 4.10 Galileo IDs, and RTKLIB's
single-point solution on our observation + Enn navigation files equal to the position the pseudoranges
were made for (so RTKLIB reads our Galileo records to the orbits and clocks gnssrx computes)."""
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from receiver.export.nmea import checksum, nmea_lines
from receiver.export.rinex_obs import write_rinex_obs
from receiver.gnss.ephemeris import earth_rotation, sat_state
from receiver.gnss.gal_inav import quantize_gal
from receiver.gnss.geodesy import azel, ecef2lla, lla2ecef
from receiver.gnss.rinex import write_rinex_nav
from receiver.gnss.signals import C_LIGHT
from receiver.runfile.reader import RunData
from receiver.runfile.record import FIX_DTYPE, OBS_DTYPE
from receiver.sim.gal_constellation import gal_nominal_content

REPO = Path(__file__).resolve().parents[3]
WEEK, TOW = 2300, 345600.0 + 600.0
TRUTH = np.array(lla2ecef(35.68, 139.77, 40.0))
BIAS_M = 12345.678                 # receiver clock bias
EPOCHS = 5


@pytest.fixture(scope="module")
def sky():
    """Nominal Galileo ephemerides with clock terms, harmonics and two different BGDs, and the satellites above
    10 deg."""
    content = gal_nominal_content(REPO / "data/gal_nominal_constellation.yaml", WEEK, TOW)
    rng = np.random.default_rng(5)
    ephs = {}
    for prn, c in content.items():
        ephs[prn] = quantize_gal(replace(c.eph, af0=rng.normal(0, 3e-4), af1=rng.normal(0, 3e-12),
                                         tgd=rng.normal(0, 3e-9),               # BGD(E1,E5b): applied on E1
                                         bgd_e1e5a=rng.normal(0, 3e-9),         # BGD(E1,E5a): not
                                         crs=rng.normal(0, 50), crc=rng.normal(0, 150), cuc=rng.normal(0, 2e-6),
                                         cus=rng.normal(0, 2e-6), cic=rng.normal(0, 5e-8),
                                         cis=rng.normal(0, 5e-8), delta_n=rng.normal(0, 2e-9)))
    visible = []
    for prn, e in sorted(ephs.items()):
        pos, _, _, _ = sat_state(e, TOW)
        if np.degrees(azel(TRUTH, pos)[1]) > 10.0:
            visible.append(prn)
    assert len(visible) >= 6
    return ephs, visible


def _pseudorange(e, t_rx):
    """c (receiver clock at reception - satellite clock at transmission) for a receiver at TRUTH with
    clock bias BIAS_M, and the satellite's azimuth / elevation (deg)."""
    t_sv = t_rx - 0.075
    for _ in range(6):
        pos, _, clk, _ = sat_state(e, t_sv)
        tau = t_rx - (t_sv - clk)
        rho = np.linalg.norm(earth_rotation(pos, tau) - TRUTH)
        t_sv = t_rx - rho / C_LIGHT + clk
    az, el = azel(TRUTH, earth_rotation(pos, tau))
    return C_LIGHT * (t_rx - t_sv) + BIAS_M, np.degrees(az), np.degrees(el)


def _run(tmp_path, sky) -> RunData:
    ephs, visible = sky
    fx = np.zeros(EPOCHS, FIX_DTYPE)
    obs = np.zeros(EPOCHS * len(visible), OBS_DTYPE)
    lat, lon, h = ecef2lla(TRUTH)
    for k in range(EPOCHS):
        t = TOW + k
        fx[k] = (WEEK, t, 30.0 + k, TRUTH, np.zeros(3), BIAS_M, 0.0, len(visible), 1.5, 0.8, 1.2, 1.7, 0,
                 lat, lon, h, 0)
        for j, prn in enumerate(visible):
            pr, az, el = _pseudorange(ephs[prn], t)
            obs[k * len(visible) + j] = (k, WEEK, t, 30.0 + k, prn, pr, 0.0, -500.0 + 10 * j, 1e5 * j + 5 * k,
                                         45.0, 10.0 + k, 1, 1, el, az, 0.0)
    return RunData(path=str(tmp_path / "gal.h5"), attrs={"system": "E"}, config={}, fixes=fx, obs=obs,
                   ephemerides=[ephs[p] for p in visible], _iono_done=True)


def test_galileo_rinex_observation_header_and_labels(tmp_path, sky):
    out = tmp_path / "gal.obs"
    info = write_rinex_obs(out, _run(tmp_path, sky))
    text = out.read_text().splitlines()
    assert text[0][20:21] == "O" and text[0][40:41] == "E"
    types = {ln[0]: ln[7:60].split() for ln in text if ln[60:].strip() == "SYS / # / OBS TYPES"}
    assert types == {"E": ["C1C", "L1C", "D1C", "S1C"]}           # E1-C (pilot) tracking, RINEX 3 band 1
    assert [ln[:5] for ln in text if ln[60:].strip() == "SYS / PHASE SHIFT"] == ["E L1C"]
    assert all(ln[48:51] == "GPS" for ln in text if ln[60:].strip().startswith("TIME OF"))
    body = text[next(i for i, ln in enumerate(text) if "END OF HEADER" in ln) + 1:]
    _, visible = sky
    assert [ln[:3] for ln in body[1:1 + len(visible)]] == [f"E{p:02d}" for p in visible]
    assert info["epochs"] == EPOCHS and info["satellites"] == visible


def test_galileo_nmea_talker_and_ids(tmp_path, sky):
    """Galileo-only fix: GA talker on GGA/RMC/GSA/GSV, satellite IDs 1-36 (NMEA 4.10)."""
    _, visible = sky
    lines = nmea_lines(_run(tmp_path, sky))
    for ln in lines:
        body, cs = ln[1:].split("*")
        assert checksum(body) == cs
    assert {ln[1:3] for ln in lines} == {"GA"}
    gsa = [ln for ln in lines if ln[3:6] == "GSA"]
    assert len(gsa) == EPOCHS
    assert [v for v in gsa[0].split("*")[0].split(",")[3:15] if v] == [f"{p:02d}" for p in visible]
    first = lines[:[i for i, ln in enumerate(lines) if ln[3:6] == "GGA"][1]]            # the first fix's
    gsv_ids = [int(f) for ln in first if ln[3:6] == "GSV" for f in ln.split("*")[0].split(",")[4::4]]
    assert gsv_ids == visible


RTKLIB_CONF = """\
pos1-posmode       =single
pos1-frequency     =l1
pos1-elmask        =5
pos1-ionoopt       =off
pos1-tropopt       =off
pos1-sateph        =brdc
pos1-navsys        =8
out-solformat      =xyz
out-timesys        =gpst
out-timeform       =tow
out-timendec       =6
"""


@pytest.mark.skipif(shutil.which("rnx2rtkp") is None, reason="RTKLIB rnx2rtkp not installed (apt-get install rtklib)")
def test_rnx2rtkp_on_our_galileo_files_finds_the_true_position(tmp_path, sky):
    """Pseudoranges made with gnssrx's Galileo orbits / clocks / BGD(E1,E5b) for a known position (no
    atmosphere): RTKLIB, reading our RINEX observation and Enn navigation files with its own Galileo code, puts
    the receiver there (centimetres) and finds the clock bias.  (Written without the BGD, or with the two BGDs
    swapped, the files put it 1.3 m or 1.8 m away: RTKLIB also applies BGD(E1,E5b) to an E1 pseudorange.)"""
    ephs, visible = sky
    run = _run(tmp_path, sky)
    obs, nav = tmp_path / "gal.obs", tmp_path / "gal.nav"
    write_rinex_obs(obs, run)
    write_rinex_nav(nav, [ephs[p] for p in visible])
    conf = tmp_path / "spp.conf"
    conf.write_text(RTKLIB_CONF)
    pos = tmp_path / "spp.pos"
    res = subprocess.run(["rnx2rtkp", "-k", str(conf), "-o", str(pos), str(obs), str(nav)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    rows = np.loadtxt(pos, comments="%", ndmin=2)
    assert len(rows) == EPOCHS and np.all(rows[:, 5] == 5) and np.all(rows[:, 6] == len(visible))
    err = np.linalg.norm(rows[:, 2:5] - TRUTH, axis=1)
    print(f"\nrnx2rtkp -sys E on synthetic Galileo files: 3D error max {np.max(err):.4f} m")
    assert np.max(err) < 0.05, err
    # RTKLIB's solution time = receiver clock reading - its clock bias estimate = the true GPS time
    np.testing.assert_allclose(rows[:, 1], TOW + np.arange(EPOCHS), atol=1e-6)


def _mixed_run(tmp_path):
    """Two epochs of G01, G07, J01, E05, E11, C01, C12 in a run over several signals (keys 305, 311, 401, 412)."""
    sats = [1, 7, 193, 305, 311, 401, 412]
    lat, lon, h = ecef2lla(TRUTH)
    fx = np.zeros(2, FIX_DTYPE)
    obs = np.zeros(2 * len(sats), OBS_DTYPE)
    for k in range(2):
        fx[k] = (WEEK, TOW + k, 30.0 + k, TRUTH, np.zeros(3), 12.0, 0.1, len(sats), 1.2, 0.7, 1.0, 1.4, 0,
                 lat, lon, h, 1)
        for j, p in enumerate(sats):
            obs[k * len(sats) + j] = (k, WEEK, TOW + k, 30.0 + k, p, 2.1e7 + 1e5 * j, 0.0, -1000.0 + j, 1e6 + j,
                                      44.0, 10.0, 1, 1, 40.0 + j, 100.0 + 10 * j, 0.1)
    return RunData(path=str(tmp_path / "mixed.h5"), attrs={"system": "M"}, config={}, fixes=fx, obs=obs,
                   _iono_done=True)


def test_mixed_gps_galileo_beidou_rinex_and_nmea(tmp_path):
    """GPS + QZSS + Galileo + BeiDou in one fix: a mixed RINEX file with an E line of C1C..S1C and E05/E11
    labels; NMEA GN with one GSA per system (NMEA 4.10 IDs 1 GPS, 3 Galileo, 4 BeiDou), GSV per system."""
    run = _mixed_run(tmp_path)
    out = tmp_path / "mixed.obs"
    write_rinex_obs(out, run)
    text = out.read_text().splitlines()
    assert text[0][40:41] == "M"
    types = {ln[0]: ln[7:60].split() for ln in text if ln[60:].strip() == "SYS / # / OBS TYPES"}
    assert types == {"G": ["C1C", "L1C", "D1C", "S1C"], "C": ["C2I", "L2I", "D2I", "S2I"],
                     "E": ["C1C", "L1C", "D1C", "S1C"], "J": ["C1C", "L1C", "D1C", "S1C"]}
    body = text[next(i for i, ln in enumerate(text) if "END OF HEADER" in ln) + 1:]
    assert [ln[:3] for ln in body[1:8]] == ["G01", "G07", "J01", "E05", "E11", "C01", "C12"]
    lines = nmea_lines(run)
    first = lines[:[i for i, ln in enumerate(lines) if ln[3:6] == "GGA"][1]]
    assert first[0].startswith("$GNGGA") and first[1].startswith("$GNRMC")
    gsa = [ln.split("*")[0].split(",") for ln in first if ln[3:6] == "GSA"]
    assert {f[-1]: [v for v in f[3:15] if v] for f in gsa} == {"1": ["01", "07", "193"], "3": ["05", "11"],
                                                               "4": ["01", "12"]}
    gsv = {ln[1:3]: [int(v) for v in ln.split("*")[0].split(",")[4::4]] for ln in first if ln[3:6] == "GSV"}
    assert gsv == {"GP": [1, 7, 193], "GA": [5, 11], "GB": [1, 12]}


def test_galileo_run_file_info_and_navigation_file(tmp_path, sky):
    """A Galileo-only run file (system E): ``gnssrx info`` names the system and lists E.. satellites; the
    navigation file exported from it holds Enn records equal to the stored ephemerides, and the header the
    NeQuick-G / GST-UTC / GST-GPS parameters decoded again from a channel's stored E1-B symbols."""
    from receiver.export.info import format_info, run_info
    from receiver.export.rinex_obs import write_nav
    from receiver.gnss.gal_inav import GalEphemeris, Ggto, GstUtc, InavContent, InavStream, NequickG
    from receiver.gnss.rinex import read_rinex_nav
    from receiver.gnss.rinex_gal import read_gal_header
    from receiver.runfile.reader import load_run
    from receiver.runfile.record import EPOCH_DTYPE
    from receiver.runfile.writer import RunWriter
    ephs, visible = sky
    synthetic = _run(tmp_path, sky)
    path = tmp_path / "gal_run.h5"
    w = RunWriter(path, "{}", {"sample_rate_hz": 4e6, "system": "E"})
    w.write_ephemerides({p: ephs[p] for p in visible})
    w.append_observables(synthetic.obs)
    w.append_fixes(synthetic.fixes)
    # 70 s of one channel's E1-B symbols (an odd 30-s sub-frame carries word 10, the GGTO)
    e = ephs[visible[0]]
    content = InavContent(e, NequickG(ai0=80.25, ai1=0.5, ai2=-0.0078125),
                          GstUtc(a0=2.0 ** -30 * 5, a1=-2.0 ** -49, dt_ls=18, tot=342000, wnot=e.gst_week % 256,
                                 wn_lsf=e.gst_week % 256, dn=7, dt_lsf=18),
                          Ggto(a0g=2.0 ** -35 * 77, a1g=2.0 ** -51 * -3, t0g=342000.0, wn0g=e.gst_week % 64))
    n = 70 * 250
    rec = np.zeros(n, EPOCH_DTYPE)
    rec["code_period"] = 1 + np.arange(n)
    rec["time_s"] = 0.004 * np.arange(n)
    rec["prompt1_i"] = 900.0 * InavStream(content, e.gst_week).signs(int(TOW - 600.0) * 250, n)
    w.append_channel(visible[0], rec)
    w.close()
    text = format_info(run_info(path))
    labels = " ".join(f"E{p:02d}" for p in visible)
    assert "systems         Galileo" in text
    assert f"satellites {labels}" in text and f"(decoded) {labels}" in text
    run = load_run(path)
    assert all(type(e) is GalEphemeris for e in run.ephemerides)
    info = write_nav(tmp_path / "gal_run.nav", run)
    assert info["satellites"] == visible
    back, _ = read_rinex_nav(tmp_path / "gal_run.nav", systems=("E",))
    assert sorted(back) == visible
    h = read_gal_header(tmp_path / "gal_run.nav")
    assert (h["nequick"].ai0, h["nequick"].ai1, h["nequick"].ai2) == (80.25, 0.5, -0.0078125)
    # (the header fields keep 11 / 10 significant digits)
    assert (h["utc"].a0, h["utc"].a1) == pytest.approx((2.0 ** -30 * 5, -2.0 ** -49), rel=1e-9)
    assert (h["utc"].tot, h["utc"].wnot) == (342000, e.gst_week % 256)
    assert (h["ggto"].a0g, h["ggto"].a1g) == pytest.approx((2.0 ** -35 * 77, 2.0 ** -51 * -3), rel=1e-9)
    assert (h["ggto"].t0g, h["ggto"].wn0g) == (342000.0, e.gst_week % 64)
    for p in visible:
        t = ephs[p].toe + 100.0
        np.testing.assert_allclose(sat_state(back[p][0], t)[0], sat_state(ephs[p], t)[0], atol=1e-4)


def test_assisted_runs_export_the_records_of_their_systems(tmp_path, sky):
    """An assisted run (navigation.ephemeris: a mixed RINEX file with G05 and E05): the exported navigation
    file holds the records the fixes used, E05 for a Galileo-only run, G05 and E05 for a GPS + Galileo one
    (satellite keys 5 and 305) -- not the GPS record of the same PRN number."""
    from receiver.export.rinex_obs import write_nav
    from receiver.gnss.gal_inav import GalEphemeris
    from receiver.gnss.rinex import read_rinex_nav
    from receiver.sim.constellation import nominal_ephemerides
    ephs, _ = sky
    gps, _ = nominal_ephemerides(REPO / "data/gps_nominal_constellation.yaml", WEEK, TOW)
    mixed = tmp_path / "assist.rnx"
    write_rinex_nav(mixed, [gps[5], ephs[5]])
    for system, config, keys in (("E", {"signal": "gal_e1"}, [5]),
                                 ("M", {"signals": ["gps_l1ca", "gal_e1"]}, [5, 305])):
        obs = np.zeros(len(keys), OBS_DTYPE)
        obs["prn"], obs["gps_week"], obs["gps_tow"] = keys, WEEK, TOW
        run = RunData(path=str(tmp_path / f"{system}.h5"), attrs={"system": system},
                      config=dict(config, navigation={"ephemeris": str(mixed)}), fixes=np.zeros(0, FIX_DTYPE),
                      obs=obs, _iono_done=True, _decoded=({}, None))     # no file behind: nothing decoded
        used = {run.eph_key(e): type(e) for e in run.used_ephemerides()}
        assert used == ({5: GalEphemeris} if system == "E" else {5: type(gps[5]), 305: GalEphemeris})
        write_nav(tmp_path / f"{system}.nav", run)
        labels = sorted(ln[:3] for ln in open(tmp_path / f"{system}.nav") if ln[:1] in "GE" and ln[1:3].isdigit())
        assert labels == (["E05"] if system == "E" else ["E05", "G05"])
        back, _ = read_rinex_nav(tmp_path / f"{system}.nav", systems=("E",))
        assert back[5][0].sqrt_a == pytest.approx(ephs[5].sqrt_a, rel=1e-12)
