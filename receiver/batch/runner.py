"""Running a batch: ``run_batch(batch, ...) -> BatchResult``.

The plan and its cache keys are made in :mod:`receiver.batch.plan`, finished runs are reused through
:mod:`receiver.batch.cache`, the worker tasks are :mod:`receiver.batch.tasks` and they run on an executor of
:mod:`receiver.batch.executors`.  This module schedules: at most ``capacity`` tasks are in flight; ready runs
go first, then new simulations.  With ``keep_recordings: false`` at most capacity + 1 simulated IF files exist
at a time and each is deleted as soon as its last run is done.  Stale ``*.partial`` run files are removed at
start.  Ctrl-C stops the workers and keeps every finished run.
"""
from __future__ import annotations

import concurrent.futures as cf
from concurrent.futures.process import BrokenProcessPool
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .cache import _cached_result, _write_json
from .config import Batch, load_batch
from .executors import _Exec
from .metrics import METRICS_VERSION
from .plan import RecordingTask, RunTask, make_plan
from .tasks import execute_run, simulate_recording

# ------------------------------------------------------------------------------------------ batch
@dataclass
class BatchResult:
    """What a batch did: run counts (executed, cached, failed), recordings simulated, wall time (s), one summary
    row per run and the paths of the summary and group files written."""
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
        """Summary of the batch for the terminal: counts, wall time, executor and the files written."""
        return (f"batch {self.name}: {self.n_runs} runs ({self.executed} executed, {self.cached} cached, "
                f"{self.failed} failed), {self.simulated} recordings simulated, {self.wall_s:.1f} s "
                f"[{self.executor}]\nsummary: {self.summary_csv}\n         {self.summary_h5}\n"
                f"groups:  {self.groups_csv}")


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


def remove_stale_partials(runs_dir) -> int:
    """Remove the ``*.partial`` run files left by interrupted runs; keep those whose ``.lock`` names a live
    process (a run of another batch invocation writing into the same directory).  Returns the count."""
    from ..safeio import OutputLock, _alive
    n = 0
    for stale in Path(runs_dir).glob("*.partial"):
        owner = OutputLock(str(stale)[:-len(".partial")])._owner()
        if owner is not None and _alive(owner):
            continue
        stale.unlink(missing_ok=True)
        n += 1
    return n


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
    os.makedirs(os.path.join(b.output_dir, "runs"), exist_ok=True)
    remove_stale_partials(os.path.join(b.output_dir, "runs"))
    sched = _Schedule(plan, b.cfg.keep_recordings, force, retry)
    ex = _Exec(jobs, scheduler, client) if sched.todo else None
    executor_name = "cache" if ex is None else (f"dask {ex.capacity} threads" if ex.kind == "dask" else
                                               f"{ex.kind} {ex.capacity} job{'s' if ex.capacity > 1 else ''}")
    sched.bar = _progress(len(sched.todo), quiet, b.name)
    aborted = True
    try:
        sched.execute(ex)
        aborted = False
    finally:
        if sched.bar is not None:
            sched.bar.close()
        if ex is not None:
            ex.close(abort=aborted)
    results = sched.results
    executed = sum(1 for v in results.values() if v.get("_executed"))
    rows = summary_rows(plan, results)
    res = BatchResult(name=b.name, output_dir=b.output_dir, n_runs=len(plan.runs), executed=executed,
                      cached=sched.n_cached, failed=sum(1 for v in results.values() if v.get("status") != "ok"),
                      simulated=sched.n_sim, wall_s=time.perf_counter() - t0, rows=rows, executor=executor_name)
    if write:
        res.summary_csv, res.summary_h5, res.groups_csv = write_summary(plan, rows)
    return res


