"""A simulated GPS L1 + L5 recording (configs/scenarios/l1l5_static_tokyo.yaml, L5 at 10.5 MS/s), the receiver
run on it assisted with a RINEX navigation file, and the run exported as RINEX observation + navigation files:
the input of the tests that hand our RINEX to RTKLIB."""
from receiver.export.rinex_obs import write_nav, write_rinex_obs
from receiver.pipeline import run
from receiver.runfile.reader import load_run
from receiver.schema import load_receiver_config
from receiver.sim.simulate import simulate

from repo_paths import CONFIGS


def simulate_run_export(d, duration_s, nav):
    """Into directory d: x.bin / x_l5.bin (+ truth), run.h5, run.obs, run.nav; nav is both the simulator's
    broadcast ephemerides and the receiver's assistance."""
    simulate(CONFIGS / "scenarios/l1l5_static_tokyo.yaml", str(d / "x.bin"), progress=False, overrides=[
        f"time.duration_s={duration_s}", f"constellation.rinex={nav}", "l5.sample_rate_hz=10.5e6"])
    run(load_receiver_config(d / "x.yaml", [("navigation.ephemeris", str(nav)),
                                            ("output.path", str(d / "run.h5"))]), quiet=True)
    r = load_run(d / "run.h5")
    write_rinex_obs(d / "run.obs", r)
    write_nav(d / "run.nav", r)
