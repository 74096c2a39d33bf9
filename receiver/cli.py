"""Command-line interface: ``gnssrx run | acquire | simulate | eval | leo ...``.

Bad user input (config keys/values, missing or malformed files) raises UserError anywhere below; it is
reported here as one line on stderr with exit code 2 and no traceback.  SIGINT and SIGTERM stop a command
(at the next chunk boundary in ``run`` and ``simulate``, see receiver/interrupt.py), remove its temporary
files and exit with 130 / 143 and one line.
"""
from __future__ import annotations

import logging
import os
import sys
from dataclasses import dataclass

import click

from . import __version__, interrupt, limit_blas_threads
from .errors import UserError
from .logs import setup_cli


def _prepare_process() -> None:
    """What every command sets up before its work: one BLAS thread (:func:`receiver.limit_blas_threads`,
    effective when numpy has not loaded yet), stale numba caches of a source tree dropped, and numba's
    first cache load without its BLAS probe importing scipy.linalg and a failed cache write (a full disk)
    not fatal (receiver/_numba_start.py), and the C allocator's settings for a flat resident memory
    (receiver/_malloc.py, before any thread starts)."""
    limit_blas_threads()
    from . import _malloc, _numba_start
    _malloc.configure()
    from .tracking import refresh_compiled_caches
    refresh_compiled_caches()
    _numba_start.prepare()
    _numba_start.tolerate_cache_write_errors()


@dataclass
class _Invocation:
    """One call of the ``gnssrx`` command group, owned by that call (the click context's ``obj``):
    ``process_entry`` -- it is this process's own command line (not click's test runner nor a script
    calling main(args=...)); ``finished_run`` -- ``gnssrx run`` has written all its outputs (its files are
    closed and renamed): only then does the process exit without the teardown."""
    process_entry: bool = False
    finished_run: bool = False


def _invocation() -> _Invocation:
    """The running command's :class:`_Invocation` (a fresh one when the command runs outside the group)."""
    ctx = click.get_current_context(silent=True)
    inv = ctx.find_object(_Invocation) if ctx is not None else None
    return inv if inv is not None else _Invocation()


class _Group(click.Group):
    def main(self, *args, **kwargs):
        # the process's own command line: the console script or ``python -m receiver.cli`` (their __main__
        # module calls this very group), no explicit arguments (click's test runner and scripts pass
        # args=...), standalone (the exit status is the result); then the exit skips the teardown
        process_entry = not args and "args" not in kwargs and kwargs.get("standalone_mode", True) and \
            getattr(sys.modules.get("__main__"), "main", None) is self
        inv = kwargs.setdefault("obj", _Invocation(process_entry=bool(process_entry)))
        try:
            return self._main(*args, **kwargs)
        except SystemExit as exc:
            if process_entry and isinstance(inv, _Invocation) and inv.finished_run:
                _exit_now(exc.code)
            raise

    def _main(self, *args, **kwargs):
        import signal
        _prepare_process()
        saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGXFSZ)}
        interrupt.install()
        try:
            return super().main(*args, **kwargs)
        except interrupt.Interrupted as exc:       # outside a command (argument parsing, exit)
            click.echo(f"gnssrx: interrupted by {exc.name}", err=True)
            sys.exit(exc.exit_code)
        finally:
            interrupt.reset()
            try:
                for s, h in saved.items():
                    if h is not None:
                        signal.signal(s, h)
            except ValueError:          # not the main thread
                pass

    def parse_args(self, ctx, args):
        if not args:                 # bare ``gnssrx``: the help, and success (click's default exits 2)
            click.echo(ctx.get_help())
            ctx.exit(0)
        return super().parse_args(ctx, args)

    def invoke(self, ctx):
        try:
            result = super().invoke(ctx)
            interrupt.check()           # a signal during the last steps still stops with 130/143
            return result
        except UserError as exc:
            click.echo(f"gnssrx: error: {exc}", err=True)
            ctx.exit(2)
        except (interrupt.Interrupted, KeyboardInterrupt) as exc:
            sig = exc if isinstance(exc, interrupt.Interrupted) else interrupt.Interrupted(2)
            click.echo(f"gnssrx: interrupted by {sig.name}; unfinished output files removed", err=True)
            ctx.exit(sig.exit_code)


def _exit_now(code) -> None:
    """End the process with ``sys.exit(code)``'s status without the interpreter's teardown of every module
    (with numpy, numba / llvmlite and h5py loaded that teardown took 0.2-0.25 s of a quiet 1-s run, ~0.5 s
    at load 9).  Only after a completed ``gnssrx run`` (its files are closed and renamed; other commands
    and error exits end as usual).  The atexit handlers still run
    (logging, HDF5, multiprocessing), the receiver's thread pool is shut down and stdout / stderr are
    flushed first.  Returns (the caller raises SystemExit as usual) when another non-daemon thread is still
    alive, or under a profiler, tracer or coverage (their results are written at the interpreter's exit)."""
    import atexit
    import threading
    if sys.getprofile() is not None or sys.gettrace() is not None:
        return
    from . import threads
    threads.shutdown()
    if any(t is not threading.main_thread() and t.is_alive() and not t.daemon for t in threading.enumerate()):
        return
    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code & 0xFF
    else:                                   # sys.exit("message"): printed, status 1
        print(code, file=sys.stderr)
        status = 1
    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001 - a closed pipe: nothing more can be written anyway
                pass
        os._exit(status)


