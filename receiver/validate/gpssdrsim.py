"""GPS-SDR-SIM (an independent GPS L1 C/A simulator, osqzss/gps-sdr-sim) as a signal source.

:func:`simulator` returns the path of a built binary: ``$GNSSRX_GPSSDRSIM`` when set, else one built by the shared
build script (``../shared/tools/build-gps-sdr-sim.sh``) into the cache directory (``out/validate/sim-bin``).
Without a C compiler or the sources it raises :class:`SimulatorUnavailable` with the reason (tests skip on it).

:func:`generate` runs it in dynamic mode (``-u``: an ECEF user-motion file at 10 Hz; row k is the antenna
position at GPS time t0 + 0.1 k, the first output sample is at t0) with ``-b 16`` (noiseless int16 I/Q)
and ``-p 128`` (path loss off: every satellite at the same power, complex amplitude 250, i.e. power
``SAT_POWER`` = 62 500 LSB^2 -- the post-processing sets the C/N0 against that), or with path loss on
(``path_loss=True``: gain 20 200 km / range times the antenna pattern, zenith ~1).  Outputs are cached by
a hash of the binary, the motion file and the options.

Limits of the simulator (gpssim.c, 28ca29a): motion files of at most USER_MOTION_SIZE rows (the build
script sets 4000: 400 s); the output has (rows - 1) x 0.1 s of samples; the sample rate is floored to a
multiple of 10 Hz; the start time must lie within the ephemeris file's span and is floored to a whole
second; no troposphere, Klobuchar ionosphere from the file, up to 16 channels above 0 deg elevation, no
receiver clock error, no multipath.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("GNSSRX_SHARED") or ROOT.parent / "shared")     # ../shared (or $GNSSRX_SHARED)
BUILD_SCRIPT = SHARED / "tools" / "build-gps-sdr-sim.sh"
DEFAULT_CACHE = ROOT / "out" / "validate"
NAV_FILE = SHARED / "data" / "brdc0010.22n"
#: complex power of one satellite's signal with -p 128 (table amplitude 250 on I and Q)
SAT_POWER = 250.0 ** 2
MAX_ROWS = 4000                   # USER_MOTION_SIZE of the shared build script
MOTION_RATE_HZ = 10.0


class SimulatorUnavailable(RuntimeError):
    """GPS-SDR-SIM cannot be found or built here (the message says why)."""


def _file_hash(path, n=1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while True:
            b = f.read(n)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def simulator(cache_dir=None) -> Path:
    """The GPS-SDR-SIM binary (building it into ``cache_dir/sim-bin`` when needed)."""
    env = os.environ.get("GNSSRX_GPSSDRSIM")
    if env:
        if not os.access(env, os.X_OK):
            raise SimulatorUnavailable(f"GNSSRX_GPSSDRSIM={env} is not an executable")
        return Path(env)
    out = Path(cache_dir or DEFAULT_CACHE) / "sim-bin"
    exe = out / "gps-sdr-sim"
    if exe.is_file() and os.access(exe, os.X_OK):
        return exe
    if not BUILD_SCRIPT.is_file():
        raise SimulatorUnavailable(f"GPS-SDR-SIM build script {BUILD_SCRIPT} not found (../shared absent)")
    if not (shutil.which("gcc") or shutil.which("cc")):
        raise SimulatorUnavailable("no C compiler (gcc / cc) to build GPS-SDR-SIM")
    out.mkdir(parents=True, exist_ok=True)
    p = subprocess.run(["bash", str(BUILD_SCRIPT), str(out)], capture_output=True, text=True)
    if p.returncode != 0 or not exe.is_file():
        raise SimulatorUnavailable(f"GPS-SDR-SIM build failed: {(p.stderr or p.stdout).strip()[-300:]}")
    return exe


def simulator_id(exe) -> str:
    """A short hash of the simulator binary (part of every cache key)."""
    return _file_hash(exe)[:16]


def write_motion(path, ecef: np.ndarray) -> None:
    """An ECEF user-motion file: rows ``t, x, y, z`` at 10 Hz (t = 0.1 k)."""
    ecef = np.asarray(ecef, float).reshape(-1, 3)
    if ecef.shape[0] > MAX_ROWS:
        raise ValueError(f"GPS-SDR-SIM takes at most {MAX_ROWS} motion rows ({MAX_ROWS / 10:.0f} s)")
    t = np.arange(ecef.shape[0]) / MOTION_RATE_HZ
    with open(path, "w") as f:
        for tk, (x, y, z) in zip(t, ecef):
            f.write(f"{tk:.1f},{x:.4f},{y:.4f},{z:.4f}\n")


def generate(ecef: np.ndarray, start: str, fs: float, out_dir, path_loss: bool = False,
             nav=NAV_FILE, cache_dir=None) -> Path:
    """Noiseless int16 I/Q samples of the antenna trajectory ``ecef`` (10 Hz rows) starting at ``start``
    ('YYYY/MM/DD,hh:mm:ss', GPS time) at ``fs`` Hz (a multiple of 10).  Cached in ``out_dir`` by hash."""
    exe = simulator(cache_dir)
    if abs(fs / 10 - round(fs / 10)) > 1e-9:
        raise ValueError("GPS-SDR-SIM's sample rate must be a multiple of 10 Hz")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    ecef = np.asarray(ecef, float).reshape(-1, 3)
    h = hashlib.sha256()
    h.update(simulator_id(exe).encode())
    h.update(np.round(ecef, 4).tobytes())
    h.update(f"{start}|{fs:.0f}|{path_loss}|{_file_hash(nav)[:16]}".encode())
    key = h.hexdigest()[:20]
    out = out_dir / f"gpssim_{key}.bin"
    if out.is_file():
        return out
    motion = out_dir / f"gpssim_{key}.motion.csv"
    write_motion(motion, ecef)
    tmp = out.with_suffix(".part")
    # GPS-SDR-SIM copies its file names into 100-character buffers (MAX_CHAR): names relative to its
    # working directory, and the broadcast file through a short link there
    link = out_dir / "brdc.nav"
    if not link.exists():
        link.symlink_to(Path(nav).resolve())
    cmd = [str(exe), "-e", link.name, "-u", motion.name, "-t", start, "-d", f"{ecef.shape[0] / 10:.1f}",
           "-s", f"{fs:.0f}", "-b", "16", "-o", tmp.name]
    if not path_loss:
        cmd += ["-p", "128"]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=out_dir)
    expect = (ecef.shape[0] - 1) * int(round(fs / 10)) * 4
    if p.returncode != 0 or not tmp.is_file() or tmp.stat().st_size != expect:
        msg = [ln for ln in (p.stderr or "").splitlines() if "ERROR" in ln] or [f"exit {p.returncode}"]
        if tmp.exists():
            tmp.unlink()
        raise RuntimeError(f"GPS-SDR-SIM failed: {msg[0].strip()}")
    os.replace(tmp, out)
    motion.unlink()
    return out
