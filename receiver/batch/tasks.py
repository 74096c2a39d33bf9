"""The two worker tasks of a batch -- simulate one recording, run the receiver on one config and score it --
executed in this process, a process-pool worker or a Dask worker (see :mod:`receiver.batch.executors`).
Neither raises for a failing run: the failure is recorded in the result."""
from __future__ import annotations

import io
import math
import os
import time
import traceback

from ..schema import build_receiver
from ..logs import capture
from .cache import _write_json
from .metrics import METRICS_VERSION, compute_metrics


def write_nav_for_scenario(scenario: dict, path: str):
    """The ephemerides and iono/UTC the simulator broadcasts for this scenario, as a RINEX 3.04 nav file
    (GPS, + QZSS with constellation.qzss; BeiDou scenarios: the BeiDou sets; GPS + BeiDou: a mixed file)."""
    from ..gnss.ephemeris import IonoUtc
    from ..gnss.rinex import write_rinex_nav
    from ..sim.constellation import load_constellation, quantize_iono
    from ..sim.scenario import load_scenario, resolve_path
    sc = load_scenario(scenario)
    con, tm, atm = sc.constellation, sc.time, sc.atmosphere
    if con.source in ("bds_nominal", "bds_rinex"):      # a BeiDou recording: its D1/D2 sets (BDT)
        from types import SimpleNamespace
        from ..sim.bds_constellation import bds_nominal_ephemerides, bds_rinex_ephemerides
        if con.source == "bds_nominal":
            b_ephs, b_iono = bds_nominal_ephemerides(resolve_path(con.bds_file, "constellation file"),
                                                     tm.gps_week, tm.tow_s)
        else:
            b_ephs, b_iono = bds_rinex_ephemerides(resolve_path(con.rinex, "RINEX file"), tm.gps_week,
                                                   tm.tow_s + tm.duration_s / 2.0)
        cons = SimpleNamespace(ephemerides=b_ephs, iono_utc=quantize_iono(b_iono) if b_iono is not None else None)
    else:
        cons = load_constellation(con.source, resolve_path(con.rinex, "RINEX file") if con.rinex else None,
                                  resolve_path(con.nominal_file, "constellation file"), tm.gps_week, tm.tow_s,
                                  tm.tow_s + tm.duration_s / 2.0,
                                  resolve_path(con.qzss_file, "constellation file") if con.qzss else None)
    ephs = dict(cons.ephemerides)
    if len(list(getattr(sc, "signals", None) or [])) > 1:     # GPS + BeiDou: the nominal BeiDou sets too
        from ..gnss.satid import sat_key
        from ..sim.bds_constellation import bds_nominal_ephemerides
        b_ephs, _ = bds_nominal_ephemerides(resolve_path(con.bds_file, "constellation file"), tm.gps_week,
                                            tm.tow_s)
        ephs.update({sat_key("C", p): e for p, e in b_ephs.items()})
    if con.prns:
        ephs = {p: e for p, e in ephs.items() if p in con.prns}
    for p in con.exclude_prns:
        ephs.pop(p, None)
    iono = cons.iono_utc
    if atm.klobuchar_alpha is not None or atm.klobuchar_beta is not None:
        base = iono or IonoUtc(wnt=tm.gps_week, dt_ls=18, tot=math.floor(tm.tow_s / 4096.0) * 4096.0)
        iono = quantize_iono(IonoUtc(**{**base.__dict__, "alpha": tuple(atm.klobuchar_alpha or base.alpha),
                                        "beta": tuple(atm.klobuchar_beta or base.beta)}))
    tmp = path + ".tmp"
    write_rinex_nav(tmp, {p: [e] for p, e in sorted(ephs.items())}, iono)
    os.replace(tmp, path)


def simulate_recording(task: dict) -> dict:
    """Worker: simulate one recording (IF, truth, input fragment, RINEX nav, then the JSON marker)."""
    t0 = time.perf_counter()
    try:
        from ..sim.simulate import simulate
        paths = task["paths"]
        os.makedirs(os.path.dirname(paths["if"]), exist_ok=True)
        if os.path.exists(paths["meta"]):
            os.remove(paths["meta"])
        with capture(io.StringIO()):
            simulate(task["scenario"], paths["if"], progress=False)
        write_nav_for_scenario(task["scenario"], paths["nav"])
        wall = time.perf_counter() - t0
        _write_json(paths["meta"], {"key": task["key"], "input": task["input"], "seed": task["seed"],
                                    "scenario": task["scenario"], "sim_wall_s": wall,
                                    "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
        return {"status": "ok", "wall_s": wall}
    except Exception as exc:   # recorded, the batch continues
        return {"status": "failed", "error": f"simulation failed: {type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc(limit=8), "wall_s": time.perf_counter() - t0}


def execute_run(task: dict) -> dict:
    """Worker: run the receiver on one config, then score it.  Never raises for a failing run."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = {"key": task["key"], "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    log = io.StringIO()
    try:
        from ..pipeline import run
        from ..threads import set_threads
        set_threads(1)                                # the batch parallelises over runs: 1 thread each
        cfg = build_receiver(task["config"])
        with capture(log):                            # log records of the stages go to the run's record
            summary = run(cfg, quiet=True, log=lambda *a, **k: None)
            from ..export import export_all      # the standard outputs the config asks for
            export_all(summary.output, cfg.output, log=None)
        m = compute_metrics(task["h5"], task["truth"], task["reference_llh"], task["carrier_settle_s"])
        m["job_wall_s"] = time.perf_counter() - t0
        m["job_cpu_s"] = time.process_time() - c0
        out.update(status="ok", error="", metrics=m)
    except Exception as exc:   # recorded, the batch continues
        out.update(status="failed", error=f"{type(exc).__name__}: {exc}".strip(),
                   traceback=traceback.format_exc(limit=12), metrics={"job_wall_s": time.perf_counter() - t0})
    out["log"] = log.getvalue()[-4000:]
    out["metrics_version"] = METRICS_VERSION
    out["host"] = os.uname().nodename if hasattr(os, "uname") else ""
    return out