class _StderrWarnings(logging.Handler):
    """receiver.errors.warn -> one line ``gnssrx: warning: ...`` on the current sys.stderr."""

    def emit(self, record):
        try:
            sys.stderr.write(f"gnssrx: warning: {record.getMessage()}\n")
            sys.stderr.flush()
        except Exception:  # noqa: BLE001 - logging must not break the run
            self.handleError(record)


def _warnings_to_stderr():
    lg = logging.getLogger("receiver.warnings")
    if not any(isinstance(h, _StderrWarnings) for h in lg.handlers):
        lg.addHandler(_StderrWarnings())
    lg.propagate = False


@click.group(cls=_Group)
@click.version_option(__version__, prog_name="gnssrx")
def main():
    """gnssrx - GNSS software receiver for recorded IF samples."""
    setup_cli()
    _warnings_to_stderr()


def _load(config, input_path, sets, output=None):
    from .schema import load_receiver_config
    overrides = list(sets)
    if input_path:
        overrides.append(("input.path", input_path))
    if output:
        overrides.append(("output.path", output))
    return load_receiver_config(config, overrides)


@main.command()
@click.argument("config", type=str)
@click.option("--input", "input_path", type=str, help="IF file (overrides input.path)")
@click.option("--output", "-o", type=str, help="HDF5 output (overrides output.path)")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="override a config key")
@click.option("--quiet", "-q", is_flag=True, help="no progress bar (the summary is still printed)")
@click.option("--threads", "n_threads", type=click.IntRange(min=0), default=0, show_default=True,
              help="threads for tracking and acquisition (0: all cores); results do not depend on it")
@click.option("--timings", is_flag=True, help="print the wall and CPU time of each stage to stderr")
def run(config, input_path, output, sets, quiet, n_threads, timings):
    """Run the receiver on a recorded IF file and write one HDF5 file."""
    from .stagetimes import StageTimes, recording
    inv = _invocation()
    times = StageTimes()                    # this command's stage times (--timings)
    times.add("start-up", *_since_process_start())
    with recording(times):
        _run(config, input_path, output, sets, quiet, n_threads, inv)
    if timings:
        import time
        wall, _ = _since_process_start()
        click.echo(times.text(wall, time.process_time()), err=True)
    inv.finished_run = True          # run file closed, standard outputs written: exit without the teardown


def _run(config, input_path, output, sets, quiet, n_threads, inv):
    """``gnssrx run``'s work, inside its stage-time recording."""
    from .stagetimes import stage
    import gc
    own = inv.process_entry and gc.isenabled()
    if own:
        gc.disable()                # no collection while the imports build their ~10^5 lasting objects
    try:
        with stage("imports"):
            from .pipeline import run as run_pipeline
            from .threads import set_threads
    finally:
        if own:
            _freeze_gc()
    set_threads(n_threads)
    with stage("config"):
        cfg = _load(config, input_path, sets, output)
    log = logging.getLogger("receiver.pipeline").info
    from .probe.hints import explain_no_fix, warn_format
    warn_format(cfg)                             # the file's bytes against input.format (1 MiB read)
    summary = run_pipeline(cfg, quiet=quiet, log=log, reads=[config])
    with stage("export"):
        from .export import export_all      # standard outputs (output.rinex, nmea, ...) from the closed run file
        export_all(summary.output, cfg.output, log=None if quiet else log)
    click.echo(summary.text())                   # --quiet silences the progress bar only
    for line in explain_no_fix(cfg, summary):    # what was acquired / tracked, what to check
        click.echo(line)


def _freeze_gc():
    """After ``run``'s imports (the garbage collector was off meanwhile, then on again): every object alive
    (~10^5: numpy, scipy, numba, h5py, ...) is moved out of the cyclic collector's reach (gc.freeze).
    They live as long as the process; otherwise every full collection during the run walks them again,
    40-60 ms each, landing wherever the allocation counts trigger one (in a 1-s run: during the imports
    and in the HDF5 close; 0.11 -> 0.015 s of collections).  Objects created later are collected as
    usual.  Only for the process's own command line (``_Invocation.process_entry``): a test runner or a script calling
    ``main`` keeps its collector as it is (freezing would keep its uncollected garbage forever)."""
    import atexit
    import gc
    gc.freeze()
    gc.enable()
    atexit.register(gc.unfreeze)    # the interpreter's teardown (error exits) then finalizes them as usual


