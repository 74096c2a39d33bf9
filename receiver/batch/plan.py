"""Planning a batch: every run and simulated recording, with its content-hash key (the cache key).

Plan
    Every (variant x sweep point) x input x seed is one run.  Its receiver config is built and validated
    up front (a bad key fails the whole batch with a one-line UserError before anything runs).

Content hashes (cache keys)
    * recording key = sha256 of the fully resolved scenario (``time.seed`` included; files it names, such
      as a RINEX or trajectory CSV, replaced by their content signature) and the code version;
    * run key = sha256 of the fully resolved receiver config with ``output.path`` removed, its input file
      replaced by the recording key (simulated) or the file's content signature (recording), any other
      file it names (``navigation.ephemeris`` ...) by its content signature, and the code version.
    Content signature of a file: sha256 of its bytes up to 16 MiB; beyond, of its size and its first and
    last 4 MiB.  Code version (``code_version: auto``): sha256 of ``receiver.__version__`` and of every
    ``receiver/**/*.py`` except ``receiver/batch`` and ``receiver/leo``, and the numpy / scipy / numba
    versions; a fixed string pins it.  As the
    resolved config includes every default, a change of the receiver's config schema (a new key or default)
    changes the run keys even with a pinned code version.  ``--force`` re-runs the runs, not the simulations
    (recordings are content-addressed).
"""
from __future__ import annotations

import copy
import hashlib
import json
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

from ..config import apply_overrides, dotted_get, read_yaml, search_bases
from ..schema import build_receiver, used_plugins
from ..errors import UserError
from .config import Batch

SIG_FULL_BYTES = 16 << 20
SIG_PART_BYTES = 4 << 20
_SIG_CACHE: dict = {}


