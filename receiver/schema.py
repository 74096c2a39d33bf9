"""The receiver's config schema, assembled from the stages' fragments, and loading a receiver config.

Each stage owns the schema fragment of its config section next to its code (the choices come from the
stage's registries, each default is stated there once); :mod:`receiver.config` holds the machinery (``P``,
``build``, YAML, file lookup).  This module puts the fragments together in the order of the config file and
runs the checks that span several sections:

    input        receiver/source/config.py
    signal(s)    receiver/acquisition/config.py (the names of receiver.gnss.registry)
    acquisition  receiver/acquisition/config.py
    tracking     receiver/tracking/config.py
    navigation   receiver/navigation/config.py
    vector       receiver/tracking/vector/config.py
    output       receiver/runfile/config.py
"""
from __future__ import annotations

from .acquisition import config as acquisition_config
from .acquisition.config import SIGNAL_PRNS, run_signals, signal_prns  # noqa: F401 (the receiver's config API)
from .config import Section, build, find_file, read_yaml, resolve_path
from .navigation import config as navigation_config
from .runfile import config as output_config
from .source import config as input_config
from .tracking import config as tracking_config
from .tracking.vector import config as vector_config

RECEIVER_SCHEMA = {
    "input": input_config.SCHEMA,
    **acquisition_config.SIGNALS_SCHEMA,
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
