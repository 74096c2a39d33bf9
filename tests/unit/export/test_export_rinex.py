"""RINEX 3.04 export (receiver.export.rinex_obs): read back by georinex, solved by RTKLIB's rnx2rtkp,
and LLI / SSI rules on synthetic observables."""
import shutil
import subprocess
import types
import warnings

import numpy as np
import pytest

from receiver.export.rinex_obs import LLI_HALF_CYCLE, LLI_LOSS, lli_flags, ssi_from_cn0
from receiver.runfile.reader import load_run
from receiver.gnss.ephemeris import select
from receiver.navigation.pvt import NavSolver, Observation
from receiver.gnss.rinex import read_rinex_nav
from receiver.runfile.record import OBS_DTYPE
from receiver.gnss.signals import C_LIGHT

from repo_paths import TOKYO_NAV


# ------------------------------------------------------------------------------------------ unit rules
def _obs(rows):
    """rows: (time_s, prn, lock_time_s, half_cycle_resolved)."""
    a = np.zeros(len(rows), OBS_DTYPE)
    for i, (t, prn, lock, half) in enumerate(rows):
        a[i]["time_s"], a[i]["prn"], a[i]["lock_time_s"], a[i]["half_cycle_resolved"] = t, prn, lock, half
    return a


def test_lli_marks_lock_restarts_gaps_and_half_cycle():
    obs = _obs([
        (10.0, 1, 5.0, 1), (10.0, 2, 5.0, 1),
        (10.1, 1, 5.1, 1), (10.1, 2, 0.05, 1),    # PRN 2: lock restarted since 10.0
        (10.2, 1, 5.2, 1), (10.2, 2, 0.15, 1),
        (10.2, 3, 0.02, 0),                        # PRN 3 appears: lock younger than the epoch gap, half cycle
        (10.3, 1, 5.3, 1), (10.3, 3, 0.12, 1),     # PRN 2 missing here
        (10.8, 1, 5.8, 1), (10.8, 2, 0.75, 1),     # PRN 2 back after a gap, but locked since before 10.2
        (10.8, 3, 0.30, 1),                        # PRN 3: lock (0.3 s) younger than the 0.5 s gap
    ])
    lli = lli_flags(obs)
    got = {(round(float(t), 1), int(p)): int(v) for t, p, v in zip(obs["time_s"], obs["prn"], lli)}
    assert got[(10.0, 1)] == 0 and got[(10.0, 2)] == 0        # first epoch: nothing known before
    assert got[(10.1, 2)] == LLI_LOSS and got[(10.1, 1)] == 0
    assert got[(10.2, 2)] == 0
    assert got[(10.2, 3)] == LLI_LOSS | LLI_HALF_CYCLE
    assert got[(10.3, 3)] == 0
    assert got[(10.8, 2)] == 0
    assert got[(10.8, 3)] == LLI_LOSS
    assert got[(10.8, 1)] == 0


def test_ssi_follows_the_rinex3_table():
    assert [ssi_from_cn0(c) for c in (5, 12, 17.9, 18, 35.9, 36, 47, 48, 53.9, 54, 70)] == \
        [1, 2, 2, 3, 5, 6, 7, 8, 8, 9, 9]
    assert ssi_from_cn0(float("nan")) == 0


# ------------------------------------------------------------------------------------------ reference run
def _header(path):
    lines = []
    with open(path) as fh:
        for ln in fh:
            lines.append(ln.rstrip("\n"))
            if "END OF HEADER" in ln:
                break
    return lines


@pytest.mark.slow
def test_obs_header_is_rinex_304(tokyo_exports):
    h = _header(tokyo_exports["obs"])
    assert h[0][:9].strip() == "3.04" and h[0][20] == "O" and h[0][40] == "G"
    assert all(len(ln) == 80 for ln in h), "header lines are 60 columns of content + 20 of label"
    labels = [ln[60:].strip() for ln in h]
    for need in ("PGM / RUN BY / DATE", "MARKER NAME", "OBSERVER / AGENCY", "REC # / TYPE / VERS",
                 "ANT # / TYPE", "APPROX POSITION XYZ", "ANTENNA: DELTA H/E/N", "SYS / # / OBS TYPES",
                 "TIME OF FIRST OBS", "SYS / PHASE SHIFT", "END OF HEADER"):
        assert need in labels, need
    types_line = h[labels.index("SYS / # / OBS TYPES")]
    assert types_line[:60].split() == ["G", "4", "C1C", "L1C", "D1C", "S1C"]


