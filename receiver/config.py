"""Typed, validated YAML configuration.

A schema is a nested dict whose leaves are :class:`P` (parameter specs with a default, a type, a
documentation string and optional limits).  :func:`build` merges a user's YAML (and ``--set`` overrides)
over the defaults and returns a :class:`Section` tree with attribute access.  Unknown keys, wrong types and
out-of-range values raise :class:`receiver.errors.UserError` naming the dotted key.

The receiver's own schema is assembled from its stages' fragments in :mod:`receiver.schema`
(``RECEIVER_SCHEMA``, ``load_receiver_config``); other commands (simulator scenarios, LEO, batch) define
their own schemas with the same machinery.
"""
from __future__ import annotations

import copy
import math
import os
import re
from dataclasses import dataclass, field
from typing import Any

import yaml

from .errors import UserError
from .suggest import did_you_mean, refuse_binary

#: YAML dumper of Section.to_yaml: the safe dumper, through libyaml when PyYAML was built with it
_SAFE_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)

_REQUIRED = object()


@dataclass
class P:
    """One parameter: default value, type name, doc string and limits.

    kind: float | int | bool | str | list_int | list_float | list | dict | any
    """
    default: Any
    kind: str
    doc: str
    choices: tuple | None = None
    lo: float | None = None
    hi: float | None = None
    nullable: bool = False
    required: bool = False
    extra: dict = field(default_factory=dict)


class Section:
    """Attribute-access view of one config level."""

    def __init__(self, values: dict):
        self.__dict__["_values"] = values

    def __getattr__(self, name):
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(name) from None

    def __setattr__(self, name, value):
        raise AttributeError("config sections are read-only")

    def __getitem__(self, name):
        return self._values[name]

    def __contains__(self, name):
        return name in self._values

    def get(self, dotted: str):
        """The value at a dotted path (``"tracking.carrier.dataless"``) below this section (KeyError if absent)."""
        node = self
        for part in dotted.split("."):
            node = node[part]
        return node

    def to_dict(self) -> dict:
        """The section as a plain nested dict (a deep copy; sections become dicts)."""
        return {k: (v.to_dict() if isinstance(v, Section) else copy.deepcopy(v))
                for k, v in self._values.items()}

    def to_yaml(self) -> str:
        """The section as YAML (libyaml's emitter when PyYAML has it: ~4x faster than the pure-Python one,
        the same text for every shipped config, tests/unit/core/test_config_yaml_dump.py)."""
        return yaml.dump(self.to_dict(), Dumper=_SAFE_DUMPER, sort_keys=False)

    def __repr__(self):
        return f"Section({self.to_dict()!r})"


def _check(key: str, spec: P, value):
    if value is None:
        if spec.nullable:
            return None
        raise UserError(f"config key '{key}' must not be empty")
    k = spec.kind
    try:
        if k == "float":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError
            value = float(value)
            if not math.isfinite(value):
                raise ValueError
        elif k == "int":
            if isinstance(value, bool) or not (isinstance(value, int) or
                                               (isinstance(value, float) and value.is_integer())):
                raise TypeError
            value = int(value)
        elif k == "bool":
            if not isinstance(value, bool):
                raise TypeError
        elif k == "str":
            if not isinstance(value, str):
                raise TypeError
        elif k in ("list_int", "list_float"):
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                value = [value]
            if not isinstance(value, list):
                raise TypeError
            sub = P(None, k[5:], spec.doc)
            value = [_check(f"{key}[{i}]", sub, v) for i, v in enumerate(value)]
        elif k == "list":
            if not isinstance(value, list):
                raise TypeError
        elif k == "dict":
            if not isinstance(value, dict):
                raise TypeError
        elif k != "any":
            raise AssertionError(f"unknown kind {k}")
    except (TypeError, ValueError):
        raise UserError(f"config key '{key}' must be of type {k}, got {value!r}") from None
    if spec.choices is not None and value not in spec.choices:
        raise UserError(f"config key '{key}' must be one of {', '.join(map(str, spec.choices))}; "
                        f"got {value!r}" + did_you_mean(value, spec.choices))
    for v in (value if isinstance(value, list) and k.startswith("list_") else [value]):
        if spec.lo is not None and v < spec.lo:
            raise UserError(f"config key '{key}' must be >= {spec.lo}, got {v!r}")
        if spec.hi is not None and v > spec.hi:
            raise UserError(f"config key '{key}' must be <= {spec.hi}, got {v!r}")
    return value


def _merge(schema: dict, user: dict, prefix: str) -> dict:
    if not isinstance(user, dict):
        raise UserError(f"config section '{prefix.rstrip('.') or '<top>'}' must be a mapping")
    unknown = [k for k in user if k not in schema]
    if unknown:
        raise UserError(f"unknown config key '{prefix}{unknown[0]}'" + did_you_mean(unknown[0], schema, prefix))
    out = {}
    for name, spec in schema.items():
        key = prefix + name
        if isinstance(spec, dict):
            out[name] = Section(_merge(spec, user.get(name) or {}, key + "."))
        else:
            if name in user:
                out[name] = _check(key, spec, user[name])
            elif spec.required:
                raise UserError(f"config key '{key}' is required")
            else:
                out[name] = copy.deepcopy(spec.default)
    return out


