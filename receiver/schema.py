"""The receiver's config schema, assembled from the stages' fragments, and loading a receiver config.

Each stage owns the schema fragment of its config section next to its code (the choices come from the
stage's registries, each default is stated there once); :mod:`receiver.config` holds the machinery (``P``,
``build``, YAML, file lookup).  This module puts the fragments together in the order of the config file and
runs the checks that span several sections:

    input        receiver/source/config.py
    signal(s)    here (the names of receiver.gnss.registry)
    acquisition  receiver/acquisition_config.py
    tracking     receiver/tracking/config.py
    navigation   receiver/navigation/config.py
    vector       receiver/tracking/vector/config.py
    output       receiver/runfile/config.py
"""
from __future__ import annotations

from . import acquisition_config
from .config import P, Section, build, find_file, read_yaml, resolve_path
from .errors import UserError
from .gnss.registry import SIGNAL_NAMES
from .navigation import config as navigation_config
from .runfile import config as output_config
from .source import config as input_config
from .tracking import config as tracking_config
from .tracking.vector import config as vector_config

SIGNAL_PRNS = acquisition_config.SIGNAL_PRNS

RECEIVER_SCHEMA = {
    "input": input_config.SCHEMA,
    "signal": P("gps_l1ca", "str", "signal to acquire, track and navigate with: gps_l1ca (GPS and QZSS "
                                   "L1 C/A, LNAV) or bds_b1i (BeiDou B1I, D1/D2 messages)",
                choices=SIGNAL_NAMES),
    "signals": P([], "list", "several signals in one run (e.g. [gps_l1ca, bds_b1i]; empty: `signal` alone): "
                             "every signal is acquired and tracked from the same input (input.if_hz is the IF "
                             "of the first; the others sit at if_hz + their carrier - the first's), and the "
                             "fixes use all systems with an inter-system clock bias; README \"Multi-GNSS\""),
    "acquisition": acquisition_config.SCHEMA,
    "tracking": tracking_config.SCHEMA,
    "navigation": navigation_config.SCHEMA,
    "vector": vector_config.SCHEMA,
    "output": output_config.SCHEMA,
}

#: config keys naming input files; relative paths resolve against the current directory, else the config
#: file's directory, else the repository root (so `configs/*.yaml` can say `../shared/data/...`)
PATH_KEYS = (("input", "path"), ("navigation", "ephemeris"))


def load_receiver_config(path=None, overrides=None) -> Section:
    """The receiver config of YAML file ``path`` (None: the defaults) with ``--set`` overrides, validated
    (one-line UserErrors)."""
    if path is not None:
        path = find_file(path)
    raw = read_yaml(path) if path is not None else {}
    for sec, key in PATH_KEYS:
        if isinstance(raw.get(sec), dict) and isinstance(raw[sec].get(key), str):
            raw[sec][key] = resolve_path(raw[sec][key], path)
    files = raw.get("input", {}).get("signal_files") if isinstance(raw.get("input"), dict) else None
    if isinstance(files, dict):
        for v in files.values():
            if isinstance(v, dict) and isinstance(v.get("path"), str):
                v["path"] = resolve_path(v["path"], path)
    cfg = build(RECEIVER_SCHEMA, raw, overrides)
    validate_receiver(cfg)
    return cfg


def run_signals(cfg: Section) -> list:
    """The run's signal names: ``signals`` when set (checked: known names, no repeats), else [``signal``]."""
    sigs = list(cfg.signals or [])
    if not sigs:
        return [cfg.signal]
    for s in sigs:
        if s not in SIGNAL_NAMES:
            raise UserError(f"config key 'signals' must list names of {', '.join(SIGNAL_NAMES)}; got {s!r}")
    if len(set(sigs)) < len(sigs):
        raise UserError(f"config key 'signals' names a signal twice: {sigs}")
    return sigs


def signal_prns(cfg: Section, name: str) -> list:
    """The PRNs searched for signal ``name`` of the run (acquisition.prns_by_signal, else acquisition.prns
    for the first signal, else all of the signal's PRNs)."""
    by = cfg.acquisition.prns_by_signal or {}
    if name in by:
        return list(by[name])
    if name == run_signals(cfg)[0]:
        return list(cfg.acquisition.prns)
    return list(SIGNAL_PRNS[name])


def validate_receiver(cfg: Section) -> Section:
    """Checks of meaning that span several keys (one-line UserErrors), the stages' own in turn: the IF
    inside the sampled band, a non-empty PRN list of existing PRNs (duplicates are removed with a warning),
    the vector loops' signals, the per-signal files and PRN lists."""
    input_config.check(cfg.input)
    acquisition_config.check_prns(cfg.acquisition)
    sigs = run_signals(cfg)
    vector_config.check(cfg.vector, sigs)
    acquisition_config.check(cfg.acquisition, sigs)
    input_config.check_signal_files(cfg.input, sigs)
    acquisition_config.check_by_signal(cfg.acquisition, sigs)
    return cfg
