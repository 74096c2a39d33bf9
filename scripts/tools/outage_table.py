#!/usr/bin/env python3
"""Acceptance tables of the outage batch (configs/batch/outages.yaml) as markdown.

    python scripts/tools/outage_table.py out/batch/outages/summary.h5 [--out tables.md]

For every input with total outages: per variant, the time from the signal's return to the first good fix
(measured fix within 10 m; receiver/evaluate/outages.py) per outage length -- mean over the seeds, the
worst seed in brackets, and how many seeds never got one --, the largest 3D error of the measured fixes and
of all fixes (coast included), coast fixes, and whether fixes continued to the end.  For every input with a
random blockage: availability (measured fix in the epochs with >= 4 satellites visible) and 3D RMS.  The
last column checks issue 14's acceptance on the worst seed:
  scalar: good fix <= 2 s after each <= 3 s outage, <= 4 s after <= 8 s, <= 10 s after longer ones; no fix
          (of any kind) > 30 m; fixes to the end; urban canyon: availability >= 95 %, 3D RMS <= 5 m;
  vector: good fix <= 2 s after each <= 8 s outage; no measured fix > 30 m; fixes to the end;
  both: no measured (non-coast) fix more than 0.3 s into a total outage (coast epochs flagged).
A variant is vector when its run config has vector.enabled.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np


from receiver.batch.compare import read_summary  # noqa: E402
from receiver.evaluate.outages import N_OUTAGE_KEYS  # noqa: E402


def _is_vector(row) -> bool:
    import yaml
    try:
        return bool(yaml.safe_load(row.get("config_yaml") or "{}").get("vector", {}).get("enabled", False))
    except Exception:
        return False


def _finite(xs):
    return [x for x in xs if x is not None and np.isfinite(x)]


def _fmt(x, nd=2):
    return "-" if x is None or not np.isfinite(x) else f"{x:.{nd}f}"


def ttgf_cell(values) -> str:
    ok = _finite(values)
    never = len(values) - len(ok)
    if not ok:
        return f"never ({never}/{len(values)})" if values else "-"
    cell = f"{np.mean(ok):.2f} ({max(ok):.2f})"
    return cell + (f", never {never}/{len(values)}" if never else "")


def ttgf_limit(dur: float, vector: bool) -> float | None:
    if vector:
        return 2.0 if dur <= 8.0 + 1e-6 else None
    return 2.0 if dur <= 3.0 + 1e-6 else 4.0 if dur <= 8.0 + 1e-6 else 10.0


def total_table(name, groups) -> list:
    first = next(iter(groups.values()))[0]
    n_out = int(first["outage_n"]) if np.isfinite(first["outage_n"]) else 0
    durs = [first[f"outage{k}_dur_s"] for k in range(1, min(n_out, N_OUTAGE_KEYS) + 1)]
    head = ["variant", "runs"] + [f"{d:g} s" for d in durs] + [
        "max err measured (m)", "max err all (m)", "coast fixes", "unflagged fixes in outages", "fixes to end",
        "acceptance"]
    lines = [f"### {name}: total outages -- time from signal return to the first good fix (s): mean over "
             "seeds (worst)", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for variant, rows in groups.items():
        vec = _is_vector(rows[0])
        cells, fails = [variant + (" (vector)" if vec else ""), str(len(rows))], []
        for k, d in enumerate(durs, start=1):
            vals = [r[f"outage{k}_ttgf_s"] for r in rows]
            cells.append(ttgf_cell(vals))
            lim = ttgf_limit(d, vec)
            if lim is not None and not all(np.isfinite(v) and v <= lim for v in vals):
                fails.append(f"{d:g} s > {lim:g} s")
        em = [r["outage_max_err_m"] for r in rows]
        ea = [r["outage_max_err_all_m"] for r in rows]
        cells += [_fmt(max(_finite(em), default=math.nan), 1), _fmt(max(_finite(ea), default=math.nan), 1),
                  _fmt(np.mean(_finite([r["outage_coast_fixes"] for r in rows]) or [math.nan]), 0)]
        inside = _finite([r.get("outage_fixes_inside", math.nan) for r in rows])
        cells.append(_fmt(max(inside, default=math.nan), 0))
        if inside and max(inside) > 0:
            fails.append("unflagged fixes in outages")
        to_end = [r["fixes_to_end"] == 1.0 for r in rows]
        cells.append(f"{sum(to_end)}/{len(rows)}")
        worst = max(_finite(em if vec else ea), default=math.inf)
        if not worst <= 30.0:
            fails.append("error > 30 m")
        if not all(to_end):
            fails.append("fixes stop")
        cells.append("met" if not fails else "NOT met: " + ", ".join(fails))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def canyon_table(name, groups) -> list:
    head = ["variant", "runs", "epochs with >= 4 visible", "availability % (worst)", "3D RMS m (worst)",
            "max err m", "fixes to end", "acceptance"]
    lines = [f"### {name}: random blockage -- measured fixes in the epochs with >= 4 satellites visible", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for variant, rows in groups.items():
        vec = _is_vector(rows[0])
        av = [r["canyon_availability"] for r in rows]
        rms = [r["canyon_rms_3d_m"] for r in rows]
        ep = _finite([r["canyon_epochs"] for r in rows])
        cells = [variant + (" (vector)" if vec else ""), str(len(rows)), _fmt(np.mean(ep) if ep else math.nan, 0),
                 f"{_fmt(100 * np.mean(_finite(av) or [math.nan]), 1)} "
                 f"({_fmt(100 * min(_finite(av), default=math.nan), 1)})",
                 f"{_fmt(np.mean(_finite(rms) or [math.nan]))} ({_fmt(max(_finite(rms), default=math.nan))})",
                 _fmt(max(_finite([r["canyon_max_err_m"] for r in rows]), default=math.nan), 1),
                 f"{sum(r['fixes_to_end'] == 1.0 for r in rows)}/{len(rows)}"]
        if vec:
            cells.append("(reported)")
        else:
            ok = all(np.isfinite(a) and a >= 0.95 for a in av) and all(np.isfinite(x) and x <= 5.0 for x in rms)
            cells.append("met" if ok else "NOT met")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def tables(summary_h5) -> str:
    rows, attrs = read_summary(summary_h5)
    out = [f"## Outage batch `{attrs.get('name', '')}` ({summary_h5})", ""]
    bad = [r for r in rows if r.get("status") != "ok"]
    ok = [r for r in rows if r.get("status") == "ok"]
    for inp in dict.fromkeys(r["input"] for r in ok):
        groups = {}
        for r in ok:
            if r["input"] == inp:
                groups.setdefault(r["variant"], []).append(r)
        any_row = next(iter(groups.values()))[0]
        if np.isfinite(any_row.get("outage_n", math.nan)):
            out += total_table(inp, groups) + [""]
        if np.isfinite(any_row.get("canyon_epochs", math.nan)):
            out += canyon_table(inp, groups) + [""]
    if bad:
        out.append(f"{len(bad)} runs did not complete:")
        out += [f"- {r['variant']} / {r['input']} seed {r['seed']}: {r['status']} {r.get('error', '')}"
                for r in bad]
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("summary", help="summary.h5 of the outage batch")
    ap.add_argument("--out", help="also write the markdown to this file")
    a = ap.parse_args(argv)
    from receiver.errors import UserError
    try:
        text = tables(a.summary)
    except UserError as e:
        print(f"outage_table: {e}", file=sys.stderr)
        return 2
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
