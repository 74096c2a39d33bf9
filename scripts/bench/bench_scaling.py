#!/usr/bin/env python3
"""Scaling with file length and batch size: throughput and resident memory of one long run sampled over time,
against a short run of the same file, and a Dask batch of many short runs under a worker memory limit.

    # a 1-hour, 12-satellite recording (2.048 MS/s int8 I/Q, ~15 GB; streamed by the simulator: it never holds
    # more than a block in memory).  Put it on a disk with room and delete it afterwards.
    python scripts/bench/bench_scaling.py generate /tmp/scaling/hour.bin --seconds 3600
    # the same length from GPS-SDR-SIM (static in Tokyo, the reference recording's ephemeris file, 10
    # satellites, white noise added for ~45 dB-Hz): ~15 min on a loaded 2-core machine instead of hours
    python scripts/bench/bench_scaling.py gpssdrsim /tmp/scaling/hour.bin --seconds 3600
    # the long run sampled every second, then the first --short seconds of the same file
    python scripts/bench/bench_scaling.py run /tmp/scaling/hour.bin [--short 15] [--interval 1] [--nice 10]
    # >= 100 short runs of the reference recording on a LocalCluster, 1 GB per worker
    python scripts/bench/bench_scaling.py dask [--runs 100] [--workers 2] [--memory-limit 1GB]

``run`` starts ``gnssrx run`` as a child whose stderr is a pseudo-terminal (so it draws its progress bar, the
processed signal seconds) and samples /proc/<pid>/status (VmRSS, RssAnon, RssFile, VmHWM) and /proc/<pid>/stat
(CPU) every ``--interval`` s: a table over time (processed s, real-time factor so far, RSS, anonymous and
file-backed RSS) and the peak of each run.  The anonymous part is the receiver's own memory (buffers of the
reader, the channels and the run-file writer); the file-backed part is the mapped input's resident pages.

``dask`` runs a batch of ``--runs`` distinct runs (``--seconds``-long slices of the reference recording at
different start times and PLL bandwidths) through ``receiver.batch.run_batch`` on a ``LocalCluster`` with the
memory limit, samples every worker's RSS, and reads the workers' and nannies' logs and the scheduler's events
for a paused, restarted or killed worker.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
RECORDING = REPO.parent / "shared" / "data" / "gpssim_static_tokyo.bin"
TOKYO_CONFIG = REPO / "configs" / "gpssim_static_tokyo.yaml"

#: the 1-hour scenario: the 12 highest satellites of the embedded constellation, 45 dB-Hz, static
SCENARIO = {
    "time": {"gps_week": 2300, "tow_s": 345600.0, "duration_s": 3600.0, "seed": 11},
    "constellation": {"source": "embedded", "elevation_mask_deg": -5.0},
    "receiver": {"trajectory": "static", "lat_deg": 46.5197, "lon_deg": 6.6323, "height_m": 400.0},
    "clock": {"bias_s": 2.5e-4, "freq_error_ppm": 0.5, "noise": "tcxo"},
    "cn0": {"mode": "constant", "dbhz": 45.0},
    "blockage": {"visible_count": [[0.0, 12]]},
    "atmosphere": {"ionosphere": "klobuchar", "troposphere": "saastamoinen"},
    "frontend": {"sample_rate_hz": 2048000.0, "if_hz": 0.0, "format": "int8_iq", "noise": True},
}

_PROGRESS = re.compile(r"tracking\s.*?([0-9]+(?:\.[0-9]+)?)/([0-9]+(?:\.[0-9]+)?) s")


def proc_sample(pid: int) -> dict | None:
    """One sample of a live process: rss_mb, anon_mb, file_mb, hwm_mb (peak RSS so far) from
    /proc/<pid>/status and cpu_s (user + system) from /proc/<pid>/stat; None once it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        stat = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return None
    kb = {}
    for line in status.splitlines():
        k, _, v = line.partition(":")
        if k in ("VmRSS", "RssAnon", "RssFile", "RssShmem", "VmHWM"):
            kb[k] = int(v.split()[0])
    fields = stat.rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    return {"rss_mb": kb.get("VmRSS", 0) / 1024, "anon_mb": kb.get("RssAnon", 0) / 1024,
            "file_mb": kb.get("RssFile", 0) / 1024, "hwm_mb": kb.get("VmHWM", 0) / 1024,
            "cpu_s": (int(fields[11]) + int(fields[12])) / ticks}


def last_progress(text: str) -> float | None:
    """The processed signal seconds of the last progress-bar update in ``text`` (receiver/pipeline.py's bar:
    ``tracking |...| 12.3/3600.0 s [...]``), None when there is none."""
    m = None
    for m in _PROGRESS.finditer(text):
        pass
    return float(m.group(1)) if m else None


