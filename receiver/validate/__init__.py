"""Outside-simulator validation: recordings made by GPS-SDR-SIM (not our simulator), scored against its truth.

Python API (the matrix, ``gnssrx validate`` and the tests use the same three calls)::

    from receiver.validate import make_case, run_receiver, score_run

    case = make_case(
        {"dynamics": "static", "place": "tokyo", "start": "02:00:00", "duration_s": 20},   # scenarios.py
        {"sample_rate_hz": 2.048e6, "format": "int8_iq", "cn0_dbhz": 38, "osc_ppm": 2.0,   # postprocess.py
         "seed": 1},
        out_dir="/tmp/me/case1")
    h5 = run_receiver(case, "/tmp/me/case1/run.h5", assisted=True)        # or vector=True, sets=[...]
    m = score_run(h5, case)     # {'ttff_s', 'availability', 'rms_3d_m', 'max_err_m', 'recovery_s', ...}
    case.cleanup()              # delete the recording (the Case's JSON and truth stay)

``make_case`` runs GPS-SDR-SIM (``gpssdrsim.simulator()`` finds or builds it; ``SimulatorUnavailable``
when it cannot) on the scenario's 10-Hz motion file, then post-processes its noiseless int16 I/Q output in
blocks into the recording (noise for the C/N0, oscillator error, filter, I/Q imbalance, DC, quantiser,
format, outages, interference).  ``run_receiver`` runs ``python -m receiver.cli run`` on it with
``configs/validate/receiver.yaml`` (troposphere off: GPS-SDR-SIM has none) and the case's input keys;
``assisted=True`` adds ``navigation.ephemeris`` = the broadcast file GPS-SDR-SIM was given.  ``score_run``
is :func:`receiver.validate.score.score_run`.  The matrix (``configs/validate/matrix.yaml``, ``make
validate``) is :mod:`receiver.validate.matrix`.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import gpssdrsim, postprocess, scenarios
from .gpssdrsim import NAV_FILE, ROOT, SimulatorUnavailable
from .score import score_run

__all__ = ["Case", "make_case", "run_receiver", "score_run", "SimulatorUnavailable", "RECEIVER_CONFIG"]

RECEIVER_CONFIG = ROOT / "configs" / "validate" / "receiver.yaml"


@dataclass
class Case:
    """A recording made for validation, with what is needed to run and score it."""
    scenario: dict
    recording: dict
    path: str                    # the recording
    truth_path: str              # .npy of the ECEF rows at 10 Hz
    input: dict                  # receiver input keys: format, sample_rate_hz, if_hz
    week: int
    tow0: float
    duration_s: float
    outages: list = field(default_factory=list)

    def truth(self):
        """(t, ecef): the truth rows at 10 Hz and their times since the start."""
        rows = np.load(self.truth_path)
        return np.arange(rows.shape[0]) / gpssdrsim.MOTION_RATE_HZ, rows

    def input_sets(self) -> list[str]:
        """The receiver's --set overrides of the input section for this recording."""
        return [f"input.format={self.input['format']}",
                f"input.sample_rate_hz={self.input['sample_rate_hz']:.3f}",
                f"input.if_hz={self.input['if_hz']:.3f}",
                f"input.start_gps_week={self.week}", f"input.start_gps_tow_s={self.tow0:.3f}"]

    def save(self, path):
        """Write the case as JSON."""
        Path(path).write_text(json.dumps(asdict(self), indent=1, default=float))

    @classmethod
    def load(cls, path):
        """Read a case written by :meth:`save`."""
        return cls(**json.loads(Path(path).read_text()))

    def cleanup(self):
        """Delete the recording (the JSON and the truth stay)."""
        if os.path.exists(self.path):
            os.remove(self.path)


def make_case(scenario: dict, recording: dict, out_dir, name: str = "case", cache_dir=None,
              keep_sim: bool = False) -> Case:
    """Simulate and post-process one case into ``out_dir`` (see the module docstring).

    ``recording`` holds ``sample_rate_hz`` (of the written file: complex rate, or the real-IF rate = 2x
    the simulator's) and the post-processing keys of :mod:`receiver.validate.postprocess`."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    scn = dict(scenario)
    scn.setdefault("place", "tokyo")
    scn.setdefault("start", "02:00:00")
    rec = dict(recording)
    fs = float(rec.get("sample_rate_hz", 2.6e6))
    real = postprocess.real_format(rec.get("format", "int8_iq"))
    fs_sim = fs / 2 if real else fs
    rows = scenarios.trajectory_rows(scn)
    truth = out_dir / f"{name}.truth.npy"
    np.save(truth, rows)
    sim = gpssdrsim.generate(rows, f"{scenarios.DATE},{scn['start']}", fs_sim, out_dir / "sim",
                             path_loss=bool(rec.get("path_loss", False)), cache_dir=cache_dir)
    path = out_dir / f"{name}.bin"
    try:
        inp = postprocess.process(sim, path, fs_sim, rec)
    finally:
        if not keep_sim and sim.exists():
            sim.unlink()
    case = Case(scenario=scn, recording=rec, path=str(path), truth_path=str(truth),
                input={k: inp[k] for k in ("format", "sample_rate_hz", "if_hz")},
                week=scenarios.GPS_WEEK, tow0=scenarios.start_tow(scn["start"]),
                duration_s=(rows.shape[0] - 1) / gpssdrsim.MOTION_RATE_HZ,
                outages=[dict(o, atten_db=float(o.get("atten_db", math.inf)))
                         for o in rec.get("outages") or []])
    case.save(out_dir / f"{name}.json")
    return case


def receiver_command(case: Case, out_h5, assisted: bool = True, vector: bool = False, config=None,
                     sets=(), threads: int | None = None) -> list[str]:
    """The ``receiver.cli run`` command line of a case (``threads`` None: the receiver's default)."""
    cmd = [sys.executable, "-m", "receiver.cli", "run", str(config or RECEIVER_CONFIG), "--input", case.path,
           "-o", str(out_h5), "--quiet"] + (["--threads", str(threads)] if threads is not None else [])
    allsets = case.input_sets()
    if assisted:
        allsets.append(f"navigation.ephemeris={NAV_FILE}")
    if vector:
        allsets.append("vector.enabled=true")
    allsets += list(sets)
    for s in allsets:
        cmd += ["--set", s]
    return cmd


def run_receiver(case: Case, out_h5, assisted: bool = True, vector: bool = False, config=None, sets=(),
                 threads: int | None = None, timeout: float | None = None) -> Path:
    """Run ``python -m receiver.cli run`` on the case (this checkout's receiver); returns the run file.
    A failed run raises RuntimeError with the receiver's last line."""
    cmd = receiver_command(case, out_h5, assisted, vector, config, sets, threads)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env, timeout=timeout)
    if p.returncode != 0 or not Path(out_h5).is_file():
        last = (p.stderr or p.stdout or "").strip().splitlines()
        raise RuntimeError(f"receiver failed ({p.returncode}): {last[-1] if last else ''}")
    return Path(out_h5)