@pytest.mark.slow
def test_georinex_reads_back_the_same_values(tokyo_exports):
    gr = pytest.importorskip("georinex", reason="georinex not installed (pip install '.[test]')")
    run = load_run(tokyo_exports["h5"])
    obs = run.obs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = gr.load(tokyo_exports["obs"], useindicators=True)
    epochs = np.unique(obs["time_s"])
    assert ds.sizes["time"] == len(epochs) > 300
    assert sorted(ds.sv.values) == [f"G{p:02d}" for p in sorted(set(obs["prn"].tolist()))]
    assert ds.attrs["version"] == pytest.approx(3.04)
    assert ds.attrs["interval"] == pytest.approx(0.1)
    # epoch times: receiver clock = GPS time of the fix + clock bias / c (georinex keeps microseconds)
    rx = run.rx_tow()
    t_file = ds.time.values.astype("datetime64[ns]")
    gps_epoch = np.datetime64("1980-01-06T00:00:00", "ns")
    sow = ((t_file - gps_epoch).astype("int64") / 1e9) - obs["gps_week"][0] * 604800.0
    first = np.array([rx[obs["time_s"] == t][0] for t in epochs])
    assert np.max(np.abs(sow - first)) < 1.5e-6
    # every value, by satellite and epoch
    idx = {t: i for i, t in enumerate(epochs)}
    ti = np.array([idx[t] for t in obs["time_s"]])
    svs = list(ds.sv.values)
    si = np.array([svs.index(f"G{p:02d}") for p in obs["prn"]])
    c1c = ds["C1C"].values[ti, si]
    l1c = ds["L1C"].values[ti, si]
    d1c = ds["D1C"].values[ti, si]
    s1c = ds["S1C"].values[ti, si]
    assert np.max(np.abs(c1c - obs["pseudorange_m"])) <= 0.0005 + 1e-6
    assert np.max(np.abs(l1c + obs["carrier_phase_cycles"])) <= 0.0005 + 1e-6     # RINEX sign convention
    assert np.max(np.abs(d1c - obs["doppler_hz"])) <= 0.0005 + 1e-6
    assert np.max(np.abs(s1c - obs["cn0_dbhz"])) <= 0.0005 + 1e-4
    ssi = ds["C1Cssi"].values[ti, si]
    assert np.array_equal(ssi, [ssi_from_cn0(c) for c in obs["cn0_dbhz"]])
    # no observation where the run has none
    assert np.count_nonzero(np.isfinite(ds["C1C"].values)) == len(obs)
    # loss-of-lock indicators as the rules give them (half cycle unresolved before the first preamble)
    lli = np.nan_to_num(ds["L1Clli"].values[ti, si], nan=0.0).astype(int)
    assert np.array_equal(lli, lli_flags(obs))
    assert np.array_equal(lli & LLI_HALF_CYCLE > 0, obs["half_cycle_resolved"] == 0)


def test_nav_file_holds_the_ephemerides_and_iono_the_fixes_used(tokyo_exports):
    ephs, iono = read_rinex_nav(tokyo_exports["nav"])
    ref, ref_iono = read_rinex_nav(TOKYO_NAV)
    run = load_run(tokyo_exports["h5"])
    observed = set(run.obs["prn"].tolist())
    assert set(ephs) == observed
    tow, week = float(np.median(run.obs["gps_tow"])), int(run.obs["gps_week"][0])
    rx = run.rx_tow()
    for prn, lst in ephs.items():       # assisted run: the records the engine selected from the file
        picked = {(select(ref[prn], t).toe, select(ref[prn], t).iode) for t in rx[run.obs["prn"] == prn]}
        assert {(e.toe, e.iode) for e in lst} == picked
        assert select(lst, tow, week).toe == select(ref[prn], tow, week).toe
        for got in lst:
            want = next(e for e in ref[prn] if (e.toe, e.iode) == (got.toe, got.iode))
            for f in ("toc", "sqrt_a", "e", "m0", "af0", "af1", "tgd", "omega0", "i0", "cuc", "crs"):
                assert getattr(got, f) == pytest.approx(getattr(want, f), rel=1e-11, abs=1e-20), (prn, f)
    assert iono is not None and np.allclose(iono.alpha, ref_iono.alpha) and np.allclose(iono.beta, ref_iono.beta)
    gr = pytest.importorskip("georinex", reason="georinex not installed")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nav = gr.load(tokyo_exports["nav"])
    assert sorted(nav.sv.values) == [f"G{p:02d}" for p in sorted(observed)]


