"""Where a run spends its time: wall and CPU seconds per stage (``gnssrx run --timings``).

``with stage("tracking"): ...`` adds the wall time of the block and the CPU time the whole process used
meanwhile (every thread: the tracking pool's workers count under "tracking"; a background thread running
at the same time counts under the stage that was open in the main thread).  Stages may nest: the
time of an inner stage is not counted again in the outer one ("self" times).  The cost is a few
microseconds per block, so the stages stay instrumented in every run.
"""
from __future__ import annotations

import time
from contextlib import contextmanager

_wall: dict[str, float] = {}
_cpu: dict[str, float] = {}
_calls: dict[str, int] = {}
_stack: list[list] = []          # [name, wall of the children, cpu of the children]


def reset() -> None:
    """Forget all stage times (before a run)."""
    _wall.clear()
    _cpu.clear()
    _calls.clear()
    _stack.clear()


@contextmanager
def stage(name: str):
    """Context manager: add the block's wall and process CPU time (s), less that of nested stages, to `name`."""
    w0, c0 = time.perf_counter(), time.process_time()
    _stack.append([name, 0.0, 0.0])
    try:
        yield
    finally:
        _, cw, cc = _stack.pop()
        dw, dc = time.perf_counter() - w0, time.process_time() - c0
        _wall[name] = _wall.get(name, 0.0) + dw - cw
        _cpu[name] = _cpu.get(name, 0.0) + dc - cc
        _calls[name] = _calls.get(name, 0) + 1
        if _stack:
            _stack[-1][1] += dw
            _stack[-1][2] += dc


def add(name: str, wall: float, cpu: float) -> None:
    """Account a span measured elsewhere (e.g. the start-up before the CLI ran)."""
    _wall[name] = _wall.get(name, 0.0) + wall
    _cpu[name] = _cpu.get(name, 0.0) + cpu
    _calls[name] = _calls.get(name, 0) + 1


def table() -> dict[str, tuple[float, float, int]]:
    """name -> (wall s, CPU s, calls), in the order the stages first ran."""
    return {k: (_wall[k], _cpu[k], _calls[k]) for k in _wall}


def text(total_wall: float | None = None, total_cpu: float | None = None) -> str:
    """The stage table as aligned text (wall s, CPU s, calls), with the sum over the stages and, when given, the
    whole process's totals."""
    rows = table()
    lines = [f"{'stage':<22} {'wall s':>8} {'CPU s':>8} {'calls':>6}"]
    for k, (w, c, n) in rows.items():
        lines.append(f"{k:<22} {w:8.3f} {c:8.3f} {n:6d}")
    sw = sum(w for w, _, _ in rows.values())
    sc = sum(c for _, c, _ in rows.values())
    lines.append(f"{'sum of stages':<22} {sw:8.3f} {sc:8.3f}")
    if total_wall is not None:
        lines.append(f"{'whole process':<22} {total_wall:8.3f} {total_cpu:8.3f}")
    return "\n".join(lines)
