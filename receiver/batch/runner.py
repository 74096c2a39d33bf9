"""Planning, caching and parallel execution of a batch: ``run_batch(batch, ...) -> BatchResult``.

Plan
    Every (variant x sweep point) x input x seed is one run.  Its receiver config is built and validated
    up front (a bad key fails the whole batch with a one-line UserError before anything runs).

Content hashes (cache keys)
    * recording key = sha256 of the fully resolved scenario (``time.seed`` included; files it names, such
      as a RINEX or trajectory CSV, replaced by their content signature) and the code version;
    * run key = sha256 of the fully resolved receiver config with ``output.path`` removed, its input file
      replaced by the recording key (simulated) or the file's content signature (recording), any other
      file it names (``navigation.ephemeris`` ...) by its content signature, and the code version.
    Content signature of a file: sha256 of its bytes up to 16 MiB; beyond, of its size and its first and
    last 4 MiB.  Code version (``code_version: auto``): sha256 of ``receiver.__version__`` and of every
    ``receiver/**/*.py`` except ``receiver/batch`` and ``receiver/leo``, and the numpy / scipy / numba
    versions; a fixed string pins it.  As the
    resolved config includes every default, a change of the receiver's config schema (a new key or default)
    changes the run keys even with a pinned code version.  ``--force`` re-runs the runs, not the simulations
    (recordings are content-addressed).

Layout of ``output_dir``
    ``runs/<run key>.h5`` (the run file), ``runs/<run key>.json`` (status, error, metrics; written last, so
    a run without its JSON is re-run), ``summary.csv``, ``summary.h5``, ``groups.csv``.  Simulated
    recordings live in ``recordings_dir`` as ``<recording key>.{bin,truth.h5,yaml,nav,json}`` (``.nav``:
    the broadcast ephemeris as RINEX 3.04, used by assisted inputs; ``.json`` written last).

A run whose JSON exists with the same key is not run again (failed runs neither, unless
``retry_failed``).  A run that raises is recorded as failed with its error; the others continue.  A killed
batch restarted with the same file runs only what is missing.

Execution
    ``jobs == 1``: in this process; ``jobs > 1``: a process pool (forkserver); a Dask ``scheduler``
    (``tcp://host:port`` or ``local``): the distributed cluster, through its concurrent.futures executor
    (``output_dir`` and ``recordings_dir`` must then be on a file system shared with the workers, and the
    workers need gnssrx installed).  At most ``capacity`` tasks are in flight; ready runs go first, then new
    simulations.  With ``keep_recordings: false`` at most capacity + 1 simulated IF files exist at a time and
    each is deleted as soon as its last run is done.  Pool workers exit within 0.5 s when the batch process
    dies (even by SIGKILL), so a restarted batch never races an orphan; stale ``*.partial`` run files are
    removed at start.  Ctrl-C stops the workers and keeps every finished run.
"""
from __future__ import annotations

import concurrent.futures as cf
from concurrent.futures.process import BrokenProcessPool
import contextlib
import copy
import hashlib
import io
import json
import math
import os
import sys
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from ..config import RECEIVER_SCHEMA, apply_overrides, build, read_yaml
from ..errors import UserError
from .config import REPO_ROOT, Batch, load_batch
from .metrics import METRICS_VERSION, compute_metrics

SIG_FULL_BYTES = 16 << 20
SIG_PART_BYTES = 4 << 20
_SIG_CACHE: dict = {}


