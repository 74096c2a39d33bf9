"""The validation matrix: rows x seeds x receiver variants, cached, as a table (``make validate``).

``configs/validate/matrix.yaml``::

    defaults:                       # merged into every row (mappings key by key)
      seeds: 3
      mode: assisted                # assisted (navigation.ephemeris = the simulator's RINEX) | unassisted
      variants: [scalar]            # scalar | vector (vector.enabled=true)
      scenario: {duration_s: 20}    # receiver/validate/scenarios.py
      recording: {format: int8_iq}  # receiver/validate/postprocess.py (+ sample_rate_hz)
      expect: {ttff_s: 10, availability: 0.95, rms_3d_m: 5, max_err_meas_m: 30, max_recovery_s: 10}
    rows:
      - {name: ..., label: ..., scenario: {...}, recording: {...}, expect: {...}}

Rows run seed by seed (every row's seed 0, then seed 1 ...; ``priority: 0`` rows first in each round), so
a partial run covers every row.  Seed k of a row: scenarios.seed_scenario (place and time of day rotated
by k, heading), noise seed
1000 * k + the row's index.  A (row, seed, variant) passes when every ``expect`` bound holds (upper bounds,
but ``availability``, a lower bound); a missing first fix fails all.

Cache: out/validate/results/<key>.json, key = hash of the seeded scenario and recording, mode, variant,
receiver config and extra sets, the simulator binary and the receiver's sources (receiver/**.py outside
receiver/validate): a change to the receiver re-runs everything, a re-run of the table costs nothing.
"""
from __future__ import annotations

import hashlib
import json
import math
import logging
import shutil
import subprocess
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import yaml

from . import RECEIVER_CONFIG, make_case, run_receiver, score_run
from .gpssdrsim import DEFAULT_CACHE, ROOT, simulator, simulator_id
from .scenarios import seed_scenario

MATRIX = ROOT / "configs" / "validate" / "matrix.yaml"
DOC = ROOT / "docs" / "validation.md"
BEGIN, END = "<!-- BEGIN generated: validation table -->", "<!-- END generated: validation table -->"
LOWER_BOUNDS = ("availability",)
log = logging.getLogger("receiver.validate")


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in (b or {}).items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def load_matrix(path=MATRIX) -> list[dict]:
    """The rows of a matrix file, defaults merged in."""
    doc = yaml.safe_load(Path(path).read_text())
    d = doc.get("defaults") or {}
    rows = []
    for i, r in enumerate(doc["rows"]):
        row = _merge(d, r)
        row["index"] = i
        rows.append(row)
    names = [r["name"] for r in rows]
    if len(set(names)) != len(names):
        raise ValueError("matrix row names must be unique")
    return rows


def receiver_hash() -> str:
    """Hash of the receiver's sources (receiver/**.py outside receiver/validate)."""
    h = hashlib.sha256()
    for p in sorted((ROOT / "receiver").rglob("*.py")):
        if "validate" in p.relative_to(ROOT / "receiver").parts:
            continue
        h.update(str(p.relative_to(ROOT)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def _code_only(path) -> str:
    """The module's syntax tree without docstrings (comments and docs do not change the recordings)."""
    import ast
    tree = ast.parse(Path(path).read_text())
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr) and \
                isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str):
            node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree)


def generator_hash() -> str:
    """Hash of the case generator's code (scenarios, GPS-SDR-SIM driver, post-processing): part of the key."""
    h = hashlib.sha256()
    for name in ("scenarios.py", "gpssdrsim.py", "postprocess.py"):
        h.update(_code_only(Path(__file__).parent / name).encode())
    return h.hexdigest()[:16]


def seeded(row: dict, k: int) -> tuple[dict, dict]:
    """(scenario, recording) of seed k of a matrix row."""
    scn = seed_scenario(row.get("scenario") or {}, k)
    rec = dict(row.get("recording") or {})
    rec["seed"] = 1000 * k + int(row["index"]) + int(rec.get("seed", 0))
    return scn, rec