def _since_process_start() -> tuple[float, float]:
    """(wall s since this process started, CPU s it used so far); wall from /proc (Linux), else 0."""
    import time
    cpu = time.process_time()
    try:
        with open("/proc/self/stat") as fh:
            start_ticks = int(fh.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as fh:
            uptime = float(fh.read().split()[0])
        return max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK")), cpu
    except (OSError, ValueError, IndexError):
        return 0.0, cpu


@main.command()
@click.argument("config", type=str)
@click.option("--input", "input_path", type=str, help="IF file (overrides input.path)")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="override a config key")
def acquire(config, input_path, sets):
    """Acquire all configured PRNs and print a table."""
    from .acquisition.stage import acquire as do_acquire
    from .pipeline import open_input
    from .probe.hints import no_satellite_lines, warn_format
    cfg = _load(config, input_path, sets)
    warn_format(cfg)
    reader = open_input(cfg)
    start = reader.first + int(round(cfg.acquisition.start_s * reader.fs))
    notes = []
    res = do_acquire(cfg, reader, start, cfg.acquisition.prns, widen=True, notes=notes)
    click.echo(f"{'PRN':>4} {'detected':>8} {'doppler_hz':>11} {'code_phase':>11} {'metric':>7} "
               f"{'C/N0~':>6}")
    for r in res:
        click.echo(f"{r.prn:4d} {('yes' if r.detected else 'no'):>8} {r.doppler_hz:11.1f} "
                   f"{r.code_phase_chips:11.2f} {r.metric:7.2f} {r.cn0_dbhz_est:6.1f}")
    click.echo(f"detected: {' '.join(str(r.prn) for r in res if r.detected) or 'none'}")
    for line in (reader.summary_lines() if hasattr(reader, "summary_lines") else []) + notes:
        click.echo(line)
    if not any(r.detected for r in res):
        for line in no_satellite_lines(cfg, reader):
            click.echo(line)


@main.command("plugins")
def plugins_cmd():
    """List the carrier loops and vector filters: built-in and installed plugins, with where each comes
    from (docs/plugins.md)."""
    from . import plugins as P
    from .tracking.carrier import REGISTRY as LOOPS, check_class
    from .tracking.vector import REGISTRY as FILTERS, filter_class
    tables = (("carrier_loop", "carrier loops (tracking.carrier.variant)", LOOPS,
               lambda name, f: check_class(name, f.cls)),
              ("vector_filter", "vector filters (vector.variant)", FILTERS, lambda name, f: filter_class(name)))
    for kind, title, builtin, check in tables:
        group = P.KINDS[kind][0]
        click.echo(f"{title}; plugins: entry points {group} or module:Class")
        for name, cls in builtin.items():
            click.echo(f"  {name:<14} built-in  gnssrx {__version__}")
        for name, found in P.installed(kind):
            if isinstance(found, str):
                click.echo(f"  {name:<14} BROKEN    {found}")
                continue
            try:
                check(name, found)
            except UserError as exc:
                click.echo(f"  {name:<14} BROKEN    {exc}")
                continue
            click.echo(f"  {name:<14} plugin    {found.version or '?'}  {found.origin}  "
                       f"({found.cls.__module__}.{found.cls.__qualname__})")


#: commands that live in their own packages: name -> (module, attribute), imported when the command is
#: used (or listed by --help), so that ``gnssrx run`` does not pay for importing them (~0.3 s); a failing
#: import is a real error and shows
LAZY_COMMANDS = {
    "simulate": ("receiver.sim.cli", "simulate"), "eval": ("receiver.sim.cli", "evaluate_cmd"),
    "leo": ("receiver.leo.cli", "leo"), "export": ("receiver.export.cli", "export"),
    "report": ("receiver.export.cli", "report"), "info": ("receiver.export.cli", "info"),
    "batch": ("receiver.batch.cli", "batch"), "compare": ("receiver.batch.cli", "compare"),
    "probe": ("receiver.probe.cli", "probe"),
    "validate": ("receiver.validate.cli", "validate"),
    "snapshot": ("receiver.snapshot.cli", "snapshot"),
}


def _list_commands(ctx):
    return sorted(set(click.Group.list_commands(main, ctx)) | set(LAZY_COMMANDS))


def _get_command(ctx, name):
    cmd = click.Group.get_command(main, ctx, name)
    if cmd is None and name in LAZY_COMMANDS:
        import importlib
        mod, attr = LAZY_COMMANDS[name]
        cmd = getattr(importlib.import_module(mod), attr)
        if cmd.name != name:                 # pragma: no cover - the table and the command disagree
            raise RuntimeError(f"gnssrx: command {name!r} is registered as {cmd.name!r}")
        main.add_command(cmd)
    return cmd


main.list_commands = _list_commands
main.get_command = _get_command

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