# ------------------------------------------------------------------------------------------ hashing
def _hash(obj) -> str:
    text = json.dumps(obj, sort_keys=True, default=repr, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def file_signature(path) -> str:
    """Content signature of a file (see the module docstring)."""
    path = os.path.abspath(os.fspath(path))
    st = os.stat(path)
    ck = (path, st.st_size, st.st_mtime_ns)
    if ck in _SIG_CACHE:
        return _SIG_CACHE[ck]
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        if st.st_size <= SIG_FULL_BYTES:
            h.update(fh.read())
        else:
            h.update(str(st.st_size).encode())
            h.update(fh.read(SIG_PART_BYTES))
            fh.seek(st.st_size - SIG_PART_BYTES)
            h.update(fh.read(SIG_PART_BYTES))
    sig = f"file:{st.st_size}:{h.hexdigest()[:24]}"
    _SIG_CACHE[ck] = sig
    return sig


def code_fingerprint(setting: str = "auto") -> str:
    """Code identity used in the hashes ('auto': the receiver sources, see the module docstring)."""
    if setting != "auto":
        return f"fixed:{setting}"
    import numba
    import numpy as np
    import scipy

    from .. import __version__
    pkg = Path(__file__).resolve().parents[1]
    h = hashlib.sha256(__version__.encode())
    # the numeric libraries change results too (FFT, linear algebra, numba's float contraction)
    h.update(f"numpy {np.__version__} scipy {scipy.__version__} numba {numba.__version__}".encode())
    for p in sorted(pkg.rglob("*.py")):
        rel = p.relative_to(pkg).as_posix()
        if rel.split("/")[0] in ("batch", "leo") or "__pycache__" in rel:
            continue
        h.update(rel.encode())
        h.update(p.read_bytes())
    return f"auto:{__version__}:{h.hexdigest()[:20]}"


def _walk_strings(d: dict, fn, prefix=""):
    """Replace every string leaf v of a nested dict by fn(dotted_key, v) (a new dict)."""
    out = {}
    for k, v in d.items():
        key = prefix + k
        if isinstance(v, dict):
            out[k] = _walk_strings(v, fn, key + ".")
        elif isinstance(v, str):
            out[k] = fn(key, v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _pathlike(v: str) -> bool:
    return ("/" in v or "." in v) and len(v) < 4096


# ------------------------------------------------------------------------------------------ plan
@dataclass
class RecordingTask:
    key: str
    input: str
    seed: int
    scenario: dict                  # resolved scenario, files as absolute paths
    paths: dict                     # if, truth, yaml, nav, meta

    def available(self) -> bool:
        return all(os.path.exists(self.paths[k]) for k in ("meta", "if", "truth", "nav"))


@dataclass
class RunTask:
    key: str
    variant: str                    # label (name + sweep point)
    variant_name: str
    input: str
    kind: str                       # scenario | recording
    seed: int | None
    config: dict                    # validated receiver config (raw dict), output.path = h5
    h5: str
    json: str
    truth: str | None
    reference_llh: list | None
    recording: str | None           # recording key
    set_values: dict = field(default_factory=dict)
    carrier_settle_s: float = 1.0


@dataclass
class Plan:
    batch: Batch
    runs: list
    recordings: dict                # key -> RecordingTask
    code: str


def _recording_paths(rec_dir: str, key: str) -> dict:
    stem = os.path.join(rec_dir, key)
    return {"if": stem + ".bin", "truth": stem + ".truth.h5", "yaml": stem + ".yaml", "nav": stem + ".nav",
            "meta": stem + ".json"}


def _scenario_files(sc: dict):
    """(scenario with file leaves as absolute paths, scenario with file leaves as signatures)."""
    from ..sim.scenario import resolve_path

    def resolved(_k, v):
        if not _pathlike(v):
            return v
        try:
            p = resolve_path(v)
        except UserError:
            return v
        return p if os.path.isfile(p) else v

    absolute = _walk_strings(sc, resolved)
    signed = _walk_strings(absolute, lambda k, v: file_signature(v) if os.path.isabs(v) and os.path.isfile(v)
                           else v)
    return absolute, signed


def _receiver_file(v: str, base_dir: str) -> str | None:
    """An existing file named by a receiver config string (cwd, batch dir, repo root), else None."""
    if not _pathlike(v):
        return None
    p = os.path.expanduser(v)
    cands = [p] if os.path.isabs(p) else [os.path.join(b, p) for b in (os.getcwd(), base_dir, str(REPO_ROOT))]
    for c in cands:
        if os.path.isfile(c):
            return os.path.abspath(c)
    return None


def _deep_merge(a: dict, b: dict) -> dict:
    out = copy.deepcopy(a)
    for k, v in (b or {}).items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _cfg_get(d: dict, dotted: str):
    node = d
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def make_plan(batch: Batch) -> Plan:
    """Expand the batch into runs and the simulated recordings they need (validating every config)."""
    from ..sim.scenario import load_scenario
    b = batch
    code = code_fingerprint(b.cfg.code_version)
    runs_dir = os.path.join(b.output_dir, "runs")
    recordings: dict = {}
    layers: dict = {}
    # input side: (input, seed) -> (receiver overrides, recording key or None, identity overrides for hashing)
    points = []
    for inp in b.inputs:
        if inp.kind == "scenario":
            seeds = inp.seeds if inp.seeds is not None else b.cfg.seeds
            base_sc = load_scenario(inp.scenario, inp.scenario_set)
            for seed in (seeds if seeds else [base_sc.time.seed]):
                sc = load_scenario(inp.scenario, list(inp.scenario_set) + [("time.seed", int(seed))])
                absolute, signed = _scenario_files(sc.to_dict())
                key = _hash({"scenario": signed, "code": code})
                paths = _recording_paths(b.recordings_dir, key)
                recordings[key] = RecordingTask(key=key, input=inp.name, seed=int(seed), scenario=absolute,
                                                paths=paths)
                fe, tm = sc.frontend, sc.time
                ov = [("input.path", paths["if"]), ("input.format", fe.format),
                      ("input.sample_rate_hz", fe.sample_rate_hz), ("input.if_hz", fe.if_hz),
                      ("input.start_gps_week", tm.gps_week), ("input.start_gps_tow_s", tm.tow_s)]
                if inp.assisted:
                    ov.append(("navigation.ephemeris", paths["nav"]))
                ident = {paths["if"]: f"sim:{key}", paths["nav"]: f"simnav:{key}"}
                points.append((inp, int(seed), None, ov, key, ident, paths["truth"]))
        else:
            ov = [("input.path", inp.recording)]
            points.append((inp, None, inp.config, ov, None, {}, inp.truth))
    runs = []
    for var in b.variants:
        base_path = var.config or b.base_config
        if base_path not in layers:
            layers[base_path] = read_yaml(base_path) if base_path else {}
        for inp, seed, inp_cfg, inp_ov, rec_key, ident, truth in points:
            raw = apply_overrides(layers[base_path], b.batch_set)
            if inp_cfg:
                if inp_cfg not in layers:
                    layers[inp_cfg] = read_yaml(inp_cfg)
                raw = _deep_merge(raw, layers[inp_cfg])
            raw = apply_overrides(raw, inp_ov)
            raw = apply_overrides(raw, inp.receiver_set)
            raw = apply_overrides(raw, var.overrides)
            raw = apply_overrides(raw, [("output.path", None)])
            where = f"variant '{var.label}', input '{inp.name}'"
            try:
                cfg = build(RECEIVER_SCHEMA, raw).to_dict()
            except UserError as exc:
                raise UserError(f"{where}: {exc}") from None
            cfg = _walk_strings(cfg, lambda k, v: (_receiver_file(v, b.base_dir) or v)
                                if k != "output.path" else v)
            hashed = _walk_strings(cfg, lambda k, v: ident.get(v) or (file_signature(v) if os.path.isabs(v)
                                                                     and os.path.isfile(v) else v))
            key = _hash({"config": hashed, "code": code})
            h5 = os.path.join(runs_dir, key + ".h5")
            cfg = apply_overrides(cfg, [("output.path", h5)])
            runs.append(RunTask(
                key=key, variant=var.label, variant_name=var.name, input=inp.name, kind=inp.kind, seed=seed,
                config=cfg, h5=h5, json=os.path.join(runs_dir, key + ".json"), truth=truth,
                reference_llh=inp.reference_llh, recording=rec_key,
                set_values={k: _cfg_get(cfg, k) for k in b.set_keys},
                carrier_settle_s=b.cfg.metrics.carrier_settle_s))
    keys = [r.key for r in runs]
    if len(set(keys)) != len(keys):
        dup = next(r for r in runs if keys.count(r.key) > 1)
        twins = [f"{r.variant}/{r.input}/{r.seed}" for r in runs if r.key == dup.key]
        raise UserError(f"runs {' and '.join(twins)} have identical configs and inputs (duplicate variants?)")
    used = {r.recording for r in runs if r.recording}
    return Plan(batch=b, runs=runs, recordings={k: v for k, v in recordings.items() if k in used}, code=code)


# ------------------------------------------------------------------------------------------ worker tasks
def _write_json(path, obj):
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w") as fh:
        json.dump(obj, fh, indent=1, default=_json_default)
    os.replace(tmp, path)


def _json_default(o):
    try:
        import numpy as np
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
    except ImportError:  # pragma: no cover
        pass
    return repr(o)


def _read_json(path):
    try:
        with open(path) as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return None


def write_nav_for_scenario(scenario: dict, path: str):
    """The ephemerides and iono/UTC the simulator broadcasts for this scenario, as a RINEX 3.04 nav file."""
    from ..gnss.ephemeris import IonoUtc
    from ..gnss.rinex import write_rinex_nav
    from ..sim.constellation import load_constellation, quantize_iono
    from ..sim.scenario import load_scenario, resolve_path
    sc = load_scenario(scenario)
    con, tm, atm = sc.constellation, sc.time, sc.atmosphere
    cons = load_constellation(con.source, resolve_path(con.rinex, "RINEX file") if con.rinex else None,
                              resolve_path(con.nominal_file, "constellation file"), tm.gps_week, tm.tow_s,
                              tm.tow_s + tm.duration_s / 2.0)
    ephs = dict(cons.ephemerides)
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


def _capture_stdout(buf):
    """Redirect print() into buf - only on the main thread (process workers, inline): sys.stdout is global,
    so tasks on threads (a threaded Dask worker) leave it alone."""
    if threading.current_thread() is threading.main_thread():
        return contextlib.redirect_stdout(buf)
    return contextlib.nullcontext()


def simulate_recording(task: dict) -> dict:
    """Worker: simulate one recording (IF, truth, input fragment, RINEX nav, then the JSON marker)."""
    t0 = time.perf_counter()
    try:
        from ..sim.simulate import simulate
        paths = task["paths"]
        os.makedirs(os.path.dirname(paths["if"]), exist_ok=True)
        if os.path.exists(paths["meta"]):
            os.remove(paths["meta"])
        with _capture_stdout(io.StringIO()):
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
        cfg = build(RECEIVER_SCHEMA, task["config"])
        with _capture_stdout(log):                    # messages of the stages go to the run's record
            run(cfg, quiet=True, log=lambda *a, **k: None)
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


# ------------------------------------------------------------------------------------------ executors
class _InlineExecutor:
    """jobs == 1: run every task in this process (the serial reference)."""

    def submit(self, fn, *args):
        fut = cf.Future()
        try:
            fut.set_result(fn(*args))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller through the future
            if isinstance(exc, KeyboardInterrupt):
                raise
            fut.set_exception(exc)
        return fut

    def shutdown(self, **_):
        pass


_PRELOAD = ["receiver.batch.runner", "receiver.pipeline", "receiver.sim.simulate", "receiver.evaluate"]


def _process_pool(jobs: int):
    import multiprocessing as mp
    for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ.setdefault(v, "1")
    methods = mp.get_all_start_methods()
    if "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD)
    else:  # pragma: no cover - Windows / macOS without forkserver
        ctx = mp.get_context("spawn")
    return cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_worker_init,
                                  initargs=(os.getpid(),))


def _worker_init(batch_pid: int):
    """Pool workers exit as soon as the batch process is gone: a batch killed hard (SIGKILL) leaves no
    orphan still running (forkserver workers hold both ends of their task queue and never see EOF)."""
    def watch():
        while True:
            time.sleep(0.5)
            try:
                os.kill(batch_pid, 0)
            except ProcessLookupError:
                os._exit(1)
            except OSError:      # pragma: no cover - exists, other owner
                pass

    threading.Thread(target=watch, name="gnssrx-batch-watchdog", daemon=True).start()


class _Exec:
    """The executor of one batch: inline, process pool or Dask (owns what it creates)."""

    def __init__(self, jobs: int, scheduler: str | None, client=None):
        self.kind, self.client, self.cluster, self._own_client = "local", client, None, False
        self.jobs = jobs
        if client is not None or scheduler:
            try:
                from distributed import Client, LocalCluster
            except ImportError:
                raise UserError("a Dask scheduler needs dask.distributed: pip install 'gnssrx[dask]'") from None
            if client is None:
                if scheduler == "local":
                    self.cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                                dashboard_address=None)
                    client = Client(self.cluster)
                else:
                    try:
                        client = Client(scheduler, timeout="10s")
                    except (OSError, TimeoutError, ValueError) as exc:
                        raise UserError(f"cannot connect to the Dask scheduler {scheduler}: {exc}") from None
                self._own_client = True
            self.client, self.kind = client, "dask"
            self.capacity = max(1, sum(client.nthreads().values()))
            self.pool = client.get_executor(pure=False)
        elif jobs <= 1:
            self.kind, self.capacity, self.pool = "inline", 1, _InlineExecutor()
        else:
            self.capacity, self.pool = jobs, _process_pool(jobs)

    def submit(self, fn, arg):
        return self.pool.submit(fn, arg)

    def renew(self):
        """After a crashed worker broke the process pool: a fresh pool."""
        if self.kind == "local":
            self.pool.shutdown(wait=False, cancel_futures=True)
            self.pool = _process_pool(self.jobs)

    def close(self, abort=False):
        if self.kind == "local":
            if abort:
                for p in list(getattr(self.pool, "_processes", {}).values()):
                    try:
                        p.terminate()
                    except Exception:  # pragma: no cover
                        pass
            self.pool.shutdown(wait=not abort, cancel_futures=True)
        elif self.kind == "dask":
            if self._own_client:
                self.client.close()
                if self.cluster is not None:
                    self.cluster.close()


