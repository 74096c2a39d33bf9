#!/usr/bin/env python3
"""Compare two `make figures` result directories: do their tables agree within the stated intervals?

    python scripts/figures/figures_compare.py figures_run1 figures_run2 [--all] [--rtol 1e-9]
    make figures-compare A=figures_run1 B=figures_run2

Each directory is a FIGDIR (sub-directories vector/, carrier/, leo/; a missing one is reported and skipped) or
one of those sub-directories.  Read: vector/vector_results.json, carrier/carrier_results.json,
leo/leo_results.json - the per-seed values behind every table cell.  For every cell (a metric of a table row):

* per-seed: the two runs' per-seed values are "identical" when every seed agrees to --rtol (default 1e-9
  relative, float tolerance: the same seed must give the same number on any -j); otherwise the largest
  per-seed difference is shown;
* interval: the two means agree when their stated 95 % intervals (mean ± Student-t half width over the seeds,
  as printed in the tables) overlap, |mean_A - mean_B| <= h_A + h_B; a cell with fewer than two seeds (no
  interval) must agree to --rtol;
* counts (diverged runs, lost-lock seeds, failed LEO runs) must be equal when the seeds are the same, else
  their 95 % Wilson intervals must overlap.

With different seed lists (e.g. a run cut short), the seeds both runs have must still agree per seed, and the
means by the interval test.  Run times (wall_s)
are not compared.  Prints one line per differing cell (every cell with --all) and a summary; exit 0 when
every cell agrees within the intervals, 1 otherwise, 2 on bad input.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))

PARTS = {"vector": "vector_results.json", "carrier": "carrier_results.json", "leo": "leo_results.json"}
SKIP = {"wall_s"}                      # machine-dependent timing, not a result


class BadInput(Exception):
    pass


# ------------------------------------------------------------------------------------------ cells
# A cell: name -> {"kind": "value" | "count", "seeds": [...], "values": [per-seed values]} (value), or
# {"kind": "count", "seeds": [...], "k": int, "n": int} (count).

def _num(v):
    return float("nan") if v is None else float(v)


def vector_cells(doc):
    cells = {}
    for exp, d in doc.items():
        for row in d.get("rows", []):
            seeds = list(row["seeds"])
            base = f"vector/{exp}/{row['run']}"
            for k, vals in row["per_seed"].items():
                if k in SKIP:
                    continue
                if k == "diverged":
                    cells[f"{base}/diverged"] = {"kind": "count", "seeds": seeds, "k": int(sum(map(bool, vals))),
                                                 "n": len(vals), "flags": [bool(v) for v in vals]}
                else:
                    cells[f"{base}/{k}"] = {"kind": "value", "seeds": seeds, "values": [_num(v) for v in vals]}
    return cells


def carrier_cells(doc):
    cells = {}
    for name, d in doc.get("scint", {}).items():
        seeds = list(range(len(d["std_per_seed"])))
        cells[f"carrier/scint/{name}/phase_std_deg"] = {"kind": "value", "seeds": seeds,
                                                        "values": [_num(v) for v in d["std_per_seed"]]}
        cells[f"carrier/scint/{name}/loss_of_lock"] = {"kind": "value", "seeds": seeds,
                                                       "values": [_num(v) for v in d["lol_per_seed"]]}
        lost = [bool(v) for v in d["lost_per_seed"]]
        cells[f"carrier/scint/{name}/lost_lock"] = {"kind": "count", "seeds": seeds, "k": sum(lost),
                                                    "n": len(lost), "flags": lost}
    for name, vals in doc.get("weak", {}).items():
        cells[f"carrier/weak/{name}/threshold_dbhz"] = {"kind": "value", "seeds": list(range(len(vals))),
                                                        "values": [_num(v) for v in vals]}
    return cells


def leo_cells(doc):
    cells = {}
    seed0 = doc.get("args", {}).get("seed", 0)

    def blocks(prefix, bl, first):
        seeds = [first + k for k in range(len(bl))]
        for m in bl[0]:
            for q in ("total", "final3d_mean", "rmse_mean", "rmse_min", "rmse_max"):
                cells[f"{prefix}/{m}/{q}"] = {"kind": "value", "seeds": seeds,
                                              "values": [_num(b[m][q]) for b in bl]}
            for i, ax in enumerate("xyz"):
                cells[f"{prefix}/{m}/axis_{ax}"] = {"kind": "value", "seeds": seeds,
                                                    "values": [_num(b[m]["axis"][i]) for b in bl]}
            nf = [int(b[m]["n_failed"]) for b in bl]
            runs = int(doc.get("args", {}).get("runs", 0))
            cells[f"{prefix}/{m}/n_failed"] = {"kind": "count", "seeds": seeds, "k": sum(nf),
                                               "n": max(runs, sum(nf), 1), "flags": nf}

    blocks("leo/main", doc["blocks"], seed0)
    for lv, bl in doc.get("sensitivity", {}).items():
        blocks(f"leo/sensitivity_level{lv}", bl, seed0 + 1000 + 10 * int(lv))
    return cells


READERS = {"vector": vector_cells, "carrier": carrier_cells, "leo": leo_cells}


def load(path):
    """{part: cells} of a FIGDIR or one of its sub-directories."""
    if not os.path.isdir(path):
        raise BadInput(f"not a directory: {path}")
    found = {}
    for part, fname in PARTS.items():
        for cand in (os.path.join(path, part, fname), os.path.join(path, fname)):
            if os.path.exists(cand):
                try:
                    with open(cand) as fh:
                        found[part] = READERS[part](json.load(fh))
                except (ValueError, KeyError, TypeError, IndexError) as e:
                    raise BadInput(f"{cand}: not a {part} results file ({type(e).__name__}: {e})")
                break
    if not found:
        raise BadInput(f"{path}: no {', '.join(PARTS.values())} in it or in its vector/, carrier/, leo/")
    return found


# ------------------------------------------------------------------------------------------ statistics
def interval(values):
    """(n, mean, half width of the 95 % Student-t interval) of the finite values (the tables' statistic)."""
    from receiver.batch.compare import interval as t_interval
    n, mean, lo, hi = t_interval(list(values), 0.95)
    return n, mean, ((hi - lo) / 2.0 if n >= 2 else float("nan"))


def wilson(k, n, z=1.96):
    if n <= 0:
        return 0.0, 1.0
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def _same(a, b, rtol):
    if math.isnan(a) and math.isnan(b):
        return True
    if math.isnan(a) or math.isnan(b):
        return False
    return abs(a - b) <= rtol * max(abs(a), abs(b), 1e-300) or a == b


def _common(ca, cb, key):
    """Per-seed values of the seeds both cells have: (seeds, values in A, values in B)."""
    ia = {s: i for i, s in enumerate(ca["seeds"])}
    ib = {s: i for i, s in enumerate(cb["seeds"])}
    seeds = [s for s in ca["seeds"] if s in ib]
    return seeds, [ca[key][ia[s]] for s in seeds], [cb[key][ib[s]] for s in seeds]


def compare_cell(ca, cb, rtol):
    """(agree: bool, identical: bool, text).  identical: same seeds, every per-seed value equal to rtol;
    with different seed lists the seeds both have are compared per seed (shown) and the means by interval."""
    same_seeds = ca["seeds"] == cb["seeds"]
    key = "flags" if ca["kind"] == "count" else "values"
    cs, xa, xb = _common(ca, cb, key)
    common_ok = all(_same(float(x), float(y), rtol) for x, y in zip(xa, xb))
    common = "" if same_seeds else (f" | common seeds {cs}: {'identical' if common_ok else 'DIFFER'}"
                                    if cs else " | no common seed")
    if ca["kind"] == "count":
        ka, na, kb, nb = ca["k"], ca["n"], cb["k"], cb["n"]
        identical = same_seeds and common_ok
        if same_seeds:
            agree = ka == kb
        else:
            (la, ha), (lb, hb) = wilson(ka, na), wilson(kb, nb)
            agree = la <= hb and lb <= ha and common_ok
        return agree, identical, f"{ka}/{na} | {kb}/{nb}{common}"
    va, vb = ca["values"], cb["values"]
    identical = same_seeds and common_ok
    na, ma, ha = interval(va)
    nb, mb, hb = interval(vb)
    if na == 0 and nb == 0:
        agree, delta = True, float("nan")
    elif na == 0 or nb == 0:
        agree, delta = False, float("nan")
    elif math.isnan(ha) or math.isnan(hb):
        agree, delta = _same(ma, mb, rtol), mb - ma
    else:
        delta = mb - ma
        agree = abs(delta) <= ha + hb
    if identical:
        agree = True
    elif not common_ok and not same_seeds:
        agree = False                  # a seed both runs have gave a different number
    seed_diff = common
    if same_seeds and not identical and len(va) == len(vb):
        d = [abs(x - y) for x, y in zip(va, vb) if not (math.isnan(x) or math.isnan(y))]
        seed_diff = f" | max per-seed |diff| {max(d):.4g}" if d else " | NaN pattern differs"
    fmt = lambda m, h: "nan" if math.isnan(m) else (f"{m:.4g}" if math.isnan(h) else f"{m:.4g} ± {h:.3g}")  # noqa: E731
    return agree, identical, f"{fmt(ma, ha)} | {fmt(mb, hb)} | Δ {delta:+.3g}{seed_diff}"


def compare(a, b, rtol=1e-9, show_all=False, out=print):
    """Compare two loaded directories; returns the number of cells that disagree (missing cells count)."""
    bad = 0
    for part in PARTS:
        if part not in a or part not in b:
            if part in a or part in b:
                out(f"{part}: only in {'A' if part in a else 'B'} (skipped)")
            continue
        ca, cb = a[part], b[part]
        names = sorted(set(ca) | set(cb))
        n_ident = n_agree = n_bad = 0
        out(f"{part}: {len(names)} cells")
        for name in names:
            if name not in ca or name not in cb:
                n_bad += 1
                out(f"  MISSING in {'B' if name in ca else 'A'}: {name}")
                continue
            agree, identical, text = compare_cell(ca[name], cb[name], rtol)
            n_ident += identical
            n_agree += agree and not identical
            n_bad += not agree
            if show_all or not identical:
                tag = "identical" if identical else ("within intervals" if agree else "OUTSIDE intervals")
                seeds = "" if ca[name]["seeds"] == cb[name]["seeds"] else " (different seeds)"
                out(f"  {name}: {text} -> {tag}{seeds}")
        out(f"{part}: {n_ident} identical per seed, {n_agree} differ but within the stated intervals, "
            f"{n_bad} outside / missing")
        bad += n_bad
    return bad


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("a", help="first figure directory (FIGDIR, or its vector/ carrier/ leo/)")
    ap.add_argument("b", help="second figure directory")
    ap.add_argument("--all", action="store_true", help="print every cell, not only those that differ")
    ap.add_argument("--rtol", type=float, default=1e-9, help="relative tolerance of 'identical' (default 1e-9)")
    args = ap.parse_args(argv)
    try:
        a, b = load(args.a), load(args.b)
    except BadInput as e:
        sys.stderr.write(f"figures-compare: {e}\n")
        return 2
    print(f"A = {args.a}\nB = {args.b}\n(cells: A mean ± 95 % half width | B | difference B - A)")
    common = [p for p in PARTS if p in a and p in b]
    if not common:
        sys.stderr.write("figures-compare: the two directories have no results of the same kind\n")
        return 2
    bad = compare(a, b, args.rtol, args.all)
    print(f"figures-compare: {'AGREE' if not bad else 'DIFFER'}: {bad} cell(s) outside the stated intervals or "
          f"missing ({', '.join(common)} compared)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