def job_key(row, k, variant, sim_id, rx_id) -> str:
    """The cache key of one (row, seed, variant) run (see the module docstring)."""
    scn, rec = seeded(row, k)
    blob = json.dumps({"scenario": scn, "recording": rec, "mode": row.get("mode", "assisted"),
                       "variant": variant, "sets": row.get("sets") or [],
                       "config": Path(row.get("config") or RECEIVER_CONFIG).read_text(),
                       "sim": sim_id, "rx": rx_id, "gen": generator_hash()}, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def check(metrics: dict, expect: dict) -> list[str]:
    """The ``expect`` bounds a run misses (empty: it passes)."""
    if not math.isfinite(metrics.get("ttff_s", math.nan)):
        return ["no fix"]
    bad = []
    for k, bound in (expect or {}).items():
        v = metrics.get(k, math.nan)
        if k == "max_recovery_s" and not metrics.get("recovery_s"):
            continue
        ok = (v >= bound) if k in LOWER_BOUNDS else (v <= bound)
        if not (isinstance(v, (int, float)) and ok):
            bad.append(k)
    return bad


def _run_job(row, k, variants, keys, work, results):
    """Make one seeded case and run its variants; writes results/<key>.json per variant."""
    scn, rec = seeded(row, k)
    d = Path(work) / f"{row['name']}_{k}"
    t0 = time.time()
    case = make_case(scn, rec, d, name="case")
    t_make = time.time() - t0
    out = {}
    try:
        for v, key in zip(variants, keys):
            t1 = time.time()
            h5 = d / f"run_{v}.h5"
            try:
                run_receiver(case, h5, assisted=row.get("mode", "assisted") == "assisted",
                             vector=v == "vector", config=row.get("config"), sets=row.get("sets") or [],
                             threads=1, timeout=float(row.get("timeout_s", 1800)))
                m = score_run(h5, case)
                m["error"] = None
            except Exception as e:       # a crash is a result too
                m = {"error": str(e).splitlines()[-1][:200] if str(e) else type(e).__name__,
                     "ttff_s": math.nan}
            m.update({"row": row["name"], "seed": k, "variant": v, "place": scn["place"], "start": scn["start"],
                      "t_make_s": t_make, "t_run_s": time.time() - t1, "failed": check(m, row.get("expect"))})
            if h5.is_file():            # kept with its truth for --rescore
                shutil.move(str(h5), Path(results) / f"{key}.h5")
                shutil.copy(case.truth_path, Path(results) / f"{key}.truth.npy")
                case_k = type(case)(**{**case.__dict__, "truth_path": str(Path(results) / f"{key}.truth.npy")})
                case_k.save(Path(results) / f"{key}.case.json")
            (Path(results) / f"{key}.json").write_text(json.dumps(m, default=float))
            out[v] = m
    finally:
        shutil.rmtree(d, ignore_errors=True)
    return out


def _rescore(results, key, m, row):
    from . import Case
    h5, cj = results / f"{key}.h5", results / f"{key}.case.json"
    if h5.is_file() and cj.is_file():
        keep = {k: m[k] for k in ("row", "seed", "variant", "place", "start", "t_make_s", "t_run_s", "error")
                if k in m}
        m = {**score_run(h5, Case.load(cj)), **keep}
    m["failed"] = check(m, row.get("expect"))
    return m


def run_matrix(rows, jobs=2, cache_dir=DEFAULT_CACHE, only=None, rescore=False, dry_run=False) -> dict:
    """Run (or read from the cache) every (row, seed, variant); returns {(row, seed, variant): metrics}.
    ``rescore``: recompute the cached metrics from the kept run files; ``dry_run``: run nothing."""
    exe = simulator(cache_dir)
    sim_id, rx_id = simulator_id(exe), receiver_hash()
    results = Path(cache_dir) / "results"
    work = Path(cache_dir) / "work"
    results.mkdir(parents=True, exist_ok=True)
    out, todo = {}, []
    for row in rows:
        if only and not any(s in row["name"] for s in only):
            continue
        variants = list(row.get("variants") or ["scalar"])
        for k in range(int(row.get("seeds", 3))):
            keys = [job_key(row, k, v, sim_id, rx_id) for v in variants]
            missing = []
            for v, key in zip(variants, keys):
                f = results / f"{key}.json"
                if f.is_file():
                    m = json.loads(f.read_text())
                    out[(row["name"], k, v)] = _rescore(results, key, m, row) if rescore else m
                else:
                    missing.append((v, key))
            if missing:
                todo.append((row, k, [m[0] for m in missing], [m[1] for m in missing]))
    # every row's first seed first, then the second ...; rows with priority 0 first within a round
    todo.sort(key=lambda t: (t[1], int(t[0].get("priority", 1)), t[0]["index"]))
    log.info(f"validate: {len(out)} cached, {sum(len(t[2]) for t in todo)} to run ({len(todo)} recordings), "
        f"{jobs} at a time")
    if todo and not dry_run:
        with ProcessPoolExecutor(max_workers=max(1, jobs)) as ex:
            futs = {ex.submit(_run_job, row, k, vs, ks, work, results): (row["name"], k) for row, k, vs, ks in todo}
            for n, f in enumerate(as_completed(futs), 1):
                name, k = futs[f]
                try:
                    res = f.result()
                except Exception as e:
                    log.info(f"  [{n}/{len(todo)}] {name} seed {k}: case failed: {e}")
                    continue
                for v, m in res.items():
                    out[(name, k, v)] = m
                    log.info(f"  [{n}/{len(todo)}] {name} seed {k} {v}: ttff {m.get('ttff_s', math.nan):.1f} s, "
                        f"rms {m.get('rms_3d_m', math.nan):.2f} m, {'pass' if not m['failed'] else m['failed']}"
                        f"{' ERROR ' + m['error'] if m.get('error') else ''}")
    return out


def _fmt(v, f="{:.1f}"):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float) and math.isinf(v):
        return "never"
    return f.format(v)