def run_sampled(cmd: list[str], interval: float = 1.0, env=None, nice: int = 0) -> dict:
    """Run ``cmd`` with its stderr on a pseudo-terminal, sampling it every ``interval`` s: {"returncode",
    "wall_s", "samples": [{"t_s", "processed_s", **proc_sample}], "stdout", "stderr", "peak_rss_mb"}."""
    import fcntl
    import pty
    import struct
    import termios
    master, slave = pty.openpty()
    # a window size: without one the progress bar has no width and draws nothing
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))
    pre = (lambda: os.nice(nice)) if nice else None
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=slave, stdin=subprocess.DEVNULL, env=env,
                         preexec_fn=pre)
    os.close(slave)
    buf = []

    def drain():
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:
                return
            if not chunk:
                return
            buf.append(chunk.decode("utf-8", "replace"))

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    out_chunks = []
    threading.Thread(target=lambda: out_chunks.append(p.stdout.read()), daemon=True).start()
    samples, tail, seen = [], "", 0
    while p.poll() is None:
        s = proc_sample(p.pid)
        if s is not None:
            n = len(buf)
            tail, seen = (tail + "".join(buf[seen:n]))[-4000:], n
            s.update(t_s=time.perf_counter() - t0, processed_s=last_progress(tail))
            samples.append(s)
        time.sleep(interval)
    p.wait()
    reader.join(timeout=2)
    os.close(master)
    peak = max((s["hwm_mb"] for s in samples), default=float("nan"))
    return {"returncode": p.returncode, "wall_s": time.perf_counter() - t0, "samples": samples,
            "stdout": (out_chunks[0] if out_chunks else b"").decode(), "stderr": "".join(buf),
            "peak_rss_mb": peak}


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))


