"""BDS B1I acquisition and scalar tracking on a short simulated IF file (GEO D2 PRN 5, MEO D1+NH PRN 11)."""
import h5py
import numpy as np
import pytest

from receiver.config import load_receiver_config
from receiver.pipeline import run
from receiver.sim.simulate import simulate

REPO = __import__("pathlib").Path(__file__).resolve().parents[1]


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