def _agg(ms, key, fn):
    vals = [m.get(key, math.nan) for m in ms]
    vals = [v for v in vals if isinstance(v, (int, float)) and not math.isnan(v)]
    return fn(vals) if vals else math.nan


def describe(row) -> tuple[str, str, str, str]:
    """(dynamics, MS/s, format, C/N0) of a row for the table."""
    rec = row.get("recording") or {}
    scn = row.get("scenario") or {}
    fs = float(rec.get("sample_rate_hz", 2.6e6)) / 1e6
    fmt = rec.get("format", "int8_iq").replace("_iq", "").replace("_real", " real")
    return (scn.get("dynamics", "?"), f"{fs:g}", fmt,
            f"{rec.get('cn0_dbhz', 45):g}")


def table(rows, res) -> str:
    """The Markdown table: one line per (row, variant), the seeds summarised."""
    head = ("| row | mode | dynamics | MS/s | format | C/N0 | impairment | variant | fixed | TTFF s (max) | "
            "avail. (min) | 3D RMS m (med / max) | worst m | non-coast max m | recovery s (max) | rx C/N0 | pass |")
    lines = [head, "|" + "|".join(["---"] * (head.count("|") - 1)) + "|"]
    for row in rows:
        for v in row.get("variants") or ["scalar"]:
            ms = [res[(row["name"], k, v)] for k in range(int(row.get("seeds", 3))) if (row["name"], k, v) in res]
            dyn, fs, fmt, cn0 = describe(row)
            if not ms:
                lines.append("| " + " | ".join([row["name"], "A" if row.get("mode", "assisted") == "assisted" else "U",
                                                 dyn, fs, fmt, cn0, row.get("label", ""), v, "not run"]
                                                + [""] * 8) + " |")
                continue
            n = len(ms)
            fixed = sum(1 for m in ms if math.isfinite(m.get("ttff_s", math.nan)))
            errs = sorted({m["error"] for m in ms if m.get("error")})
            passed = sum(1 for m in ms if not m["failed"])
            rec = _agg(ms, "max_recovery_s", max) if row.get("recording", {}).get("outages") else math.nan
            lines.append("| " + " | ".join([
                row["name"], "A" if row.get("mode", "assisted") == "assisted" else "U", dyn, fs, fmt, cn0,
                row.get("label", ""), v, f"{fixed}/{n}", _fmt(_agg(ms, "ttff_s", max)),
                _fmt(_agg(ms, "availability", min), "{:.2f}"),
                f"{_fmt(_agg(ms, 'rms_3d_m', lambda x: sorted(x)[len(x) // 2]), '{:.2f}')} / "
                f"{_fmt(_agg(ms, 'rms_3d_m', max), '{:.2f}')}",
                _fmt(_agg(ms, "max_err_m", max)), _fmt(_agg(ms, "max_err_meas_m", max)), _fmt(rec),
                _fmt(_agg(ms, "cn0_dbhz", lambda x: sorted(x)[len(x) // 2])),
                f"{passed}/{n}" + (" (crash: " + "; ".join(errs) + ")" if errs else "")]) + " |")
    return "\n".join(lines)


def write_doc(text: str, path=DOC, header: str = "") -> None:
    """Put the table into the generated section of docs/validation.md (replacing the previous one)."""
    path = Path(path)
    body = path.read_text() if path.is_file() else ""
    block = f"{BEGIN}\n{header}{text}\n{END}"
    if BEGIN in body and END in body:
        body = body[:body.index(BEGIN)] + block + body[body.index(END) + len(END):]
    else:
        body = body.rstrip() + "\n\n" + block + "\n"
    path.write_text(body)


def doc_header(cache_dir=DEFAULT_CACHE) -> str:
    """The line above the table: receiver sources, git commit, simulator binary, date."""
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    return (f"Receiver sources {receiver_hash()} (git {commit}), GPS-SDR-SIM binary "
            f"{simulator_id(simulator(cache_dir))}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.\n\n")