# ------------------------------------------------------------------------------------------ batch
@dataclass
class BatchResult:
    name: str
    output_dir: str
    n_runs: int
    executed: int                   # runs executed by this invocation
    cached: int                     # runs taken from the cache
    failed: int                     # failed runs (this invocation or cached failures)
    simulated: int                  # recordings simulated by this invocation
    wall_s: float
    rows: list                      # one dict per run (summary rows)
    summary_csv: str = ""
    summary_h5: str = ""
    groups_csv: str = ""
    executor: str = ""

    def text(self) -> str:
        return (f"batch {self.name}: {self.n_runs} runs ({self.executed} executed, {self.cached} cached, "
                f"{self.failed} failed), {self.simulated} recordings simulated, {self.wall_s:.1f} s "
                f"[{self.executor}]\nsummary: {self.summary_csv}\n         {self.summary_h5}\n"
                f"groups:  {self.groups_csv}")


def _cached_result(run: RunTask, retry_failed: bool):
    """The stored result of a run when it can be reused, else None."""
    res = _read_json(run.json)
    if not res or res.get("key") != run.key:
        return None
    if res.get("status") == "ok":
        if not os.path.isfile(run.h5):
            return None
        if res.get("metrics_version") != METRICS_VERSION:
            try:
                m = compute_metrics(run.h5, run.truth, run.reference_llh, run.carrier_settle_s)
            except Exception:
                return None
            old = res.get("metrics") or {}
            for k in ("job_wall_s", "job_cpu_s"):       # measured by the runner, not by compute_metrics
                m[k] = old.get(k, math.nan)
            res.update(metrics=m, metrics_version=METRICS_VERSION)
            _write_json(run.json, res)
        return res
    if res.get("status") == "failed" and not retry_failed:
        return res
    return None


