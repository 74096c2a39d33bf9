"""Where a run spends its time: wall and CPU seconds per stage (``gnssrx run --timings``).

The times are kept by a :class:`StageTimes` object that its owner makes and activates for a span of work:
``with recording(times): ...`` (``gnssrx run`` makes one per command).  Inside it, ``with stage("tracking"):
...`` anywhere in the code adds the block's wall time and the CPU time the whole process used meanwhile
to the active object (every thread: the tracking pool's workers count under "tracking"; a background
thread running at the same time counts under the stage that was open in the main thread).  Outside any
recording ``stage`` does nothing.  Stages may nest: the time of an inner stage is not counted again in the
outer one ("self" times).  The cost is a few microseconds per block, so the stages stay instrumented in
every run.

The active object is a context variable (the recording's thread and context only), not module state:
two runs in one process (the API, tests) each see their own times or none.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from contextvars import ContextVar


class StageTimes:
    """Wall and CPU seconds and call counts per stage name (self times: nested stages subtracted)."""

    def __init__(self):
        self._wall: dict[str, float] = {}
        self._cpu: dict[str, float] = {}
        self._calls: dict[str, int] = {}
        self._stack: list[list] = []          # [name, wall of the children, cpu of the children]

    @contextmanager
    def stage(self, name: str):
        """Context manager: add the block's wall and process CPU time (s), less that of nested stages, to
        ``name``."""
        w0, c0 = time.perf_counter(), time.process_time()
        self._stack.append([name, 0.0, 0.0])
        try:
            yield
        finally:
            _, cw, cc = self._stack.pop()
            dw, dc = time.perf_counter() - w0, time.process_time() - c0
            self._wall[name] = self._wall.get(name, 0.0) + dw - cw
            self._cpu[name] = self._cpu.get(name, 0.0) + dc - cc
            self._calls[name] = self._calls.get(name, 0) + 1
            if self._stack:
                self._stack[-1][1] += dw
                self._stack[-1][2] += dc

    def add(self, name: str, wall: float, cpu: float) -> None:
        """Account a span measured elsewhere (e.g. the start-up before the CLI ran)."""
        self._wall[name] = self._wall.get(name, 0.0) + wall
        self._cpu[name] = self._cpu.get(name, 0.0) + cpu
        self._calls[name] = self._calls.get(name, 0) + 1

    def table(self) -> dict[str, tuple[float, float, int]]:
        """name -> (wall s, CPU s, calls), in the order the stages first finished."""
        return {k: (self._wall[k], self._cpu[k], self._calls[k]) for k in self._wall}

    def text(self, total_wall: float | None = None, total_cpu: float | None = None) -> str:
        """The stage table as aligned text (wall s, CPU s, calls), with the sum over the stages and, when
        given, the whole process's totals."""
        rows = self.table()
        lines = [f"{'stage':<22} {'wall s':>8} {'CPU s':>8} {'calls':>6}"]
        for k, (w, c, n) in rows.items():
            lines.append(f"{k:<22} {w:8.3f} {c:8.3f} {n:6d}")
        sw = sum(w for w, _, _ in rows.values())
        sc = sum(c for _, c, _ in rows.values())
        lines.append(f"{'sum of stages':<22} {sw:8.3f} {sc:8.3f}")
        if total_wall is not None:
            lines.append(f"{'whole process':<22} {total_wall:8.3f} {total_cpu:8.3f}")
        return "\n".join(lines)


_active: ContextVar[StageTimes | None] = ContextVar("gnssrx_stage_times", default=None)


@contextmanager
def recording(times: StageTimes):
    """Context manager: ``stage`` blocks inside it add to ``times``; yields ``times``."""
    token = _active.set(times)
    try:
        yield times
    finally:
        _active.reset(token)


@contextmanager
def stage(name: str):
    """Context manager: time the block as stage ``name`` of the active :class:`StageTimes` (nothing when
    no recording is active)."""
    times = _active.get()
    if times is None:
        yield
        return
    with times.stage(name):
        yield