def test_autonomous_run_nav_file_comes_from_the_decoded_message(tokyo_run, tmp_path):
    """Without the assisting file the exporter uses the ephemerides decoded from the signal (stored in the
    run) and decodes the iono/UTC page again from the stored prompt correlator outputs."""
    from receiver.export.rinex_obs import write_nav
    run = load_run(tokyo_run)
    run.config["navigation"]["ephemeris"] = None            # as if the run had been autonomous
    assert not run.assisted
    write_nav(tmp_path / "auto.nav", run)
    ephs, iono = read_rinex_nav(tmp_path / "auto.nav")
    assert sorted(ephs) == sorted(e.prn for e in run.ephemerides) and len(ephs) >= 8
    _, ref_iono = read_rinex_nav(TOKYO_NAV)
    assert iono is not None and iono.dt_ls == 18
    assert np.allclose(iono.alpha, ref_iono.alpha, rtol=1e-3) and np.allclose(iono.beta, ref_iono.beta, rtol=1e-3)


# ------------------------------------------------------------------------------------------ RTKLIB
RTKLIB_CONF = """\
pos1-posmode       =single
pos1-frequency     =l1
pos1-soltype       =forward
pos1-elmask        ={elmask}
pos1-ionoopt       =brdc
pos1-tropopt       =off
pos1-sateph        =brdc
pos1-navsys        =1
out-solformat      =xyz
out-outhead        =on
out-timesys        =gpst
out-timeform       =tow
out-timendec       =6
"""