def cmd_generate(a) -> int:
    """The long recording (and its truth, input fragment) with the simulator, streamed."""
    from receiver.sim.simulate import simulate
    out = Path(a.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    simulate(SCENARIO, str(out), overrides=[f"time.duration_s={a.seconds:g}"], progress=sys.stderr.isatty())
    print(f"wrote {out} ({out.stat().st_size / 1e9:.1f} GB) in {time.perf_counter() - t0:.0f} s")
    return 0


#: GPS-SDR-SIM's static scenario: the reference recording's place and ephemeris file, 2 h after its start
GPSSDRSIM = {"lla": "35.681298,139.766247,10.0", "start": "2022/01/01,02:00:00", "week": 2190, "tow_s": 525600.0,
             "fs": 2048000, "cn0_dbhz": 45.0}


def cmd_gpssdrsim(a) -> int:
    """The long recording from GPS-SDR-SIM (``-b 16 -p 128``: every satellite at complex amplitude 250),
    streamed through a seeded white-noise adder into int8 I/Q, and its input fragment (.yaml) beside it."""
    import numpy as np
    exe = os.environ.get("GNSSRX_GPSSDRSIM")
    nav = REPO.parent / "shared" / "data" / "brdc0010.22n"
    if not exe or not nav.exists():
        print("bench_scaling: needs GNSSRX_GPSSDRSIM (the simulator) and ../shared/data/brdc0010.22n", file=sys.stderr)
        return 2
    out = Path(a.output).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    link = out.parent / "brdc.nav"            # GPS-SDR-SIM keeps file names in 100-character buffers
    if not link.exists():
        link.symlink_to(nav.resolve())
    g = GPSSDRSIM
    sigma = 250.0 / np.sqrt(2 * 10 ** (g["cn0_dbhz"] / 10) / g["fs"])      # per component, for the C/N0
    scale = np.float32(20.0 / sigma)                                        # noise at 20 LSB rms in int8
    rng = np.random.default_rng(11)
    cmd = [exe, "-e", link.name, "-l", g["lla"], "-t", g["start"], "-d", f"{a.seconds:g}", "-s", str(g["fs"]),
           "-b", "16", "-p", "128", "-o", "-"]
    t0 = time.perf_counter()
    with subprocess.Popen(cmd, cwd=out.parent, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL) as p, \
            open(out, "wb") as fh:
        while block := p.stdout.read(1 << 22):
            x = np.frombuffer(block, np.int16).astype(np.float32)
            x += rng.standard_normal(x.size, dtype=np.float32) * np.float32(sigma)
            x *= scale
            fh.write(np.clip(np.rint(x), -127, 127).astype(np.int8).tobytes())
    if p.returncode != 0:
        print(f"bench_scaling: GPS-SDR-SIM exited with {p.returncode}", file=sys.stderr)
        return 1
    out.with_suffix(".yaml").write_text(
        f"input:\n  path: {out}\n  format: int8_iq\n  sample_rate_hz: {g['fs']}\n  if_hz: 0\n"
        f"  start_gps_week: {g['week']}\n  start_gps_tow_s: {g['tow_s']}\n"
        "navigation:\n  troposphere: none        # GPS-SDR-SIM models none\n")
    print(f"wrote {out} ({out.stat().st_size / 1e9:.1f} GB) in {time.perf_counter() - t0:.0f} s")
    return 0


def _table(res: dict, every: int) -> None:
    """Every ``every``-th sample: time, signal seconds processed, real-time factor over the rows' interval
    (signal s per wall s, and per CPU s), CPU, RSS and its anonymous and file-backed parts."""
    print(f"  {'t s':>7s} {'signal s':>9s} {'x real':>7s} {'x/CPU':>7s} {'CPU s':>7s} {'RSS MB':>7s} "
          f"{'anon MB':>8s} {'file MB':>8s}")
    rows = res["samples"]
    prev = None
    for i, s in enumerate(rows):
        if i % every and i != len(rows) - 1:
            continue
        done = s["processed_s"]
        rate = cpu_rate = f"{'-':>7s}"
        if done is not None and prev is not None and prev["processed_s"] is not None and s["t_s"] > prev["t_s"]:
            d = done - prev["processed_s"]
            rate = f"{d / (s['t_s'] - prev['t_s']):7.1f}"
            if s["cpu_s"] > prev["cpu_s"]:
                cpu_rate = f"{d / (s['cpu_s'] - prev['cpu_s']):7.1f}"
        print(f"  {s['t_s']:7.0f} {done if done is not None else float('nan'):9.1f} {rate} {cpu_rate} "
              f"{s['cpu_s']:7.1f} {s['rss_mb']:7.0f} {s['anon_mb']:8.0f} {s['file_mb']:8.0f}")
        prev = s


def _run_cmd(path: Path, config: Path, seconds: float | None, out: Path) -> list[str]:
    cmd = [sys.executable, "-m", "receiver.cli", "run", str(config), "--input", str(path), "-o", str(out)]
    return cmd + (["--set", f"input.duration_s={seconds:g}"] if seconds else [])


def cmd_run(a) -> int:
    """The long run sampled over time, then the short run of the same file."""
    path = Path(a.input)
    config = Path(a.config) if a.config else path.with_suffix(".yaml")
    if not path.exists() or not config.exists():
        print(f"bench_scaling: {path if not path.exists() else config} not found", file=sys.stderr)
        return 2
    work = Path(a.dir or path.parent)
    res = {}
    for name, seconds in (("long", a.seconds), ("short", a.short)):
        out = work / f"scaling_{name}.h5"
        r = run_sampled(_run_cmd(path, config, seconds, out), a.interval, _env(), a.nice)
        if r["returncode"] != 0:
            print(f"bench_scaling: the {name} run failed:\n{r['stderr'][-2000:]}", file=sys.stderr)
            return 1
        res[name] = r
        s = r["samples"]
        anon = [x["anon_mb"] for x in s]
        half = anon[len(anon) // 2:] or anon
        print(f"\n{name} run ({seconds or 'whole file'} s of signal): {r['wall_s']:.0f} s wall, "
              f"{s[-1]['cpu_s'] if s else float('nan'):.0f} s CPU, peak RSS {r['peak_rss_mb']:.0f} MB "
              f"(anonymous: max {max(anon, default=0):.0f} MB, over the second half {min(half):.0f}-{max(half):.0f}"
              f" MB; load average {os.getloadavg()[0]:.1f})", flush=True)
        _table(r, max(1, len(s) // a.rows))
        print("\n".join(r["stdout"].splitlines()[:4]))
        out.unlink(missing_ok=True)
    ratio = res["long"]["peak_rss_mb"] / res["short"]["peak_rss_mb"]
    print(f"\npeak RSS: long {res['long']['peak_rss_mb']:.0f} MB / short {res['short']['peak_rss_mb']:.0f} MB = "
          f"{ratio:.3f} ({'within' if abs(ratio - 1) <= 0.10 else 'NOT within'} 10 %)")
    return 0


def _dask_batch_file(path: Path, out: Path, runs: int, seconds: float) -> None:
    bws = [15, 18, 20, 25]
    skips = list(range((runs + len(bws) - 1) // len(bws)))
    path.write_text(f"name: scaling_dask\noutput_dir: {out}\nset: {{input.duration_s: {seconds:g}}}\n"
                    f"sweep: {{input.skip_s: {skips}, tracking.pll_bw_hz: {bws}}}\n"
                    f"inputs:\n  - name: tokyo\n    recording: {RECORDING}\n    config: {TOKYO_CONFIG}\n"
                    f"    reference_llh: [35.681298, 139.766247, 10.0]\n")


_TROUBLE = re.compile(r"paus|restart|exceeded|kill|memory budget|unmanaged memory|terminat", re.I)


def cmd_dask(a) -> int:
    """The batch on a LocalCluster with the memory limit; worker RSS sampled, logs and events read."""
    import tempfile
    from distributed import Client, LocalCluster
    from receiver.batch.runner import run_batch
    if not RECORDING.exists():
        print(f"bench_scaling: {RECORDING} not found", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="bench_scaling_dask_") as tmp:
        tmp = Path(tmp)
        batch = tmp / "batch.yaml"
        _dask_batch_file(batch, tmp / "out", a.runs, a.seconds)
        cluster = LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                               memory_limit=a.memory_limit, dashboard_address=None)
        client = Client(cluster)
        pids = set(client.run(os.getpid).values())
        peaks, stop = {}, threading.Event()

        def sample():
            while not stop.is_set():
                for pid in list(set(client.run(os.getpid).values()) | pids):
                    s = proc_sample(pid)
                    if s is not None:
                        peaks[pid] = max(peaks.get(pid, 0.0), s["hwm_mb"])
                stop.wait(a.interval)

        th = threading.Thread(target=sample, daemon=True)
        th.start()
        t0 = time.perf_counter()
        res = run_batch(batch, client=client, quiet=True)
        wall = time.perf_counter() - t0
        stop.set()
        th.join()
        now = set(client.run(os.getpid).values())
        logs = []
        for src, kw in (("worker", {}), ("nanny", {"nanny": True})):
            for addr, lines in client.get_worker_logs(**kw).items():
                logs += [f"{src} {addr}: {msg}" for _, msg in lines]
        logs += [f"scheduler: {msg}" for _, msg in client.get_scheduler_logs()]
        events = [e for topic in ("all", "worker") for e in client.get_events(topic)]
        client.close()
        cluster.close()
    trouble = [ln for ln in logs if _TROUBLE.search(ln)]
    print(f"dask batch: {res.n_runs} runs ({res.executed} executed, {res.failed} failed) on {a.workers} workers "
          f"(1 thread each, memory limit {a.memory_limit}) in {wall:.0f} s wall (load average "
          f"{os.getloadavg()[0]:.1f})")
    print(f"worker processes: {len(pids)} at the start, {len(now)} at the end, {len(pids | now)} seen "
          f"({'none replaced' if now == pids else 'REPLACED'}); peak RSS per worker: "
          + ", ".join(f"{v:.0f} MB" for v in sorted(peaks.values())))
    print(f"log lines read: {len(logs)}, scheduler events: {len(events)}; lines about pausing, restarting or "
          f"killing a worker or its memory: {len(trouble)}")
    for ln in trouble[:20]:
        print("  " + ln[:200])
    return 0 if (res.failed == 0 and now == pids and not trouble) else 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    g = sub.add_parser("generate", help="simulate the long recording")
    g.add_argument("output")
    g.add_argument("--seconds", type=float, default=3600.0)
    s = sub.add_parser("gpssdrsim", help="the long recording from GPS-SDR-SIM (fast)")
    s.add_argument("output")
    s.add_argument("--seconds", type=float, default=3600.0)
    r = sub.add_parser("run", help="the long run and the short run, sampled")
    r.add_argument("input")
    r.add_argument("--config", help="receiver config (default: the recording's .yaml input fragment)")
    r.add_argument("--seconds", type=float, default=None, help="signal seconds of the long run (default: all)")
    r.add_argument("--short", type=float, default=15.0)
    r.add_argument("--interval", type=float, default=1.0)
    r.add_argument("--rows", type=int, default=30, help="rows of the table over time")
    r.add_argument("--nice", type=int, default=0)
    r.add_argument("--dir", help="where the run files go (deleted after the runs)")
    d = sub.add_parser("dask", help="the Dask batch under a memory limit")
    d.add_argument("--runs", type=int, default=100)
    d.add_argument("--workers", type=int, default=2)
    d.add_argument("--memory-limit", default="1GB")
    d.add_argument("--seconds", type=float, default=2.0, help="signal seconds of each run")
    d.add_argument("--interval", type=float, default=1.0)
    a = ap.parse_args()
    return {"generate": cmd_generate, "gpssdrsim": cmd_gpssdrsim, "run": cmd_run, "dask": cmd_dask}[a.what](a)


if __name__ == "__main__":
    sys.exit(main())
