"""The batch YAML: schema, validation and expansion of variants x sweeps.

A batch file is validated with the project's config machinery (:data:`BATCH_SCHEMA`; unknown keys and bad
values raise UserError naming the key).  The list entries (``variants``, ``inputs``) are checked here by
hand with the same one-line errors.  Example (every key documented in :data:`BATCH_SCHEMA`)::

    name: pll_bandwidth
    output_dir: out/batch/pll_bandwidth     # run files, summary.{csv,h5}, groups.csv
    base_config: null                        # receiver YAML under every run (null: the defaults)
    set: {navigation.rate_hz: 2}             # receiver overrides for every run
    variants:                                # named receiver configurations
      - {name: narrow, set: {tracking.pll_bw_hz: 10}}
      - {name: wide,   set: {tracking.pll_bw_hz: 25}}
      - {name: vdll, config: configs/vector_tokyo.yaml, set: [vector.variant=cv]}
    sweep: {tracking.dll_bw_hz: [1, 2]}      # every variant at every combination (cartesian product)
    inputs:
      - name: static                         # simulated on the fly (cached by content hash), with truth
        scenario: configs/scenarios/static_default.yaml
        set: {time.duration_s: 10}           # scenario overrides
        assisted: true                       # RINEX nav of the simulated ephemeris + start time
      - name: tokyo                          # a recording: its receiver input section from `config`
        recording: ../shared/data/gpssim_static_tokyo.bin
        config: configs/gpssim_static_tokyo.yaml
        receiver_set: {navigation.ephemeris: ../shared/data/brdc0010.22n}
        reference_llh: [35.681298, 139.766247, 10.0]   # static reference position (no truth file)
    seeds: [1, 2, 3]                         # simulator seeds (time.seed) of every scenario input

Paths in the batch file (base_config, variant/input config, scenario, recording, truth) are looked up
relative to the batch file's directory, then the current directory, then the repository root.  The
receiver keys inside ``set``/``receiver_set`` follow the receiver's rule (current directory), with the
batch file's directory and the repository root as fall-backs; ``output_dir`` / ``recordings_dir`` are
relative to the current directory.

Layering of one run's receiver config (later wins): base_config (or the variant's ``config``) ->
batch ``set`` -> input (recording ``config``, or the simulator's input section and, when assisted,
``navigation.ephemeris``) -> input ``receiver_set`` -> variant ``set`` -> sweep values ->
``output.path`` (the run file).
"""
from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import P, Section, build, find_file, parse_override, read_yaml, search_bases
from ..errors import UserError
from ..suggest import did_you_mean

REPO_ROOT = Path(__file__).resolve().parents[2]

BATCH_SCHEMA = {
    "name": P(None, "str", "batch name (empty: the batch file's stem)", nullable=True),
    "output_dir": P(None, "str", "directory of the run files (runs/<hash>.h5 + .json), summary.csv, summary.h5, "
                                 "groups.csv (empty: out/batch/<name>)", nullable=True),
    "recordings_dir": P(None, "str", "cache of simulated recordings, named by content hash; may be shared by "
                                     "batches (empty: <output_dir>/recordings)", nullable=True),
    "keep_recordings": P(True, "bool", "keep simulated IF files after their runs (false: delete each IF file "
                                       "once its last run is done; truth and nav files are kept)"),
    "base_config": P(None, "str", "receiver config YAML under every run (empty: the receiver defaults)",
                     nullable=True),
    "set": P({}, "any", "receiver overrides for every run: {dotted.key: value} or a list of 'key=value'"),
    "variants": P([{"name": "default"}], "list", "receiver variants: list of {name, config (receiver YAML, "
                                                 "replaces base_config), set (overrides), sweep}"),
    "sweep": P({}, "dict", "{dotted.key: [values, ...]}: every variant runs at every combination (cartesian "
                           "product); the run's variant label gets '[key=value,...]'"),
    "inputs": P(None, "list", "inputs: list of {name, scenario | recording, ...} (see receiver/batch/config.py)",
                required=True),
    "seeds": P(None, "list_int", "simulator seeds (time.seed) for every scenario input (empty: the scenario's "
                                 "own seed); recordings run once", nullable=True, lo=0),
    "jobs": P(None, "int", "runs in parallel in the local process pool (empty: number of cores)",
              nullable=True, lo=1),
    "scheduler": P(None, "str", "Dask distributed scheduler: tcp://HOST:PORT, or 'local' for a LocalCluster of "
                                "`jobs` workers (empty: the local process pool)", nullable=True),
    "code_version": P("auto", "str", "code identity in the run hashes: 'auto' (hash of the receiver's Python "
                                     "sources and version) or any fixed string"),
    "retry_failed": P(False, "bool", "run failed runs again even if nothing changed"),
    "metrics": {
        "carrier_settle_s": P(1.0, "float", "carrier phase error scored from this long after a channel's first "
                                            "PLL lock", lo=0.0),
        "ci": P(0.95, "float", "confidence level of the grouped intervals (Student t on the mean)",
                lo=0.5, hi=0.999),
    },
}

