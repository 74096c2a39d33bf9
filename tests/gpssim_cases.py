"""Recordings made with the independent simulator GPS-SDR-SIM for the field-robustness tests: a trajectory,
total signal outages (signal zeroed, noise kept) and a tone switching on mid-file, noise for a zenith
C/N0, a front-end AGC (1-ms power, 10-ms time constant) and 8-bit I/Q quantisation.

``gpssim_binary()`` finds or builds the simulator (None: no C compiler / sources); ``make_case(...)`` writes
the int8 I/Q file and returns its truth (10 Hz ECEF positions, time 0 = the first sample)."""
from __future__ import annotations

import math
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np

from conftest import SHARED as _SHARED

# ../shared/data (or $GNSSRX_SHARED/data, as receiver/validate reads it)
SHARED = Path(os.environ["GNSSRX_SHARED"]) / "data" if os.environ.get("GNSSRX_SHARED") else _SHARED

START = "2022/01/01,01:59:44"           # 2190:525584, the reference recording's start
START_WEEK, START_TOW = 2190, 525584.0
AMP_ZENITH = 250.0                      # GPS-SDR-SIM's amplitude of a zenith satellite (gain 128, table 250)
TOOLS = SHARED.parent / "tools"


def gpssim_binary(tmp: Path) -> Path | None:
    env = os.environ.get("GPS_SDR_SIM")
    if env and os.access(env, os.X_OK):
        return Path(env)
    build = TOOLS / "build-gps-sdr-sim.sh"
    if not build.exists() or not (shutil.which("gcc") or shutil.which("cc")):
        return None
    r = subprocess.run(["bash", str(build), str(tmp / "outside-sim")], capture_output=True, text=True)
    return Path(r.stdout.strip()) if r.returncode == 0 else None


def make_case(sim: Path, out: Path, trajectory, duration_s: float, fs: float = 2.6e6, cn0_dbhz: float = 45.0,
              outages=(), tone=None, seed: int = 1) -> dict:
    """tone: dict(jnr_db, freq_hz, on_s) or None.  trajectory: receiver.sim.trajectory object."""
    t = np.arange(0.0, duration_s + 1.0, 0.1)
    p = trajectory.state(t)[0]
    motion = out.with_suffix(".motion.csv")
    np.savetxt(motion, np.column_stack([t, p]), delimiter=",", fmt="%.4f")
    raw = out.with_suffix(".raw16")
    subprocess.run([str(sim), "-e", str(SHARED / "brdc0010.22n"), "-u", str(motion), "-t", START,
                    "-d", f"{duration_s:g}", "-s", str(int(fs)), "-b", "16", "-o", str(raw)],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    sigma2 = AMP_ZENITH ** 2 * fs / 10 ** (cn0_dbhz / 10)
    rng = np.random.default_rng(seed)
    n_tot = raw.stat().st_size // 4
    m = int(round(fs * 1e-3))
    blk = m * 1000
    state = None
    with open(raw, "rb") as f, open(out, "wb") as g:
        for b0 in range(0, n_tot, blk):
            n = min(blk, n_tot - b0) // m * m
            if n == 0:
                break
            s = np.fromfile(f, dtype=np.int16, count=2 * n).astype(np.float32)
            z = (s[0::2] + 1j * s[1::2]).astype(np.complex64)
            tt = (b0 + np.arange(n)) / fs
            for a, b in outages:
                z[(tt >= a) & (tt < b)] = 0
            z += ((rng.standard_normal(n) + 1j * rng.standard_normal(n)) * math.sqrt(sigma2 / 2)).astype(np.complex64)
            if tone is not None:
                amp = math.sqrt(sigma2 * 10 ** (tone["jnr_db"] / 10))
                on = tt >= tone["on_s"]
                z += np.where(on, amp * np.exp(2j * np.pi * tone["freq_hz"] * tt), 0).astype(np.complex64)
            pw = np.mean(np.abs(z.reshape(-1, m)) ** 2, axis=1)
            gains = np.empty(len(pw))
            for i, v in enumerate(pw):
                state = v if state is None else state + 0.1 * (v - state)
                gains[i] = 24.0 * math.sqrt(2.0) / math.sqrt(state)
            z *= np.repeat(gains, m).astype(np.float32)
            q = np.empty(2 * n, np.int8)
            q[0::2] = np.clip(np.round(z.real), -127, 127)
            q[1::2] = np.clip(np.round(z.imag), -127, 127)
            q.tofile(g)
    raw.unlink()
    return {"t": t, "ecef": p}


def receiver_config(path: Path, out: Path, fs: float = 2.6e6) -> dict:
    """Assisted (broadcast file), troposphere off (GPS-SDR-SIM has none)."""
    return {"input": {"path": str(path), "format": "int8_iq", "sample_rate_hz": fs, "if_hz": 0.0,
                      "start_gps_week": START_WEEK, "start_gps_tow_s": START_TOW},
            "navigation": {"troposphere": "none", "ionosphere": "klobuchar",
                           "ephemeris": str(SHARED / "brdc0010.22n")},
            "output": {"path": str(out)}}


def fix_errors(run_h5: Path, truth: dict):
    """(time s since the first sample, 3D error m, mode) per fix."""
    from receiver.runfile.reader import RunFile
    with RunFile(str(run_h5)) as r:
        fx = r.fix_columns()
    if fx is None or not len(fx["gps_tow"]):
        return np.zeros(0), np.zeros(0), np.zeros(0, int)
    t = np.asarray(fx["gps_tow"], float) - START_TOW
    tr = np.column_stack([np.interp(t, truth["t"], truth["ecef"][:, i]) for i in range(3)])
    return t, np.linalg.norm(np.asarray(fx["ecef"]) - tr, axis=1), np.asarray(fx["mode"], int)
