"""Summary table of a batch (CSV + HDF5), grouped statistics, and the side-by-side comparison.

``summary.csv`` / ``summary.h5:/runs``
    One row per run: ``run_id`` (the run key), ``variant`` (label incl. sweep point), ``variant_name``,
    ``input``, ``kind`` (scenario | recording), ``seed`` (-1 for recordings), one column per receiver key set
    by a variant or a sweep (named by the dotted key, e.g. ``tracking.pll_bw_hz``), ``status`` (ok | failed),
    ``executed`` (run by the invocation that wrote the summary, else taken from the cache), the metrics of
    :mod:`receiver.batch.metrics`, ``error`` and ``run_file`` (relative to the output directory).
    ``summary.h5:/runs/config_yaml`` holds each run's full receiver config, so that ``compare --by`` can
    group by any receiver key.
``groups.csv`` / ``summary.h5:/groups``
    Per variant label: ``n_runs``, ``n_ok`` and, per metric, ``<metric>_mean``, ``<metric>_lo``,
    ``<metric>_hi`` - the mean over the variant's successful runs with a finite value and its confidence
    interval (level ``metrics.ci``, default 95 %): mean +/- t_{(1+ci)/2, n-1} s / sqrt(n) (Student t,
    s the sample standard deviation; NaN bounds when n < 2).
"""
from __future__ import annotations

import csv
import math
import os
import time

import numpy as np

from ..errors import UserError
from ..runfile.reader import open_h5
from .metrics import METRIC_KEYS

ID_COLUMNS = ("run_id", "variant", "variant_name", "input", "kind", "seed")
TAIL_COLUMNS = ("error", "run_file")
#: metrics shown in the comparison plot (when they have finite values)
PLOT_METRICS = ("ttff_s", "pos_3d_rms_m", "pos_h_rms_m", "pos_v_rms_m", "vel_3d_rms_mps",
                "carrier_phase_err_std_cyc", "loss_of_lock", "cn0_mean_dbhz", "realtime_factor")


# ------------------------------------------------------------------------------------------ rows
def summary_rows(plan, results: dict) -> list:
    """One dict per planned run (columns as in the module docstring; '_config' holds the config dict)."""
    rows = []
    for r in plan.runs:
        res = results.get(r.key) or {"status": "missing", "error": "not run", "metrics": {}}
        m = res.get("metrics") or {}
        row = {"run_id": r.key, "variant": r.variant, "variant_name": r.variant_name, "input": r.input,
               "kind": r.kind, "seed": -1 if r.seed is None else int(r.seed)}
        for k in plan.batch.set_keys:
            row[k] = r.set_values.get(k)
        row["status"] = res.get("status", "missing")
        row["executed"] = bool(res.get("_executed", False))
        for k in METRIC_KEYS:
            v = m.get(k, math.nan)
            row[k] = float(v) if v is not None else math.nan
        row["error"] = str(res.get("error") or "")
        row["run_file"] = os.path.relpath(r.h5, plan.batch.output_dir)
        row["_config"] = r.config
        rows.append(row)
    return rows


def columns_of(plan) -> list:
    """Column order of a plan's summary table: run identity, the batch's set keys, status, metrics, tail columns."""
    return (list(ID_COLUMNS) + list(plan.batch.set_keys) + ["status", "executed"] + list(METRIC_KEYS)
            + list(TAIL_COLUMNS))


# ------------------------------------------------------------------------------------------ statistics
def interval(values, ci: float = 0.95):
    """(n, mean, lo, hi) of the finite values: Student-t interval of the mean."""
    x = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    n = x.size
    if n == 0:
        return 0, math.nan, math.nan, math.nan
    mean = float(np.mean(x))
    if n < 2:
        return n, mean, math.nan, math.nan
    from scipy.stats import t
    half = float(t.ppf(0.5 + ci / 2.0, n - 1) * np.std(x, ddof=1) / math.sqrt(n))
    return n, mean, mean - half, mean + half


def group_stats(rows: list, by, metrics=METRIC_KEYS, ci: float = 0.95) -> list:
    """[{group: value(s), n_runs, n_ok, <m>_mean, <m>_lo, <m>_hi, <m>_n}] in first-appearance order."""
    by = [by] if isinstance(by, str) else list(by)
    groups: dict = {}
    for row in rows:
        key = tuple(_hashable(row.get(b)) for b in by)
        groups.setdefault(key, []).append(row)
    out = []
    for key, members in groups.items():
        g = {b: v for b, v in zip(by, key)}
        ok = [m for m in members if m.get("status") == "ok"]
        g["n_runs"], g["n_ok"] = len(members), len(ok)
        for k in metrics:
            n, mean, lo, hi = interval([m.get(k, math.nan) for m in ok], ci)
            g[f"{k}_mean"], g[f"{k}_lo"], g[f"{k}_hi"], g[f"{k}_n"] = mean, lo, hi, n
        g["_members"] = members
        out.append(g)
    return out


def _hashable(v):
    if isinstance(v, list):
        return tuple(v)
    if isinstance(v, dict):
        return tuple(sorted(v.items()))
    return v