_VARIANT_KEYS = {"name", "config", "set", "sweep"}
_INPUT_KEYS = {"name", "scenario", "recording", "set", "receiver_set", "config", "truth", "reference_llh",
               "assisted", "seeds"}


@dataclass
class Variant:
    """One receiver configuration point (a batch variant at one sweep combination)."""
    label: str                      # variant name + '[key=value,...]' of its sweep point
    name: str                       # the variant's name
    config: str | None              # receiver YAML replacing base_config
    overrides: list                 # (key, value) pairs: variant set, then sweep values
    sweep: dict                     # key -> value of this sweep point


@dataclass
class InputSpec:
    """One input of a batch: a scenario (simulated per seed, with its ``set`` overrides and ``assisted``) or a
    recording (its receiver ``config``, ``truth`` or ``reference_llh``); paths resolved to absolute ones."""
    name: str
    kind: str                       # "scenario" | "recording"
    scenario: Any = None            # path (absolute) or mapping
    scenario_set: list = field(default_factory=list)
    recording: str | None = None
    config: str | None = None       # receiver YAML for a recording (whole file applied)
    receiver_set: list = field(default_factory=list)
    truth: str | None = None
    reference_llh: list | None = None
    assisted: bool = False
    seeds: list | None = None


@dataclass
class Batch:
    """A loaded batch file (:func:`load_batch`): the validated config, resolved paths and directories, the
    variants expanded over their sweep points and the inputs."""
    cfg: Section
    path: str | None                # the batch file (None: built from a mapping)
    name: str
    base_dir: str                   # directory of the batch file (relative lookups)
    output_dir: str
    recordings_dir: str
    variants: list                  # [Variant]
    inputs: list                    # [InputSpec]
    set_keys: list                  # dotted keys set by variants / sweeps (summary columns)
    base_config: str | None = None  # resolved base_config
    batch_set: list = field(default_factory=list)   # (key, value) of the batch-level `set`
    raw: dict = field(default_factory=dict)


def resolve(path: str, base_dir: str, what: str) -> str:
    """A batch-file path: absolute; else the batch file's directory, the current directory, the repo root."""
    p = os.path.expanduser(str(path))
    if os.path.isabs(p):
        if os.path.exists(p):
            return p
        raise UserError(f"{what} not found: {path}")
    for base in (base_dir, os.getcwd(), *search_bases()):
        cand = os.path.normpath(os.path.join(base, p))
        if os.path.exists(cand):
            return cand
    raise UserError(f"{what} not found: {path} (looked in {base_dir}, the current directory and {REPO_ROOT})")


def overrides_list(value, key: str) -> list:
    """A `set` value -> [(dotted.key, value)]: mapping {k: v}, list of 'k=v' strings, or a 'k=v' string."""
    if value is None:
        return []
    if isinstance(value, dict):
        out = []
        for k, v in value.items():
            if not isinstance(k, str) or not k:
                raise UserError(f"config key '{key}' must map dotted receiver keys to values")
            out.append((k, v))
        return out
    if isinstance(value, str):
        value = [value]
    if isinstance(value, list):
        out = []
        for i, item in enumerate(value):
            if isinstance(item, str):
                out.append(parse_override(item))
            elif isinstance(item, dict) and len(item) == 1:
                out.append(next(iter(item.items())))
            else:
                raise UserError(f"config key '{key}[{i}]' must be 'dotted.key=value'")
        return out
    raise UserError(f"config key '{key}' must be a mapping {{dotted.key: value}} or a list of 'key=value'")