def _run_payload(r: RunTask) -> dict:
    return {"key": r.key, "config": r.config, "h5": r.h5, "truth": r.truth, "reference_llh": r.reference_llh,
            "carrier_settle_s": r.carrier_settle_s}


def _rec_payload(rec: RecordingTask) -> dict:
    return {"key": rec.key, "input": rec.input, "seed": rec.seed, "scenario": rec.scenario, "paths": rec.paths}


def _remove_if(rec: RecordingTask):
    try:
        os.remove(rec.paths["if"])
    except OSError:
        pass


def _progress(total: int, quiet: bool, name: str):
    if quiet or not sys.stderr.isatty() or total == 0:
        return None
    from tqdm import tqdm
    return tqdm(total=total, unit="run", desc=f"batch {name}", leave=False, dynamic_ncols=True)


def run_batch(batch, overrides=(), jobs: int | None = None, scheduler: str | None = None, client=None,
              force: bool = False, retry_failed: bool | None = None, quiet: bool = True,
              write: bool = True) -> BatchResult:
    """Run a batch (a Batch, a YAML path or a mapping); returns counts, rows and the summary paths.

    jobs / scheduler override the batch's keys; client: an existing dask.distributed Client (tests);
    force: ignore the cache; write: write summary.csv / summary.h5 / groups.csv.
    """
    from .compare import summary_rows, write_summary
    t0 = time.perf_counter()
    b = batch if isinstance(batch, Batch) else load_batch(batch, overrides)
    plan = make_plan(b)
    jobs = jobs or b.cfg.jobs or _cpu_count()
    scheduler = scheduler if scheduler is not None else b.cfg.scheduler
    retry = b.cfg.retry_failed if retry_failed is None else retry_failed
    keep = b.cfg.keep_recordings
    os.makedirs(os.path.join(b.output_dir, "runs"), exist_ok=True)
    for stale in Path(b.output_dir, "runs").glob("*.partial"):
        stale.unlink(missing_ok=True)

    results: dict = {}
    todo: list = []
    for r in plan.runs:
        res = None if force else _cached_result(r, retry)
        if res is not None:
            results[r.key] = res
            res["_executed"] = False
        else:
            todo.append(r)
    n_cached = len(results)
    # execution order: grouped by recording so that each IF file is freed early
    order = {k: i for i, k in enumerate(plan.recordings)}
    todo.sort(key=lambda r: (order.get(r.recording, -1), r.input, str(r.seed), r.variant))
    waiting: dict = {}
    ready: list = []
    for r in todo:
        if r.recording and not plan.recordings[r.recording].available():
            waiting.setdefault(r.recording, []).append(r)
        else:
            ready.append(r)
    pending_count: dict = {}
    for r in todo:
        if r.recording:
            pending_count[r.recording] = pending_count.get(r.recording, 0) + 1
    to_simulate = [k for k in plan.recordings if k in waiting]
    n_sim = 0
    if not keep:      # IF files no run of this batch needs any more
        for k, rec in plan.recordings.items():
            if k not in pending_count:
                _remove_if(rec)

    bar = _progress(len(todo), quiet, b.name)
    ex = _Exec(jobs, scheduler, client) if todo else None
    executor_name = "cache" if ex is None else (f"dask {ex.capacity} threads" if ex.kind == "dask" else
                                               f"{ex.kind} {ex.capacity} job{'s' if ex.capacity > 1 else ''}")
    inflight: dict = {}
    attempts: dict = {}
    live = sum(1 for k in pending_count if plan.recordings[k].available())
    by_key = {r.key: r for r in plan.runs}
    aborted = True
    try:
        while ready or to_simulate or inflight:
            while ex is not None and len(inflight) < ex.capacity:
                if ready:
                    r = ready.pop(0)
                    inflight[ex.submit(execute_run, _run_payload(r))] = ("run", r.key)
                elif to_simulate and (keep or live < ex.capacity + 1):
                    k = to_simulate.pop(0)
                    live += 1
                    inflight[ex.submit(simulate_recording, _rec_payload(plan.recordings[k]))] = ("sim", k)
                else:
                    break
            if not inflight:
                break
            done, _ = cf.wait(list(inflight), return_when=cf.FIRST_COMPLETED)
            broken = False
            for fut in done:
                kind, key = inflight.pop(fut)
                try:
                    res = fut.result()
                except Exception as exc:            # infrastructure failure (worker died ...)
                    attempts[key] = attempts.get(key, 0) + 1
                    broken = broken or isinstance(exc, BrokenProcessPool)
                    if attempts[key] <= 1:
                        if kind == "run":
                            ready.insert(0, by_key[key])
                        else:
                            to_simulate.insert(0, key)
                            live -= 1
                        continue
                    res = {"key": key, "status": "failed", "error": f"worker failure: {type(exc).__name__}: {exc}",
                           "metrics": {}, "metrics_version": METRICS_VERSION}
                if kind == "sim":
                    n_sim += res.get("status") == "ok"
                    runs = waiting.pop(key, [])
                    if res.get("status") == "ok":
                        ready[0:0] = runs
                    else:
                        live -= 1
                        for r in runs:
                            rr = {"key": r.key, "status": "failed", "error": res.get("error", "simulation failed"),
                                  "traceback": res.get("traceback", ""), "metrics": {},
                                  "metrics_version": METRICS_VERSION}
                            _write_json(r.json, rr)
                            rr["_executed"] = True
                            results[r.key] = rr
                            if bar is not None:
                                bar.update(1)
                else:
                    r = by_key[key]
                    res["variant"], res["input"], res["seed"] = r.variant, r.input, r.seed
                    _write_json(r.json, res)
                    res["_executed"] = True
                    results[key] = res
                    if bar is not None:
                        bar.update(1)
                    if r.recording:
                        pending_count[r.recording] -= 1
                        if pending_count[r.recording] == 0:
                            live -= 1
                            if not keep:
                                _remove_if(plan.recordings[r.recording])
            if broken and ex is not None:
                # in-flight tasks of a broken pool fail too; resubmit them on a fresh pool
                for fut, (kind, key) in list(inflight.items()):
                    inflight.pop(fut)
                    if kind == "run":
                        ready.insert(0, by_key[key])
                    else:
                        to_simulate.insert(0, key)
                        live -= 1
                ex.renew()
        aborted = False
    finally:
        if bar is not None:
            bar.close()
        if ex is not None:
            ex.close(abort=aborted)
    executed = sum(1 for v in results.values() if v.get("_executed"))
    rows = summary_rows(plan, results)
    res = BatchResult(name=b.name, output_dir=b.output_dir, n_runs=len(plan.runs), executed=executed,
                      cached=n_cached, failed=sum(1 for v in results.values() if v.get("status") != "ok"),
                      simulated=n_sim, wall_s=time.perf_counter() - t0, rows=rows, executor=executor_name)
    if write:
        res.summary_csv, res.summary_h5, res.groups_csv = write_summary(plan, rows)
    return res


def _cpu_count() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover
        return max(1, os.cpu_count() or 1)
