"""BDS B1I acquisition and scalar tracking on a short simulated IF file (GEO D2 PRN 5, MEO D1+NH PRN 11)."""
import h5py
import numpy as np
import pytest

from receiver.schema import load_receiver_config
from receiver.pipeline import run
from receiver.sim.simulate import simulate

from repo_paths import ROOT as REPO


@pytest.fixture(scope="module")
def b1i_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("b1i")
    out = d / "b1i.bin"
    simulate(str(REPO / "configs/scenarios/bds_b1i_short.yaml"), str(out),
             overrides=["time.duration_s=2.5"], progress=False)
    return d, out


@pytest.mark.parametrize("variant", ["pll", "cpll_atan", "pli_ekf", "adaptive_kf"])
def test_b1i_acquire_and_track(b1i_file, variant):
    d, out = b1i_file
    cfg = load_receiver_config(REPO / "configs/carrier_bds_b1i.yaml",
                               [f"input.path={out}", f"output.path={d / (variant + '.h5')}",
                                f"tracking.carrier.variant={variant}"])
    summary = run(cfg, quiet=True, log=lambda *a: None)
    assert summary.tracked == [5, 11]
    with h5py.File(d / (variant + ".h5"), "r") as f, h5py.File(str(out)[:-4] + ".truth.h5", "r") as t:
        for prn, t_int in ((5, 2), (11, 5)):
            g = f["channels"][f"C{prn:02d}"]
            st = g["state"][:]
            assert (st == 2).sum() > 100                      # data/NH synchronised
            assert g["integration_ms"][-1] == t_int           # D2: 2 ms symbols; D1: NH wiped, 5 ms
            assert g["cn0_dbhz"][-1] > 41.0                   # 45 dB-Hz simulated
            assert np.mean(g["pli"][-100:]) > 0.9
            truth_dop = t["satellites"][f"C{prn:02d}"]["doppler_hz"][-1]
            assert abs(g["doppler_hz"][-1] - truth_dop) < 5.0


@pytest.fixture(scope="module")
def b1i_false_lock(tmp_path_factory):
    """5.5 s of the static Tokyo BeiDou scenario, seed 2, with the acquisition's fine Doppler limited to its
    1-ms stage (the squared-block stage off, as before it existed) and the hot search's Doppler from plain
    phase differences (its squared form off): C32 (MEO, 45 dB-Hz, NH code) is acquired 98 Hz off and its
    5-ms carrier loop settles at +100 Hz = 1/(2 T) from the truth while the DLL keeps the code on C32
    (code-minus-carrier -19 m/s); 4 GEO satellites give the common code-minus-carrier rate."""
    import receiver.acquisition.code_search as acq
    import receiver.acquisition.reacquisition as reacq

    class _SignsIgnored:                       # the signal as the former hot-search Doppler saw it
        def __init__(self, sig):
            self._sig = sig

        def __getattr__(self, name):
            return getattr(self._sig, name)

        def short_symbols(self, prn):
            return False
    refine = reacq.refine
    d = tmp_path_factory.mktemp("b1i_fl")
    out = d / "bds.bin"
    simulate(str(REPO / "configs/scenarios/bds_static_tokyo.yaml"), str(out),
             overrides=["time.seed=2", "time.duration_s=5.5"], progress=False)
    cfg = load_receiver_config(REPO / "configs/bds_b1i_nav.yaml",
                               [f"input.path={out}", f"output.path={d / 'run.h5'}", "navigation.enabled=false",
                                "acquisition.prns=[1, 2, 3, 4, 32]"])
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(acq, "refine_doppler_squared", lambda *a, **k: a[5])     # the 1-ms estimate unchanged
        mp.setattr(reacq, "refine", lambda *a, **k: refine(*a[:6], _SignsIgnored(a[6]), *a[7:], **k))
        summary = run(cfg, quiet=True, log=lambda *a: None)
    return summary, d / "run.h5", str(out)[:-4] + ".truth.h5"


def test_b1i_carrier_false_lock_restarted_at_code_doppler(b1i_false_lock):
    """The channel whose carrier sits 100 Hz from its code's Doppler is restarted at the code's Doppler and
    then tracks the truth; the true channels (GEO C01-C04) are left alone."""
    summary, h5, truth = b1i_false_lock
    assert summary.tracked == [1, 2, 3, 4, 32]
    with h5py.File(h5, "r") as f, h5py.File(truth, "r") as t:
        for prn in (1, 2, 3, 4, 32):
            g = f["channels"][f"C{prn:02d}"]
            tt = t["satellites"][f"C{prn:02d}"]
            last = g["time_s"][:] > g["time_s"][-1] - 0.5
            err = g["doppler_hz"][:][last] - np.interp(g["time_s"][:][last], tt["time_s"][:], tt["doppler_hz"][:])
            assert np.max(np.abs(err)) < 10.0, (prn, err)
            assert np.median(g["cn0_dbhz"][:][last]) > 42.0
    assert summary.false_locks == {32: 1}
    assert "false locks     C32 x1" in summary.text()