def _label_value(v) -> str:
    if isinstance(v, float) and v.is_integer():
        return str(int(v)) if abs(v) < 1e15 else repr(v)
    return str(v)


def _sweep_points(sweep: dict, key: str) -> list[dict]:
    if not isinstance(sweep, dict):
        raise UserError(f"config key '{key}' must be a mapping {{dotted.key: [values]}}")
    keys, values = [], []
    for k, v in sweep.items():
        if not isinstance(v, list) or not v:
            raise UserError(f"config key '{key}.{k}' must be a non-empty list of values")
        keys.append(k)
        values.append(v)
    return [dict(zip(keys, combo)) for combo in itertools.product(*values)] if keys else [{}]


def _variants(raw_variants, global_sweep: dict, base_dir: str) -> tuple[list, list]:
    if not raw_variants:
        raise UserError("config key 'variants' must hold at least one variant")
    out, set_keys = [], []
    names = set()
    for i, v in enumerate(raw_variants):
        key = f"variants[{i}]"
        if isinstance(v, str):
            v = {"name": v}
        if not isinstance(v, dict):
            raise UserError(f"config key '{key}' must be a mapping {{name, config, set, sweep}}")
        unknown = sorted(set(v) - _VARIANT_KEYS)
        if unknown:
            raise UserError(f"unknown config key '{key}.{unknown[0]}'" + did_you_mean(unknown[0], _VARIANT_KEYS))
        name = v.get("name")
        if not isinstance(name, str) or not name:
            raise UserError(f"config key '{key}.name' is required (a non-empty string)")
        if name in names:
            raise UserError(f"config key '{key}.name': duplicate variant name '{name}'")
        names.add(name)
        cfg = v.get("config")
        if cfg is not None:
            if not isinstance(cfg, str):
                raise UserError(f"config key '{key}.config' must be a path")
            cfg = resolve(cfg, base_dir, f"{key}.config")
        sets = overrides_list(v.get("set"), f"{key}.set")
        sweep = {**global_sweep, **(v.get("sweep") or {})}
        for k, _ in sets:
            if k not in set_keys:
                set_keys.append(k)
        for k in sweep:
            if k not in set_keys:
                set_keys.append(k)
        for point in _sweep_points(sweep, f"{key}.sweep" if v.get("sweep") else "sweep"):
            label = name
            if point:
                label += "[" + ",".join(f"{k}={_label_value(x)}" for k, x in point.items()) + "]"
            out.append(Variant(label=label, name=name, config=cfg, overrides=sets + list(point.items()),
                               sweep=dict(point)))
    return out, set_keys