# ------------------------------------------------------------------------------------------ writing
def _cell(v):
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    if isinstance(v, (list, tuple, dict)):
        import json
        return json.dumps(v)
    return str(v)


def _write_csv(path, columns, rows):
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for row in rows:
            w.writerow([_cell(row.get(c)) for c in columns])
    os.replace(tmp, path)


def _h5_column(values):
    """A numpy array for one column (float, int, bool or str)."""
    import h5py
    if all(isinstance(v, bool) for v in values):
        return np.asarray(values, dtype=bool)
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return np.asarray(values, dtype=np.int64)
    if all((isinstance(v, (int, float)) and not isinstance(v, bool)) or v is None for v in values):
        return np.asarray([math.nan if v is None else v for v in values], dtype=float)
    return np.asarray([_cell(v) for v in values], dtype=h5py.string_dtype())


def write_summary(plan, rows: list):
    """summary.csv, summary.h5 and groups.csv in the batch's output directory; returns their paths."""
    import h5py
    import yaml
    from .. import __version__
    b = plan.batch
    out = b.output_dir
    os.makedirs(out, exist_ok=True)
    cols = columns_of(plan)
    csv_path, h5_path, groups_path = (os.path.join(out, n) for n in ("summary.csv", "summary.h5", "groups.csv"))
    _write_csv(csv_path, cols, rows)
    ci = b.cfg.metrics.ci
    groups = group_stats(rows, "variant", METRIC_KEYS, ci)
    gcols = ["variant", "n_runs", "n_ok"] + [f"{k}_{s}" for k in METRIC_KEYS for s in ("mean", "lo", "hi")]
    _write_csv(groups_path, gcols, groups)
    tmp = h5_path + ".tmp"
    with h5py.File(tmp, "w") as f:
        a = f.attrs
        a["schema"] = "gnssrx-batch-summary-1"
        a["name"] = b.name
        a["batch_yaml"] = yaml.safe_dump(b.raw, sort_keys=False)
        a["batch_file"] = b.path or ""
        a["created_utc"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        a["gnssrx_version"] = __version__
        a["code_version"] = plan.code
        a["n_runs"] = len(rows)
        a["n_ok"] = sum(1 for r in rows if r["status"] == "ok")
        a["n_failed"] = sum(1 for r in rows if r["status"] != "ok")
        a["ci"] = ci
        g = f.create_group("runs")
        g.attrs["columns"] = cols
        g.attrs["metrics"] = list(METRIC_KEYS)
        g.attrs["set_keys"] = list(b.set_keys)
        for c in cols:
            g.create_dataset(c, data=_h5_column([r.get(c) for r in rows]))
        g.create_dataset("config_yaml", data=np.asarray(
            [yaml.safe_dump(r["_config"], sort_keys=False) for r in rows], dtype=h5py.string_dtype()))
        gg = f.create_group("groups")
        gg.attrs["by"] = "variant"
        gg.attrs["ci"] = ci
        for c in gcols:
            gg.create_dataset(c, data=_h5_column([x.get(c) for x in groups]))
    os.replace(tmp, h5_path)
    return csv_path, h5_path, groups_path


# ------------------------------------------------------------------------------------------ reading
def read_summary(path) -> tuple[list, dict]:
    """(rows, attrs) of a summary.h5 (rows: dicts of the /runs columns plus 'config_yaml')."""
    path = os.fspath(path)
    f = open_h5(path, "summary file")
    with f:
        if "runs" not in f:
            raise UserError(f"{path} is not a gnssrx batch summary (no /runs group)")
        g = f["runs"]
        cols = [str(c) for c in g.attrs.get("columns", list(g.keys()))]
        if "config_yaml" in g and "config_yaml" not in cols:
            cols.append("config_yaml")
        data = {}
        for c in cols:
            v = g[c][()]
            if v.dtype.kind in ("O", "S"):
                v = np.asarray([x.decode() if isinstance(x, bytes) else str(x) for x in v], dtype=object)
            data[c] = v
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
    n = len(next(iter(data.values()))) if data else 0
    rows = []
    for i in range(n):
        row = {}
        for c, v in data.items():
            x = v[i]
            row[c] = x.item() if isinstance(x, np.generic) else x
        rows.append(row)
    return rows, attrs


def _config_value(row, key: str):
    import yaml
    cfg = row.get("_cfg")
    if cfg is None:
        cfg = row["_cfg"] = yaml.safe_load(row.get("config_yaml") or "{}") or {}
    node = cfg
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            raise KeyError(key)
        node = node[part]
    return node


def resolve_by(rows: list, by: list) -> None:
    """Make every --by key a row field: a summary column, or a receiver config key (from config_yaml)."""
    for key in by:
        if rows and key in rows[0]:
            continue
        for row in rows:
            try:
                row[key] = _config_value(row, key)
            except KeyError:
                raise UserError(f"--by {key}: neither a summary column nor a receiver config key") from None


def _fmt(v, digits=4):
    if v is None or not np.isfinite(v):
        return "n/a"
    if v != 0 and (abs(v) >= 1e5 or abs(v) < 1e-3):
        return f"{v:.{digits - 1}e}"
    return f"{v:.{digits}g}"


def _group_label(g, by):
    return ", ".join(f"{_cell(g[b])}" if len(by) == 1 else f"{b}={_cell(g[b])}" for b in by)


def comparison_table(groups: list, by: list, metrics, ci: float) -> str:
    """Side by side: one row per metric, one column per group; cells 'mean ± half-width of the CI'."""
    labels = [_group_label(g, by) for g in groups]
    head = ["metric"] + labels
    body = [["runs (ok / all)"] + [f"{g['n_ok']} / {g['n_runs']}" for g in groups]]
    for k in metrics:
        cells = [k]
        for g in groups:
            mean, lo, hi = g[f"{k}_mean"], g[f"{k}_lo"], g[f"{k}_hi"]
            if not np.isfinite(mean):
                cells.append("n/a")
            elif np.isfinite(lo):
                cells.append(f"{_fmt(mean)} ± {_fmt((hi - lo) / 2.0, 2)}")
            else:
                cells.append(_fmt(mean))
        body.append(cells)
    widths = [max(len(r[i]) for r in [head] + body) for i in range(len(head))]
    fmt_row = lambda r: "  ".join(c.ljust(widths[0]) if i == 0 else c.rjust(widths[i])  # noqa: E731
                                  for i, c in enumerate(r))
    title = (f"grouped by {', '.join(by)}: mean ± half-width of the {ci * 100:g} % interval of the mean "
             "(successful runs)")
    return "\n".join([title, fmt_row(head), "  ".join("-" * w for w in widths)] + [fmt_row(r) for r in body])


def comparison_plot(groups: list, by: list, metrics, path: str, title: str = ""):
    """Bars (group means) with interval error bars and the individual runs as dots, one panel per metric."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    metrics = list(metrics)
    ncol = min(3, max(1, len(metrics)))
    nrow = max(1, math.ceil(len(metrics) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.0 * nrow + 0.6), squeeze=False)
    labels = [_group_label(g, by) for g in groups]
    x = np.arange(len(groups))
    rng = np.random.default_rng(0)
    for ax, k in zip(axes.flat, metrics):
        mean = np.array([g[f"{k}_mean"] for g in groups], dtype=float)
        lo = np.array([g[f"{k}_lo"] for g in groups], dtype=float)
        hi = np.array([g[f"{k}_hi"] for g in groups], dtype=float)
        err = np.vstack([np.where(np.isfinite(lo), mean - lo, 0.0), np.where(np.isfinite(hi), hi - mean, 0.0)])
        ax.bar(x, np.nan_to_num(mean), color=[f"C{i % 10}" for i in range(len(groups))], alpha=0.55,
               yerr=err, capsize=4, ecolor="k")
        for i, g in enumerate(groups):
            vals = np.array([m.get(k, math.nan) for m in g["_members"] if m.get("status") == "ok"], dtype=float)
            vals = vals[np.isfinite(vals)]
            ax.plot(i + rng.uniform(-0.18, 0.18, vals.size), vals, "k.", ms=4, alpha=0.7)
        ax.set_title(k, fontsize=9)
        ax.set_xticks(x)
        ax.set_xticklabels(labels, rotation=30 if len(groups) > 2 else 0, ha="right" if len(groups) > 2
                           else "center", fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(metrics):]:
        ax.set_visible(False)
    fig.suptitle(title or f"batch comparison by {', '.join(by)} (bars: mean, whiskers: interval, dots: runs)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def compare(summary_h5, by=("variant",), metrics=None, plot: str | None = None, ci: float | None = None):
    """Group a summary's runs by the given keys; returns (table text, groups, plot path or None)."""
    rows, attrs = read_summary(summary_h5)
    if not rows:
        raise UserError(f"{summary_h5}: the summary has no runs")
    by = list(by) or ["variant"]
    resolve_by(rows, by)
    ci = float(attrs.get("ci", 0.95)) if ci is None else ci
    if metrics:
        unknown = [m for m in metrics if m not in rows[0]]
        if unknown:
            raise UserError(f"--metric {unknown[0]}: not a summary column "
                            f"(metrics: {', '.join(METRIC_KEYS)})")
        metrics = list(metrics)
    else:
        metrics = [k for k in METRIC_KEYS if k in rows[0]]
    groups = group_stats(rows, by, metrics, ci)
    shown = [k for k in metrics if any(np.isfinite(g[f"{k}_mean"]) for g in groups)]
    table = comparison_table(groups, by, shown, ci)
    if plot:
        pm = [k for k in (metrics if len(metrics) <= 12 and metrics != list(METRIC_KEYS) else PLOT_METRICS)
              if k in shown]
        comparison_plot(groups, by, pm or shown[:9], plot,
                        title=f"{attrs.get('name', '')}: by {', '.join(by)} (bars: mean, whiskers: "
                              f"{ci * 100:g} % interval, dots: runs)")
    return table, groups, plot
