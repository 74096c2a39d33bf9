"""Discovery of extensions: package entry points and ``module:Class`` names.

An extension is a class found either

* by name through an entry point of an installed distribution, in the group of its kind
  (``gnssrx.carrier_loops``, ``gnssrx.vector_filters``; ``[project.entry-points."gnssrx.carrier_loops"]
  fll_pll = "gnssrx_fll_pll:FllPll"`` in the plugin's pyproject.toml), or
* as ``module:Class`` written where the config names a variant (a module on the Python path).

The stage that uses a kind checks the class against its interface (receiver/tracking/carrier.py,
receiver/tracking/vector/__init__.py).  Every failure is one line (:class:`receiver.errors.UserError`):
a module that does not import, a missing class, a missing method, a bad parameter.  docs/plugins.md.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from importlib import metadata

from .config import P, _check
from .errors import UserError

#: kind -> (entry-point group, what the kind is called in messages)
KINDS = {
    "carrier_loop": ("gnssrx.carrier_loops", "carrier loop"),
    "vector_filter": ("gnssrx.vector_filters", "vector filter"),
}


@dataclass
class Found:
    """A class found for an extension name: where it came from and its version."""
    name: str           # as written in the config (an entry-point name or module:Class)
    cls: type
    origin: str         # "entry point <group> of <distribution>" or "module <module>"
    version: str | None


def is_reference(name) -> bool:
    """``module:Class`` (rather than a registered or entry-point name)."""
    return isinstance(name, str) and ":" in name


def entry_points(kind: str) -> dict:
    """name -> EntryPoint of the installed distributions, for one kind."""
    group = KINDS[kind][0]
    return {ep.name: ep for ep in metadata.entry_points(group=group)}


def _import(kind: str, name: str, module: str, attr: str):
    what = KINDS[kind][1]
    try:
        mod = importlib.import_module(module)
    except Exception as exc:  # noqa: BLE001 - any import failure of a plugin is the user's one-line error
        raise UserError(f"{what} plugin '{name}': cannot import module {module} "
                        f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    obj = mod
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise UserError(f"{what} plugin '{name}': module {module} has no {attr}") from None
    if not isinstance(obj, type):
        raise UserError(f"{what} plugin '{name}': {module}:{attr} is not a class")
    return obj


def find(kind: str, name: str) -> Found:
    """The class of extension ``name`` of ``kind`` (one-line UserError when absent or broken)."""
    what = KINDS[kind][1]
    if is_reference(name):
        module, _, attr = name.partition(":")
        if not module or not attr:
            raise UserError(f"{what} '{name}': write module:Class")
        cls = _import(kind, name, module, attr)
        version = getattr(cls, "version", None) or getattr(importlib.import_module(module), "__version__", None)
        return Found(name, cls, f"module {module}", version)
    eps = entry_points(kind)
    if name not in eps:
        return None
    ep = eps[name]
    module, _, attr = ep.value.partition(":")
    cls = _import(kind, name, module.strip(), attr.strip() or name)
    dist = getattr(ep, "dist", None)
    dname = dist.metadata["Name"] if dist is not None else "?"
    version = getattr(cls, "version", None) or (dist.version if dist is not None else None)
    return Found(name, cls, f"entry point {KINDS[kind][0]} of {dname}", version)


def installed(kind: str) -> list:
    """(name, Found or the one-line error text) of every entry point of ``kind``, sorted by name."""
    out = []
    for name in sorted(entry_points(kind)):
        try:
            out.append((name, find(kind, name)))
        except UserError as exc:
            out.append((name, str(exc)))
    return out


def check_params(pre: str, params, prefix: str = ""):
    """A plugin's PARAMS: a dict of receiver.config.P (nested dicts for sub-sections), defaults valid."""
    if not isinstance(params, dict):
        raise UserError(f"{pre}: PARAMS must be a dict of receiver.config.P, got {type(params).__name__}")
    for key, spec in params.items():
        if isinstance(spec, dict):
            check_params(pre, spec, prefix + key + ".")
            continue
        if not isinstance(spec, P):
            raise UserError(f"{pre}: parameter '{prefix}{key}' is not a receiver.config.P")
        if spec.kind not in ("float", "int", "bool", "str", "list_int", "list_float", "list", "dict", "any"):
            raise UserError(f"{pre}: parameter '{prefix}{key}' has unknown type {spec.kind!r}")
        if not spec.required:
            try:
                _check(f"{prefix}{key}", spec, spec.default)
            except UserError as exc:
                raise UserError(f"{pre}: the default of parameter {str(exc)[len('config key '):]}") from None
