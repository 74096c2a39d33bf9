#!/usr/bin/env python3
"""Wall-time ratio gnssrx / GNSS-SDR on the same recording with the same channel count (not part of CI).

Needs the ``gnss-sdr`` executable (Debian: ``apt-get install gnss-sdr``); gnssrx does not depend on it.
Runs both receivers on the reference recording (../shared/data/gpssim_static_tokyo.bin, 8-bit I/Q at
2.6 MS/s) one after the other, ``--repeat`` times alternating the order, and prints per run the wall time
and the CPU time of each (children's user + system), then the medians and the ratios gnssrx / GNSS-SDR.
The machine should be otherwise idle for the wall-time ratio to mean anything; the CPU-time ratio is
less sensitive to other load.

    python scripts/bench_vs_gnsssdr.py [--channels 8] [--repeat 3] [--threads 0] [--keep DIR]

GNSS-SDR's configuration (written to a temporary directory): file source (ibyte), the byte-to-complex
adapter, PCPS acquisition (1 ms, +/-10 kHz, 250 Hz steps), DLL/PLL tracking (PLL 25 Hz, DLL 2 Hz),
telemetry decoder, hybrid observables, RTKLIB single-point PVT; everything at the file's sample rate.
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"
RECORDING = SHARED / "gpssim_static_tokyo.bin"
FS = 2600000

GNSSSDR_CONF = """\
; written by gnssrx scripts/bench_vs_gnsssdr.py
[GNSS-SDR]
GNSS-SDR.internal_fs_sps={fs}
SignalSource.implementation=File_Signal_Source
SignalSource.filename={path}
SignalSource.item_type=ibyte
SignalSource.sampling_frequency={fs}
SignalSource.samples=0
SignalSource.repeat=false
SignalSource.enable_throttle_control=false
SignalSource.dump=false
SignalConditioner.implementation=Signal_Conditioner
DataTypeAdapter.implementation=Ibyte_To_Complex
InputFilter.implementation=Pass_Through
InputFilter.item_type=gr_complex
Resampler.implementation=Pass_Through
Resampler.item_type=gr_complex
Channels_1C.count={channels}
Channels.in_acquisition=1
Channel.signal=1C
Acquisition_1C.implementation=GPS_L1_CA_PCPS_Acquisition
Acquisition_1C.item_type=gr_complex
Acquisition_1C.coherent_integration_time_ms=1
Acquisition_1C.pfa=0.01
Acquisition_1C.doppler_max=10000
Acquisition_1C.doppler_step=250
Acquisition_1C.dump=false
Tracking_1C.implementation=GPS_L1_CA_DLL_PLL_Tracking
Tracking_1C.item_type=gr_complex
Tracking_1C.pll_bw_hz=25.0
Tracking_1C.dll_bw_hz=2.0
Tracking_1C.dump=false
TelemetryDecoder_1C.implementation=GPS_L1_CA_Telemetry_Decoder
TelemetryDecoder_1C.dump=false
Observables.implementation=Hybrid_Observables
Observables.dump=false
PVT.implementation=RTKLIB_PVT
PVT.positioning_mode=Single
PVT.output_rate_ms=100
PVT.display_rate_ms=500
PVT.iono_model=Broadcast
PVT.trop_model=Saastamoinen
PVT.output_path={out}
PVT.dump=false
PVT.enable_monitor=false
"""


def timed(cmd, cwd, log):
    """Run cmd; (wall s, CPU s of the child)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(log, "w") as fh:
        rc = subprocess.run(cmd, cwd=cwd, stdout=fh, stderr=subprocess.STDOUT).returncode
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if rc != 0:
        sys.exit(f"bench_vs_gnsssdr: {cmd[0]} failed (exit {rc}); see {log}")
    return wall, cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--channels", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=0, help="gnssrx run --threads (0: all cores)")
    ap.add_argument("--keep", help="keep the outputs and logs in this directory")
    args = ap.parse_args()
    exe = shutil.which("gnss-sdr")
    if exe is None:
        print("bench_vs_gnsssdr: gnss-sdr is not installed (Debian: apt-get install gnss-sdr)", file=sys.stderr)
        return 2
    if not RECORDING.exists():
        print(f"bench_vs_gnsssdr: {RECORDING} absent", file=sys.stderr)
        return 2
    work = Path(args.keep or tempfile.mkdtemp(prefix="bench_vs_gnsssdr_"))
    work.mkdir(parents=True, exist_ok=True)
    (work / "gnsssdr").mkdir(exist_ok=True)
    conf = work / "gnsssdr.conf"
    conf.write_text(GNSSSDR_CONF.format(fs=FS, path=RECORDING, channels=args.channels, out=work / "gnsssdr"))
    ours = [sys.executable, "-m", "receiver.cli", "run", str(REPO / "configs" / "gpssim_static_tokyo.yaml"),
            "--input", str(RECORDING), "-o", str(work / "gnssrx.h5"), "-q", "--threads", str(args.threads),
            "--set", f"tracking.max_channels={args.channels}"]
    theirs = [exe, f"--config_file={conf}"]
    os.environ.setdefault("PYTHONPATH", str(REPO))
    res = {"gnssrx": [], "gnss-sdr": []}
    print(f"recording {RECORDING.name}, {args.channels} channels, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f} at start")
    for i in range(args.repeat):
        order = [("gnssrx", ours), ("gnss-sdr", theirs)]
        if i % 2:
            order.reverse()
        for name, cmd in order:
            wall, cpu = timed(cmd, work / ("gnsssdr" if name == "gnss-sdr" else "."), work / f"{name}_{i}.log")
            res[name].append((wall, cpu))
            print(f"  run {i + 1} {name:<9} wall {wall:6.2f} s  CPU {cpu:6.2f} s")
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in res.items()}
    for k, (w, c) in med.items():
        print(f"median {k:<9} wall {w:6.2f} s  CPU {c:6.2f} s")
    print(f"ratio gnssrx / gnss-sdr: wall {med['gnssrx'][0] / med['gnss-sdr'][0]:.2f}, "
          f"CPU {med['gnssrx'][1] / med['gnss-sdr'][1]:.2f}   (target: wall <= 0.5)")
    print(f"load average {os.getloadavg()[0]:.1f} at the end; outputs and logs in {work}")
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