class YamlLoader(yaml.SafeLoader):
    """SafeLoader that also reads exponent floats without a dot (1e-3, 2e-19) as floats, as YAML 1.2 does;
    PyYAML (YAML 1.1) would read them as strings."""


YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))


def yaml_load(stream):
    """yaml.safe_load with :class:`YamlLoader` (every config, scenario and batch file goes through it)."""
    return yaml.load(stream, Loader=YamlLoader)


def parse_override(item: str) -> tuple[str, Any]:
    """Parse one ``--set dotted.key=value`` (value parsed as YAML)."""
    if "=" not in item:
        raise UserError(f"--set expects dotted.key=value, got '{item}'")
    key, text = item.split("=", 1)
    try:
        value = yaml_load(text) if text.strip() else None
    except yaml.YAMLError:
        value = text
    return key.strip(), value


def apply_overrides(raw: dict, overrides) -> dict:
    """A deep copy of the raw config dict with the ``--set`` overrides applied: ``"key=value"`` strings
    (parse_override) or (dotted key, value) pairs; missing sections are created, a key through a non-section
    is a UserError."""
    raw = copy.deepcopy(raw)
    for item in overrides or ():
        key, value = parse_override(item) if isinstance(item, str) else item
        node = raw
        parts = key.split(".")
        for part in parts[:-1]:
            nxt = node.get(part)
            if nxt is None:
                nxt = node[part] = {}
            if not isinstance(nxt, dict):
                raise UserError(f"--set {key}: '{part}' is not a section")
            node = nxt
        node[parts[-1]] = value
    return raw


def read_utf8(path, what: str = "file") -> str:
    """The text of a UTF-8 file; another encoding (or binary data) is a one-line UserError naming the
    first bad byte and its line."""
    path = os.fspath(path)
    refuse_binary(path, what)                   # a recording given as the config: say so
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise UserError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise UserError(f"{what} {path} is not UTF-8 text (byte 0x{data[exc.start]:02x} on line {line}); "
                        f"save it as UTF-8") from None


def read_yaml(path) -> dict:
    """Read a YAML mapping; errors become one-line UserErrors."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise UserError(f"config file not found: {path}")
    text = read_utf8(path, "config file")
    try:
        raw = yaml_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark else ""
        raise UserError(f"config file {path} is not valid YAML{where}") from None
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise UserError(f"config file {path} must hold a YAML mapping")
    return raw


def build(schema: dict, raw: dict | None = None, overrides=None) -> Section:
    """Validate raw (already parsed YAML) plus overrides against schema."""
    return Section(_merge(schema, apply_overrides(raw or {}, overrides), ""))


def defaults_doc(schema: dict, prefix: str = "") -> list[tuple[str, str, Any, str]]:
    """(key, kind, default, doc) rows, for the configuration reference (docs/reference/config.md)."""
    rows = []
    for name, spec in schema.items():
        if isinstance(spec, dict):
            rows += defaults_doc(spec, prefix + name + ".")
        else:
            kind = spec.kind + (f" ({'|'.join(map(str, spec.choices))})" if spec.choices else "")
            rows.append((prefix + name, kind, spec.default, spec.doc))
    return rows


# --------------------------------------------------------------------------------------------------
# File lookup
# --------------------------------------------------------------------------------------------------
REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def shipped_dir() -> str:
    """The directory of the shipped ``data/`` and ``configs/``: package data ``receiver/_share`` found through
    importlib.resources (in a checkout, links to the repository's own ``data/`` and ``configs/``; in an
    installed wheel, copies), so ``configs/default.yaml`` resolves from any directory."""
    from importlib.resources import files
    return str(files("receiver").joinpath("_share"))


def search_bases() -> list:
    """Fallback directories for relative file names after the current directory (and the referring
    file's directory): the repository root (for ``../shared/...`` next to a checkout) and the shipped
    data/configs."""
    return [REPO_ROOT, shipped_dir()]


def find_file(value):
    """A relative config/scenario file name that does not exist here -> the shipped one (``configs/...``,
    ``data/...``) when there is one; otherwise ``value`` unchanged."""
    v = os.fspath(value)
    if os.path.isabs(v) or os.path.exists(v):
        return value
    for base in search_bases():
        cand = os.path.join(base, v)
        if os.path.exists(cand):
            return os.path.normpath(cand)
    return value


def resolve_path(value: str, config_path=None) -> str:
    """A relative file name resolved against the referring config file's directory, then search_bases(); returned
    unchanged when empty, absolute, existing as given, or found nowhere."""
    if not value or os.path.isabs(value) or os.path.exists(value):
        return value
    bases = ([os.path.dirname(os.path.abspath(os.fspath(config_path)))] if config_path else []) + search_bases()
    for base in bases:
        cand = os.path.join(base, value)
        if os.path.exists(cand):
            return os.path.normpath(cand)
    return value


def dotted_get(mapping: dict, dotted: str, default=None):
    """The value at a dotted key (``"navigation.ephemeris"``) of nested dicts, or `default` when absent."""
    node = mapping
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return default
        node = node[part]
    return node