def _rnx2rtkp(obs, nav, elmask, tmp_path):
    conf = tmp_path / "spp.conf"
    conf.write_text(RTKLIB_CONF.format(elmask=elmask))
    pos = tmp_path / "spp.pos"
    res = subprocess.run(["rnx2rtkp", "-k", str(conf), "-o", str(pos), str(obs), str(nav)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    rows = np.loadtxt(pos, comments="%", ndmin=2)
    return rows       # week, tow, x, y, z, Q, ns, ...


def _match(tow_a, tow_b):
    k = np.abs(tow_a[:, None] - tow_b[None, :]).argmin(axis=1)
    return k, np.abs(tow_a - tow_b[k]) < 1e-3


def _resolve(run, nav_path, weighting):
    """gnssrx's own single-point solution of the exported epochs with the given weighting."""
    ephs, iono = read_rinex_nav(nav_path)
    cfg = types.SimpleNamespace(
        elevation_mask_deg=run.cfg("navigation.elevation_mask_deg"), weighting=weighting,
        troposphere=run.cfg("navigation.troposphere"), ionosphere=run.cfg("navigation.ionosphere"),
        residual_threshold_m=run.cfg("navigation.residual_threshold_m"))
    solver = NavSolver(cfg)
    o, rx = run.obs, run.rx_tow()
    out, x0 = [], None
    for t in np.unique(o["time_s"]):
        r = np.nonzero(o["time_s"] == t)[0]
        obs = [Observation(prn=int(o["prn"][i]), tx_tow=rx[i] - o["pseudorange_m"][i] / C_LIGHT,
                           doppler_hz=o["doppler_hz"][i], cn0_dbhz=o["cn0_dbhz"][i]) for i in r]
        fix = solver.fix(int(o["gps_week"][r[0]]), float(rx[r[0]]), obs, ephs, iono, x0=x0)
        x0 = fix.ecef
        out.append((fix.gps_tow, *fix.ecef))
    return np.array(out)


# upper URA bound (m) per URA index, IS-GPS-200
_URA_M = (2.40, 3.40, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0, 96.0, 192.0, 384.0, 768.0, 1536.0, 3072.0, 6144.0)


def _solve_with_rtklib_weights(run, nav_path, mask_deg):
    """Single-point solutions of the exported epochs with gnssrx's models (satellite orbit/clock/TGD,
    Sagnac, Klobuchar, no troposphere) but the measurement variances of RTKLIB's documented single-point
    error model with its default settings: 100^2 (0.003^2 + 0.003^2 / sin el) + URA^2 + 0.3^2 (code bias)
    + (0.5 iono)^2 + 3^2 (troposphere not modelled).  Gauss-Newton from the Earth's centre."""
    from receiver.gnss.geodesy import azel, ecef2lla
    from receiver.gnss.atmosphere import klobuchar_delay_s
    from receiver.gnss.ephemeris import earth_rotation, sat_state
    ephs, iono = read_rinex_nav(nav_path)
    o, rx = run.obs, run.rx_tow()
    out = []
    for tt in np.unique(o["time_s"]):
        rows = np.nonzero(o["time_s"] == tt)[0]
        t = float(rx[rows[0]])
        p = o["pseudorange_m"][rows]
        eph = [select(ephs[int(prn)], t) for prn in o["prn"][rows]]
        pos, _, clk, _ = sat_state(eph, t - p / C_LIGHT)
        ura = np.array([_URA_M[min(e.ura_index, 14)] for e in eph])
        x = np.zeros(4)
        for _ in range(30):
            rot = earth_rotation(pos, np.linalg.norm(pos - x[:3], axis=1) / C_LIGHT)
            rng = np.linalg.norm(rot - x[:3], axis=1)
            if np.linalg.norm(x[:3]) > 1e6:
                az, el = azel(x[:3], rot)
                lat, lon, _ = ecef2lla(x[:3])
                ion = C_LIGHT * klobuchar_delay_s(iono, np.radians(lat), np.radians(lon), az, el, t)
                use = el >= np.radians(mask_deg)
            else:
                el, ion, use = np.full(len(p), np.pi / 2), np.zeros(len(p)), np.ones(len(p), bool)
            var = 100.0 ** 2 * (0.003 ** 2 + 0.003 ** 2 / np.sin(el)) + ura ** 2 + 0.3 ** 2 + (0.5 * ion) ** 2 + 9.0
            v = p + C_LIGHT * clk - ion - (rng + x[3])
            h = np.hstack([-(rot - x[:3]) / rng[:, None], np.ones((len(p), 1))])
            w = 1.0 / np.sqrt(var)
            dx, *_ = np.linalg.lstsq(h[use] * w[use, None], v[use] * w[use], rcond=None)
            x += dx
            if np.linalg.norm(dx) < 1e-4:
                break
        out.append((t - x[3] / C_LIGHT, *x[:3]))
    return np.array(out)


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("rnx2rtkp") is None, reason="RTKLIB rnx2rtkp not installed (apt-get install rtklib)")
def test_rnx2rtkp_single_point_agrees_with_gnssrx(tokyo_exports, tmp_path):
    run = load_run(tokyo_exports["h5"])
    assert run.cfg("navigation.troposphere") == "none" and run.cfg("navigation.ionosphere") == "klobuchar"
    mask = run.cfg("navigation.elevation_mask_deg")
    rtk = _rnx2rtkp(tokyo_exports["obs"], tokyo_exports["nav"], mask, tmp_path)
    fx = run.fixes
    assert len(rtk) == len(fx) > 300
    assert np.all(rtk[:, 5] == 5)                                  # single-point solutions
    k, ok = _match(fx["gps_tow"], rtk[:, 1])
    assert ok.all()
    assert np.array_equal(rtk[k, 6].astype(int), fx["n_sats"])    # same satellites used

    # 1) the exported files carry exactly what the fixes used: gnssrx's solver on the exported nav file and
    #    epochs reproduces the stored fixes
    same = _resolve(run, tokyo_exports["nav"], run.cfg("navigation.weighting"))
    assert np.max(np.linalg.norm(same[:, 1:] - fx["ecef"], axis=1)) < 1e-3

    # 2) with the same weighting, gnssrx's models and RTKLIB agree to centimetres: the observation and
    #    navigation files mean to RTKLIB what they mean to gnssrx (time tags, signs, TGD, iono parameters).
    #    (An epoch where two ephemerides are equally near may be resolved differently: allow 1 m there.)
    emu = _solve_with_rtklib_weights(run, tokyo_exports["nav"], mask)
    d_emu = np.linalg.norm(emu[:, 1:] - rtk[k, 2:5], axis=1)
    assert np.max(np.abs(emu[:, 0] - rtk[k, 1])) < 1e-6
    assert np.median(d_emu) < 0.02 and np.mean(d_emu < 0.05) > 0.99 and np.max(d_emu) < 1.0, \
        f"median {np.median(d_emu):.4f} m, max {np.max(d_emu):.3f} m"

    # 3) RTKLIB vs the run's own fixes, the run made with navigation.weighting: rtklib (the same error
    #    model): every epoch within 1 m (the largest difference is an epoch exactly halfway between two
    #    ephemerides, which the two programs break differently)
    assert run.cfg("navigation.weighting") == "rtklib"
    d_run = np.linalg.norm(fx["ecef"] - rtk[k, 2:5], axis=1)
    assert np.max(d_run) < 1.0, f"max {np.max(d_run):.3f} m"
    rms = float(np.sqrt(np.mean(d_run ** 2)))
    print(f"\nrnx2rtkp vs gnssrx, {len(fx)} epochs (3D difference, m):"
          f"\n  RTKLIB weights in gnssrx models: median {np.median(d_emu):.4f} RMS "
          f"{np.sqrt(np.mean(d_emu ** 2)):.4f} max {np.max(d_emu):.4f}"
          f"\n  run's own fixes:                 median {np.median(d_run):.3f} RMS {rms:.3f} "
          f"max {np.max(d_run):.3f}")
    assert rms < 1.5 and np.median(d_run) < 1.0, f"rms {rms:.3f} m, median {np.median(d_run):.3f} m"