# ------------------------------------------------------------------------------------------ hashing
def _hash(obj) -> str:
    text = json.dumps(obj, sort_keys=True, default=repr, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def file_signature(path) -> str:
    """Content signature of a file (see the module docstring)."""
    path = os.path.abspath(os.fspath(path))
    st = os.stat(path)
    ck = (path, st.st_size, st.st_mtime_ns)
    if ck in _SIG_CACHE:
        return _SIG_CACHE[ck]
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        if st.st_size <= SIG_FULL_BYTES:
            h.update(fh.read())
        else:
            h.update(str(st.st_size).encode())
            h.update(fh.read(SIG_PART_BYTES))
            fh.seek(st.st_size - SIG_PART_BYTES)
            h.update(fh.read(SIG_PART_BYTES))
    sig = f"file:{st.st_size}:{h.hexdigest()[:24]}"
    _SIG_CACHE[ck] = sig
    return sig


def code_fingerprint(setting: str = "auto") -> str:
    """Code identity used in the hashes ('auto': the receiver sources, see the module docstring)."""
    if setting != "auto":
        return f"fixed:{setting}"
    import numba
    import numpy as np
    import scipy

    from .. import __version__
    pkg = Path(__file__).resolve().parents[1]
    h = hashlib.sha256(__version__.encode())
    # the numeric libraries change results too (FFT, linear algebra, numba's float contraction)
    h.update(f"numpy {np.__version__} scipy {scipy.__version__} numba {numba.__version__}".encode())
    for p in sorted(pkg.rglob("*.py")):
        rel = p.relative_to(pkg).as_posix()
        if rel.split("/")[0] in ("batch", "leo") or "__pycache__" in rel:
            continue
        h.update(rel.encode())
        h.update(p.read_bytes())
    return f"auto:{__version__}:{h.hexdigest()[:20]}"


def _plugin_fingerprints(cfg) -> list:
    """Name, version and source hash of each plugin the receiver config uses (part of the run's cache key:
    a changed plugin runs again)."""
    import inspect
    out = []
    for u in used_plugins(cfg):
        mod = sys.modules.get(u["class"].rsplit(".", 1)[0])
        try:
            src = hashlib.sha256(Path(inspect.getsourcefile(mod)).read_bytes()).hexdigest()[:20]
        except (TypeError, OSError):
            src = ""
        out.append({"name": u["name"], "version": u["version"], "class": u["class"], "source": src})
    return out


def _walk_strings(d: dict, fn, prefix=""):
    """Replace every string leaf v of a nested dict by fn(dotted_key, v) (a new dict)."""
    out = {}
    for k, v in d.items():
        key = prefix + k
        if isinstance(v, dict):
            out[k] = _walk_strings(v, fn, key + ".")
        elif isinstance(v, str):
            out[k] = fn(key, v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _pathlike(v: str) -> bool:
    return ("/" in v or "." in v) and len(v) < 4096


# ------------------------------------------------------------------------------------------ plan
@dataclass
class RecordingTask:
    """One simulated recording of the plan: its content-hash key, input name, seed, resolved scenario and
    output paths (keys if, truth, yaml, nav, meta)."""
    key: str
    input: str
    seed: int
    scenario: dict                  # resolved scenario, files as absolute paths
    paths: dict                     # if, truth, yaml, nav, meta

    def available(self) -> bool:
        """Whether the recording is already on disk (its meta, IF, truth and nav files all exist)."""
        return all(os.path.exists(self.paths[k]) for k in ("meta", "if", "truth", "nav"))


@dataclass
class RunTask:
    """One receiver run of the plan: its content-hash key (the cache key), variant label, input, validated
    config, output paths (h5, json) and what its evaluation needs (truth file, reference position)."""
    key: str
    variant: str                    # label (name + sweep point)
    variant_name: str
    input: str
    kind: str                       # scenario | recording
    seed: int | None
    config: dict                    # validated receiver config (raw dict), output.path = h5
    h5: str
    json: str
    truth: str | None
    reference_llh: list | None
    recording: str | None           # recording key
    set_values: dict = field(default_factory=dict)
    carrier_settle_s: float = 1.0


@dataclass
class Plan:
    """The planned batch: the runs (RunTask), the recordings to simulate (key -> RecordingTask) and the code
    version that entered the keys."""
    batch: Batch
    runs: list
    recordings: dict                # key -> RecordingTask
    code: str


def _recording_paths(rec_dir: str, key: str) -> dict:
    stem = os.path.join(rec_dir, key)
    return {"if": stem + ".bin", "truth": stem + ".truth.h5", "yaml": stem + ".yaml", "nav": stem + ".nav",
            "meta": stem + ".json"}


def _scenario_files(sc: dict):
    """(scenario with file leaves as absolute paths, scenario with file leaves as signatures)."""
    from ..sim.scenario import resolve_path

    def resolved(_k, v):
        if not _pathlike(v):
            return v
        try:
            p = resolve_path(v)
        except UserError:
            return v
        return p if os.path.isfile(p) else v

    absolute = _walk_strings(sc, resolved)
    signed = _walk_strings(absolute, lambda k, v: file_signature(v) if os.path.isabs(v) and os.path.isfile(v)
                           else v)
    return absolute, signed


def _receiver_file(v: str, base_dir: str) -> str | None:
    """An existing file named by a receiver config string (cwd, batch dir, repo root), else None."""
    if not _pathlike(v):
        return None
    p = os.path.expanduser(v)
    cands = [p] if os.path.isabs(p) else [os.path.join(b, p) for b in (os.getcwd(), base_dir, *search_bases())]
    for c in cands:
        if os.path.isfile(c):
            return os.path.abspath(c)
    return None


def _deep_merge(a: dict, b: dict) -> dict:
    out = copy.deepcopy(a)
    for k, v in (b or {}).items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def make_plan(batch: Batch) -> Plan:
    """Expand the batch into runs and the simulated recordings they need (validating every config)."""
    from ..sim.scenario import load_scenario
    b = batch
    code = code_fingerprint(b.cfg.code_version)
    runs_dir = os.path.join(b.output_dir, "runs")
    recordings: dict = {}
    layers: dict = {}
    # input side: (input, seed) -> (receiver overrides, recording key or None, identity overrides for hashing)
    points = []
    for inp in b.inputs:
        if inp.kind == "scenario":
            seeds = inp.seeds if inp.seeds is not None else b.cfg.seeds
            base_sc = load_scenario(inp.scenario, inp.scenario_set)
            for seed in (seeds if seeds else [base_sc.time.seed]):
                sc = load_scenario(inp.scenario, list(inp.scenario_set) + [("time.seed", int(seed))])
                absolute, signed = _scenario_files(sc.to_dict())
                key = _hash({"scenario": signed, "code": code})
                paths = _recording_paths(b.recordings_dir, key)
                recordings[key] = RecordingTask(key=key, input=inp.name, seed=int(seed), scenario=absolute,
                                                paths=paths)
                fe, tm = sc.frontend, sc.time
                ov = [("input.path", paths["if"]), ("input.format", fe.format),
                      ("input.sample_rate_hz", fe.sample_rate_hz), ("input.if_hz", fe.if_hz),
                      ("input.start_gps_week", tm.gps_week), ("input.start_gps_tow_s", tm.tow_s)]
                if inp.assisted:
                    ov.append(("navigation.ephemeris", paths["nav"]))
                ident = {paths["if"]: f"sim:{key}", paths["nav"]: f"simnav:{key}"}
                points.append((inp, int(seed), None, ov, key, ident, paths["truth"]))
        else:
            ov = [("input.path", inp.recording)]
            points.append((inp, None, inp.config, ov, None, {}, inp.truth))
    runs = []
    for var in b.variants:
        base_path = var.config or b.base_config
        if base_path not in layers:
            layers[base_path] = read_yaml(base_path) if base_path else {}
        for inp, seed, inp_cfg, inp_ov, rec_key, ident, truth in points:
            raw = apply_overrides(layers[base_path], b.batch_set)
            if inp_cfg:
                if inp_cfg not in layers:
                    layers[inp_cfg] = read_yaml(inp_cfg)
                raw = _deep_merge(raw, layers[inp_cfg])
            raw = apply_overrides(raw, inp_ov)
            raw = apply_overrides(raw, inp.receiver_set)
            raw = apply_overrides(raw, var.overrides)
            raw = apply_overrides(raw, [("output.path", None)])
            where = f"variant '{var.label}', input '{inp.name}'"
            try:
                built = build_receiver(raw)
                plugins = _plugin_fingerprints(built)
                cfg = built.to_dict()
            except UserError as exc:
                raise UserError(f"{where}: {exc}") from None
            cfg = _walk_strings(cfg, lambda k, v: (_receiver_file(v, b.base_dir) or v)
                                if k != "output.path" else v)
            hashed = _walk_strings(cfg, lambda k, v: ident.get(v) or (file_signature(v) if os.path.isabs(v)
                                                                     and os.path.isfile(v) else v))
            key = _hash({"config": hashed, "code": code, **({"plugins": plugins} if plugins else {})})
            h5 = os.path.join(runs_dir, key + ".h5")
            cfg = apply_overrides(cfg, [("output.path", h5)])
            runs.append(RunTask(
                key=key, variant=var.label, variant_name=var.name, input=inp.name, kind=inp.kind, seed=seed,
                config=cfg, h5=h5, json=os.path.join(runs_dir, key + ".json"), truth=truth,
                reference_llh=inp.reference_llh, recording=rec_key,
                set_values={k: dotted_get(cfg, k) for k in b.set_keys},
                carrier_settle_s=b.cfg.metrics.carrier_settle_s))
    keys = [r.key for r in runs]
    if len(set(keys)) != len(keys):
        dup = next(r for r in runs if keys.count(r.key) > 1)
        twins = [f"{r.variant}/{r.input}/{r.seed}" for r in runs if r.key == dup.key]
        raise UserError(f"runs {' and '.join(twins)} have identical configs and inputs (duplicate variants?)")
    used = {r.recording for r in runs if r.recording}
    return Plan(batch=b, runs=runs, recordings={k: v for k, v in recordings.items() if k in used}, code=code)
