"""gnssrx from Python: the stable entry points of the command line as functions (docs/plugins.md).

    from receiver import api
    cfg = api.load_config("configs/default.yaml", {"tracking.carrier.variant": "fll_pll"})
    out = api.run(cfg, input="rec.bin", output="run.h5")          # gnssrx run
    run = api.open_run(out)                                       # the run file as arrays
    stats = api.evaluate(out, "rec.truth.h5")                     # gnssrx eval
    result = api.batch("configs/batch/ci_small.yaml", jobs=2)     # gnssrx batch
    table, groups, _ = api.compare(result.summary_h5, by="variant")   # gnssrx compare

Every function raises :class:`receiver.errors.UserError` (one line) for bad input, as the command line
reports it.  The names below are the stable API; everything else in the package may change.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from .errors import UserError

__all__ = ["Run", "UserError", "batch", "compare", "evaluate", "list_plugins", "load_config", "open_run", "run"]


def _overrides(overrides) -> list:
    if overrides is None:
        return []
    if isinstance(overrides, dict):
        return list(overrides.items())
    return list(overrides)


def load_config(config=None, overrides=None):
    """The validated receiver config (a read-only :class:`receiver.config.Section`) of a YAML file (a path,
    a shipped name such as ``configs/default.yaml``, or None for the defaults), with ``overrides``: a dict
    ``{"dotted.key": value}`` or a list of ``"dotted.key=value"`` strings / (key, value) pairs."""
    from .schema import load_receiver_config
    return load_receiver_config(config, _overrides(overrides))


def run(config=None, input=None, output=None, overrides=None, threads: int = 1, quiet: bool = True,
        export: bool = True) -> str:
    """Run the receiver (``gnssrx run``); returns the path of the run file written.

    config: a YAML path / shipped name, None (defaults) or a Section from :func:`load_config`;
    input / output: the IF file and run file (override input.path / output.path); threads: tracking and
    acquisition threads (results do not depend on it); export: also write the standard files the config
    asks for (output.rinex, nmea, ...)."""
    from .config import Section
    from .pipeline import run as run_pipeline
    from .threads import set_threads
    ov = _overrides(overrides)
    if input is not None:
        ov.append(("input.path", os.fspath(input)))
    if output is not None:
        ov.append(("output.path", os.fspath(output)))
    if isinstance(config, Section):
        from .schema import build_receiver, validate_receiver
        cfg = validate_receiver(build_receiver(config.to_dict(), ov))
    else:
        cfg = load_config(config, ov)
    set_threads(threads)
    summary = run_pipeline(cfg, quiet=quiet, log=lambda *a, **k: None)
    if export:
        from .export import export_all
        export_all(summary.output, cfg.output, log=None)
    return summary.output


@dataclass
class Run:
    """A run file as arrays (:func:`open_run`).

    fixes: the navigation solutions (structured array: gps_week, gps_tow, time_s, ecef, lla, n_sats, ...);
    observables: the measurements of every fix epoch (prn, pseudorange_m, doppler_hz, cn0_dbhz, ...);
    channels: {channel group name: {column: array}} of the tracking records (time_s, prn, doppler_hz,
    cn0_dbhz, prompt_i, prompt_q, ...); config: the receiver config the run used (nested dict);
    attrs: the file's attributes (provenance; ``plugins`` when a plugin ran)."""
    path: str
    config: dict
    attrs: dict
    fixes: np.ndarray
    observables: np.ndarray
    channels: dict = field(default_factory=dict)

    def cfg(self, dotted: str, default=None):
        """One config value by its dotted key."""
        from .config import dotted_get
        return dotted_get(self.config, dotted, default)


def open_run(path, channels: bool = True) -> Run:
    """Read a run file (``gnssrx run``'s output) into arrays; ``channels``: also the tracking records."""
    from .runfile.reader import RunFile, load_run
    data = load_run(path)
    chans = {}
    if channels:
        with RunFile(os.fspath(path)) as rf:
            chans = {name: rf.channel(name) for name in rf.channel_names()}
    return Run(path=data.path, config=data.config, attrs=dict(data.attrs), fixes=data.fixes,
               observables=data.obs, channels=chans)


def evaluate(run_h5, truth_h5) -> dict:
    """Statistics of a run's fixes against a simulator truth file (``gnssrx eval``: horizontal / vertical
    / 3D errors, velocity and clock errors, TTFF; the keys of receiver.evaluate.evaluate)."""
    from .evaluate import evaluate as _evaluate
    return _evaluate(run_h5, truth_h5)


def batch(batch_file, overrides=None, jobs: int | None = None, force: bool = False, quiet: bool = True):
    """Run a batch (``gnssrx batch``: receiver configs x inputs x seeds, simulated truth, metrics); returns
    the BatchResult (``rows``: one dict of metrics per run; ``summary_csv`` / ``summary_h5`` /
    ``groups_csv``: the files written).  ``batch_file``: a YAML path or a mapping."""
    from .batch.runner import run_batch
    return run_batch(batch_file, _overrides(overrides), jobs=jobs, force=force, quiet=quiet)


def compare(summary_h5, by="variant", metrics=None, plot=None) -> tuple:
    """``gnssrx compare``: a batch summary (``summary.h5``) grouped by ``by`` (a summary column or receiver
    config key, or a list of them); returns (table text, groups: [{<by>: value, n_runs, n_ok, <metric>_mean,
    _lo, _hi, _n}], plot path or None).  ``plot``: a PNG path for the comparison plot."""
    from .batch.compare import compare as _compare
    groups_by = [by] if isinstance(by, str) else list(by)
    table, groups, path = _compare(os.fspath(summary_h5), groups_by, list(metrics) if metrics else None, plot)
    return table, [{k: v for k, v in g.items() if k != "_members"} for g in groups], path


def list_plugins() -> dict:
    """{kind: [(name, origin, version)]} of the built-in variants and installed plugins (``gnssrx
    plugins``); a broken plugin's origin is its one-line error."""
    from . import __version__, plugins
    from .tracking.carrier import REGISTRY as LOOPS
    from .tracking.vector import REGISTRY as FILTERS
    out = {}
    for kind, builtin in (("carrier_loop", LOOPS), ("vector_filter", FILTERS)):
        rows = [(name, "built-in", __version__) for name in builtin]
        for name, found in plugins.installed(kind):
            rows.append((name, found, None) if isinstance(found, str) else (name, found.origin, found.version))
        out[kind] = rows
    return out