class _Schedule:
    """The batch's work list and its bookkeeping: cached results, runs ready or waiting for their recording,
    recordings to simulate (at most one more alive than the executor's capacity unless they are kept), the
    runs and simulations in flight, one retry after an infrastructure failure, and the IF files removed as
    soon as no run needs them (unless kept)."""

    def __init__(self, plan, keep: bool, force: bool, retry: bool):
        self.plan, self.keep = plan, keep
        self.results: dict = {}
        self.todo: list = []
        for r in plan.runs:
            res = None if force else _cached_result(r, retry)
            if res is not None:
                self.results[r.key] = res
                res["_executed"] = False
            else:
                self.todo.append(r)
        self.n_cached = len(self.results)
        # execution order: grouped by recording so that each IF file is freed early
        order = {k: i for i, k in enumerate(plan.recordings)}
        self.todo.sort(key=lambda r: (order.get(r.recording, -1), r.input, str(r.seed), r.variant))
        self.waiting: dict = {}
        self.ready: list = []
        for r in self.todo:
            if r.recording and not plan.recordings[r.recording].available():
                self.waiting.setdefault(r.recording, []).append(r)
            else:
                self.ready.append(r)
        self.pending_count: dict = {}
        for r in self.todo:
            if r.recording:
                self.pending_count[r.recording] = self.pending_count.get(r.recording, 0) + 1
        self.to_simulate = [k for k in plan.recordings if k in self.waiting]
        self.n_sim = 0
        if not keep:      # IF files no run of this batch needs any more
            for k, rec in plan.recordings.items():
                if k not in self.pending_count:
                    _remove_if(rec)
        self.inflight: dict = {}
        self.attempts: dict = {}
        self.live = sum(1 for k in self.pending_count if plan.recordings[k].available())
        self.by_key = {r.key: r for r in plan.runs}
        self.bar = None

    def execute(self, ex):
        """Submit, wait, account, until nothing is ready, to simulate or in flight."""
        while self.ready or self.to_simulate or self.inflight:
            self._fill(ex)
            if not self.inflight:
                break
            done, _ = cf.wait(list(self.inflight), return_when=cf.FIRST_COMPLETED)
            broken = False
            for fut in done:
                broken = self._finished(fut) or broken
            if broken and ex is not None:
                # in-flight tasks of a broken pool fail too; resubmit them on a fresh pool
                for fut, (kind, key) in list(self.inflight.items()):
                    self.inflight.pop(fut)
                    self._requeue(kind, key)
                ex.renew()

    def _fill(self, ex):
        while ex is not None and len(self.inflight) < ex.capacity:
            if self.ready:
                r = self.ready.pop(0)
                self.inflight[ex.submit(execute_run, _run_payload(r))] = ("run", r.key)
            elif self.to_simulate and (self.keep or self.live < ex.capacity + 1):
                k = self.to_simulate.pop(0)
                self.live += 1
                self.inflight[ex.submit(simulate_recording, _rec_payload(self.plan.recordings[k]))] = ("sim", k)
            else:
                break

    def _requeue(self, kind, key):
        if kind == "run":
            self.ready.insert(0, self.by_key[key])
        else:
            self.to_simulate.insert(0, key)
            self.live -= 1

    def _finished(self, fut) -> bool:
        """Account one finished task; True when its worker pool broke."""
        kind, key = self.inflight.pop(fut)
        try:
            res = fut.result()
        except Exception as exc:            # infrastructure failure (worker died ...)
            self.attempts[key] = self.attempts.get(key, 0) + 1
            broken = isinstance(exc, BrokenProcessPool)
            if self.attempts[key] <= 1:
                self._requeue(kind, key)
                return broken
            res = {"key": key, "status": "failed", "error": f"worker failure: {type(exc).__name__}: {exc}",
                   "metrics": {}, "metrics_version": METRICS_VERSION}
        else:
            broken = False
        if kind == "sim":
            self._simulated(key, res)
        else:
            self._ran(key, res)
        return broken

    def _simulated(self, key, res):
        self.n_sim += res.get("status") == "ok"
        runs = self.waiting.pop(key, [])
        if res.get("status") == "ok":
            self.ready[0:0] = runs
            return
        self.live -= 1
        for r in runs:
            rr = {"key": r.key, "status": "failed", "error": res.get("error", "simulation failed"),
                  "traceback": res.get("traceback", ""), "metrics": {}, "metrics_version": METRICS_VERSION}
            _write_json(r.json, rr)
            rr["_executed"] = True
            self.results[r.key] = rr
            if self.bar is not None:
                self.bar.update(1)

    def _ran(self, key, res):
        r = self.by_key[key]
        res["variant"], res["input"], res["seed"] = r.variant, r.input, r.seed
        _write_json(r.json, res)
        res["_executed"] = True
        self.results[key] = res
        if self.bar is not None:
            self.bar.update(1)
        if r.recording:
            self.pending_count[r.recording] -= 1
            if self.pending_count[r.recording] == 0:
                self.live -= 1
                if not self.keep:
                    _remove_if(self.plan.recordings[r.recording])


def _cpu_count() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover
        return max(1, os.cpu_count() or 1)
