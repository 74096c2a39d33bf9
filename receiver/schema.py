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
import copy
import json

from . import plugins
from .errors import UserError
from .config import Section, apply_overrides, build, find_file, read_yaml, resolve_path
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
    """Load and validate a receiver configuration: the YAML file ``path`` (None: the defaults) merged over
    the schema's defaults, then ``overrides`` applied (a list of ``(dotted_key, value)`` pairs, as
    ``--set``).  ``path`` and the relative file names inside it are looked up as ``gnssrx run`` does
    (current directory, then the checkout and the shipped files); a bad key or value raises
    :class:`receiver.errors.UserError` naming it.  Plugins the config names extend the schema
    (:func:`receiver_schema`)."""
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
    cfg = build_receiver(raw, overrides)
    validate_receiver(cfg)
    return cfg


#: config keys that name an extensible variant: (section path, key, plugin kind)
VARIANT_KEYS = ((("tracking", "carrier"), "variant", "carrier_loop"),
                (("tracking", "carrier"), "auto_weak", "carrier_loop"),
                (("tracking", "carrier"), "auto_strong", "carrier_loop"),
                (("vector",), "variant", "vector_filter"))


def _plugin_class(kind: str, name: str):
    if kind == "carrier_loop":
        from .tracking.carrier import loop_class
        return loop_class(name)
    from .tracking.vector import filter_class
    return filter_class(name)


def _used(raw: dict):
    """(section path, key, kind, name) of every variant key of ``raw`` naming a plugin (not a built-in)."""
    out = []
    for path, key, kind in VARIANT_KEYS:
        node, spec = raw, RECEIVER_SCHEMA
        for part in path:
            node = node.get(part) if isinstance(node, dict) else None
            spec = spec[part]
        name = node.get(key) if isinstance(node, dict) and key in node else spec[key].default
        if isinstance(name, str) and name not in spec[key].choices:
            out.append((path, key, kind, name))
    return out


def receiver_schema(raw: dict | None = None) -> dict:
    """RECEIVER_SCHEMA, extended for the plugins ``raw`` (a parsed config, overrides applied) names: each
    plugin is one more choice of its variant key, and its PARAMS are mounted as the section of its name
    beside that key (``tracking.carrier.<name>``, ``vector.<name>``).  One-line errors for a plugin that
    cannot be found or loaded."""
    used = _used(raw or {})
    if not used:
        return RECEIVER_SCHEMA
    schema = dict(RECEIVER_SCHEMA)
    for path, key, kind, name in used:
        if not plugins.is_reference(name) and name not in plugins.entry_points(kind):
            spec = RECEIVER_SCHEMA
            for part in path + (key,):
                spec = spec[part]
            raise UserError(f"config key '{'.'.join(path + (key,))}' must be one of "
                            f"{', '.join(map(str, spec.choices))}, an installed plugin or module:Class; "
                            f"got {name!r}")
        cls = _plugin_class(kind, name)
        # copy the sections on the path (the fragments themselves stay untouched)
        node = schema
        for part in path:
            node[part] = dict(node[part])
            node = node[part]
        node[key] = copy.copy(node[key])
        node[key].choices = tuple(node[key].choices) + (name,)
        section = cls.name
        if section in node and node[section] is not cls.PARAMS:
            raise UserError(f"{kind.replace('_', ' ')} plugin '{name}': its name '{section}' is already the "
                            f"config key {'.'.join(path)}.{section}")
        if cls.PARAMS:
            node[section] = cls.PARAMS
    return schema


def build_receiver(raw: dict | None = None, overrides=None) -> Section:
    """The receiver config of a parsed YAML mapping and overrides, against :func:`receiver_schema`."""
    raw = apply_overrides(raw or {}, overrides)
    return build(receiver_schema(raw), raw)


def used_plugins(cfg: Section) -> list:
    """The plugins a config uses: [{kind, key, name, class, origin, version, params}] (the run file's
    ``plugins`` attribute)."""
    out = []
    for path, key, kind in VARIANT_KEYS:
        sec = cfg
        for part in path:
            sec = sec[part]
        name = sec[key]
        choices = RECEIVER_SCHEMA
        for part in path:
            choices = choices[part]
        if name in choices[key].choices or (key != "variant" and sec["variant"] != "auto") or \
                (kind == "vector_filter" and not cfg.vector.enabled):
            continue
        cls = _plugin_class(kind, name)
        found = plugins.find(kind, name)
        params = sec[cls.name].to_dict() if cls.PARAMS else {}
        out.append({"kind": kind, "key": ".".join(path + (key,)), "name": name,
                    "class": f"{cls.__module__}.{cls.__qualname__}", "origin": found.origin,
                    "version": found.version, "params": params})
    return out


def plugins_attr(cfg: Section) -> str | None:
    """JSON of :func:`used_plugins`, or None when the config uses none."""
    used = used_plugins(cfg)
    return json.dumps(used, sort_keys=True) if used else None


def validate_receiver(cfg: Section) -> Section:
    """Checks of meaning that span several keys (one-line UserErrors), the stages' own in turn: the IF
    inside the sampled band, a non-empty PRN list of existing PRNs (duplicates are removed with a warning),
    the vector loops' signals, the per-signal files and PRN lists."""
    input_config.check(cfg.input)
    acquisition_config.check_prns(cfg.acquisition)
    sigs = run_signals(cfg)
    acquisition_config.check_signals(cfg, sigs)
    vector_config.check(cfg.vector, sigs)
    acquisition_config.check(cfg.acquisition, sigs)
    input_config.check_signal_files(cfg.input, sigs)
    acquisition_config.check_by_signal(cfg.acquisition, sigs)
    return cfg
