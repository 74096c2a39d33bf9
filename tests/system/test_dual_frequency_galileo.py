"""Galileo E1 + E5a end to end (issue 38, "same with Galileo E1 + E5a"): the project's simulator writes an E1 and
an E5a file on one clock (static, 45 dB-Hz, an ionosphere 1.5 times a Klobuchar model, the BGD(E1,E5a) of each
satellite in I/NAV and in its E5a group delay); the receiver (configs/gal_e1_e5a_ionofree.yaml) acquires E5a
aided by the E1 channels, tracks the E5a-Q pilot (CS100 wiped), and fixes with the E1/E5a ionosphere-free
combination and the decoded BGD(E1,E5a); its E1 part is that of an E1-only run.  The E1-only fix, without an
ionospheric model (Galileo broadcasts NeQuick-G), keeps the whole ionosphere; the ionosphere-free fix is within
1.5 m 3D RMS of the truth.

Numbers measured on this recording (seed 1, Lausanne, 22 s; ephemerides from ~15.5 s): E1-only 3D RMS ~3.7 m,
ionosphere-free ~0.4 m."""
import h5py
import numpy as np
import pytest

from receiver.gnss.geodesy import ecef2enu
from receiver.gnss.signals import C_LIGHT
from receiver.pipeline import run
from receiver.schema import load_receiver_config
from receiver.sim.multiband import GAMMA_E1E5A
from receiver.sim.simulate import simulate

from repo_paths import CONFIGS

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("e1e5a")
    simulate(CONFIGS / "scenarios/gal_e1e5a_static.yaml", str(d / "x.bin"), progress=False,
             overrides=["time.duration_s=22.0", "e5a.sample_rate_hz=10.5e6"])
    cfg = load_receiver_config(CONFIGS / "gal_e1_e5a_ionofree.yaml", [
        ("input.path", str(d / "x.bin")), ("output.path", str(d / "run.h5")),
        ("input.signal_files", {"gal_e5a": {"path": str(d / "x_e5a.bin"), "format": "int8_iq",
                                            "sample_rate_hz": 10.5e6, "if_hz": 0.0}})])
    run(cfg, quiet=True)
    e1 = load_receiver_config(CONFIGS / "gal_e1_e5a_ionofree.yaml", [
        ("input.path", str(d / "x.bin")), ("output.path", str(d / "e1.h5")), ("signals", ["gal_e1"]),
        ("input.signal_files", {})])
    run(e1, quiet=True)
    return d


def test_e1_part_unchanged(runs):
    """The E1 part of the E1 + E5a run is an E1-only run, bit for bit (the band only reads the E1 channels)."""
    with h5py.File(runs / "run.h5") as a, h5py.File(runs / "e1.h5") as b:
        for grp in ("navigation", "observables"):
            assert set(a[grp]) == set(b[grp])
            for k in a[grp]:
                assert np.array_equal(a[grp][k][:], b[grp][k][:], equal_nan=True), (grp, k)
        assert "navigation_ionofree" not in b


def test_e5a_aided_acquisition_and_pseudoranges(runs):
    with h5py.File(runs / "run.h5") as h, h5py.File(runs / "x_e5a.truth.h5") as t:
        assert h.attrs["band_signal"] == "gal_e5a"
        acq = h["acquisition_e5a"]
        found = set(acq["prn"][:][acq["detected"][:] == 1].tolist())
        assert len(found) >= 6 and np.all(acq["aided"][:] == 1)
        o = h["observables_e5a"]
        tm, prn, pr = o["time_s"][:], o["prn"][:], o["pseudorange_m"][:]
        assert set(prn.tolist()) == found
        for p in found:
            g = t[f"satellites/E{p:02d}"]
            k = prn == p
            err = pr[k] - np.interp(tm[k], g["time_s"][:], g["pseudorange_m"][:])
            assert np.sqrt(np.mean(err ** 2)) < 3.0, p


def test_band_difference_is_ionosphere_and_broadcast_group_delay(runs):
    """P5 - P1 = (gamma - 1) (I1 + c BGD(E1,E5a)): the truth's E1 ionosphere and the BGD the receiver decoded
    from I/NAV word type 5 (a few ns: up to a metre here), satellite by satellite within the code noise."""
    with h5py.File(runs / "run.h5") as h, h5py.File(runs / "x.truth.h5") as t1:
        bgd = dict(zip(h["ephemeris/prn"][:].tolist(), h["ephemeris/bgd_e1e5a"][:].tolist()))
        assert max(abs(v) for v in bgd.values()) > 1e-9
        o1, o5 = h["observables"], h["observables_e5a"]
        t_1, p_1, r_1 = o1["time_s"][:], o1["prn"][:], o1["pseudorange_m"][:]
        t_5, p_5, r_5 = o5["time_s"][:], o5["prn"][:], o5["pseudorange_m"][:]
        err, moved = [], []
        for p in np.unique(p_5):
            k5 = p_5 == p
            k1 = (p_1 == p) & np.isin(t_1, t_5[k5])
            assert k5.sum() >= 30 and np.array_equal(t_1[k1], t_5[k5])
            g = t1[f"satellites/E{p:02d}"]
            i1 = np.interp(t_5[k5], g["time_s"][:], g["iono_delay_m"][:])
            expect = (GAMMA_E1E5A - 1.0) * (i1 + C_LIGHT * bgd[int(p)])
            err.append(np.mean(r_5[k5] - r_1[k1] - expect))
            moved.append((GAMMA_E1E5A - 1.0) * C_LIGHT * bgd[int(p)])
        assert np.max(np.abs(err)) < 1.0 and abs(np.mean(err)) < 0.4
        # (the BGD term is resolved: leaving it out would be off by more than the error above)
        assert np.max(np.abs(moved)) > 0.5


def test_ionofree_removes_the_ionosphere(runs):
    with h5py.File(runs / "run.h5") as h, h5py.File(runs / "x.truth.h5") as t:
        truth = t["receiver/ecef"][0]
        e1, iff = h["navigation"], h["navigation_ionofree"]
        assert len(iff["time_s"]) >= 0.9 * len(e1["time_s"]) >= 40
        assert np.all(iff["n_sats"][:] >= 6)
        rms = {}
        for name, g in (("e1", e1), ("if", iff)):
            e = ecef2enu(g["ecef"][:], truth)
            rms[name] = float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))
        assert rms["e1"] > 2.5 and rms["if"] < 1.5, rms