def _inputs(raw_inputs, base_dir: str) -> list:
    if not raw_inputs:
        raise UserError("config key 'inputs' must hold at least one input")
    out, names = [], set()
    for i, item in enumerate(raw_inputs):
        key = f"inputs[{i}]"
        if not isinstance(item, dict):
            raise UserError(f"config key '{key}' must be a mapping with 'scenario' or 'recording'")
        unknown = sorted(set(item) - _INPUT_KEYS)
        if unknown:
            raise UserError(f"unknown config key '{key}.{unknown[0]}'" + did_you_mean(unknown[0], _INPUT_KEYS))
        has_sc, has_rec = item.get("scenario") is not None, item.get("recording") is not None
        if has_sc == has_rec:
            raise UserError(f"config key '{key}' needs exactly one of 'scenario' or 'recording'")
        spec = InputSpec(name="", kind="scenario" if has_sc else "recording")
        if has_sc:
            sc = item["scenario"]
            if isinstance(sc, str):
                spec.scenario = resolve(sc, base_dir, f"{key}.scenario")
                default_name = Path(sc).stem
            elif isinstance(sc, dict):
                spec.scenario = sc
                default_name = f"scenario{i}"
            else:
                raise UserError(f"config key '{key}.scenario' must be a path or a mapping")
            spec.scenario_set = overrides_list(item.get("set"), f"{key}.set")
            for k in ("config", "truth", "reference_llh"):
                if item.get(k) is not None:
                    raise UserError(f"config key '{key}.{k}' applies to recordings only")
            a = item.get("assisted", False)
            if not isinstance(a, bool):
                raise UserError(f"config key '{key}.assisted' must be of type bool, got {a!r}")
            spec.assisted = a
            seeds = item.get("seeds")
            if seeds is not None:
                if isinstance(seeds, int) and not isinstance(seeds, bool):
                    seeds = [seeds]
                if not (isinstance(seeds, list) and seeds and
                        all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds)):
                    raise UserError(f"config key '{key}.seeds' must be a list of non-negative integers")
                spec.seeds = list(seeds)
        else:
            if not isinstance(item["recording"], str):
                raise UserError(f"config key '{key}.recording' must be a path")
            spec.recording = resolve(item["recording"], base_dir, f"{key}.recording")
            default_name = Path(item["recording"]).stem
            for k in ("set", "assisted", "seeds"):
                if item.get(k) is not None:
                    raise UserError(f"config key '{key}.{k}' applies to scenarios only "
                                    "(receiver overrides of a recording: receiver_set)")
            if item.get("config") is not None:
                spec.config = resolve(item["config"], base_dir, f"{key}.config")
            if item.get("truth") is not None:
                spec.truth = resolve(item["truth"], base_dir, f"{key}.truth")
            ref = item.get("reference_llh")
            if ref is not None:
                if not (isinstance(ref, list) and len(ref) == 3 and
                        all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in ref)):
                    raise UserError(f"config key '{key}.reference_llh' must be [lat_deg, lon_deg, height_m]")
                if spec.truth:
                    raise UserError(f"config key '{key}': give either truth or reference_llh")
                spec.reference_llh = [float(x) for x in ref]
        spec.receiver_set = overrides_list(item.get("receiver_set"), f"{key}.receiver_set")
        name = item.get("name", default_name)
        if not isinstance(name, str) or not name:
            raise UserError(f"config key '{key}.name' must be a non-empty string")
        if name in names:
            raise UserError(f"config key '{key}.name': duplicate input name '{name}'")
        names.add(name)
        spec.name = name
        out.append(spec)
    return out


def load_batch(source, overrides=()) -> Batch:
    """A batch from a YAML path or a mapping, plus ``--set``-style overrides of batch keys."""
    if isinstance(source, dict):
        raw, path, base_dir = source, None, os.getcwd()
        stem = "batch"
    else:
        path = os.path.abspath(os.fspath(find_file(source)))
        raw = read_yaml(path)
        base_dir = os.path.dirname(path)
        stem = Path(path).stem
    cfg = build(BATCH_SCHEMA, raw, overrides)
    name = cfg.name or stem
    out_dir = os.path.abspath(cfg.output_dir or os.path.join("out", "batch", name))
    rec_dir = os.path.abspath(cfg.recordings_dir) if cfg.recordings_dir else os.path.join(out_dir, "recordings")
    batch_set = overrides_list(cfg.set, "set")
    variants, set_keys = _variants(cfg.variants, dict(cfg.sweep or {}), base_dir)
    labels = [v.label for v in variants]
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if dup:
        raise UserError(f"variants: duplicate variant label '{dup[0]}'")
    inputs = _inputs(cfg.inputs, base_dir)
    base = resolve(cfg.base_config, base_dir, "base_config") if cfg.base_config else None
    return Batch(cfg=cfg, path=path, name=name, base_dir=base_dir, output_dir=out_dir, recordings_dir=rec_dir,
                 variants=variants, inputs=inputs, set_keys=set_keys, base_config=base, batch_set=batch_set,
                 raw=cfg.to_dict())
