#!/usr/bin/env python
"""Write ``figures/index.md``: every paper-reproduction figure with the paper's claim beside our number.

    python scripts/figures/figures_index.py [FIGURES_DIR]      # default: figures/

Run by ``make figures`` after the figure targets (figures-vector, figures-carrier, figures-leo, ...).  Each
target writes into its own directory ``FIGURES_DIR/<name>/``; this script looks at every such directory:

* ``claims.json`` (the convention for figure scripts): a JSON list of objects
  ``{"figure": "fig6_rmse.png", "claim": "SR-CKF RMSE 137 m", "measured": "142 m"}``; optional keys
  ``"status"`` (e.g. "reproduced", "partly", "not reproduced") and ``"note"``.  ``figure`` is a file name
  inside the directory (or any label when a claim is about a table).  ``claim`` is the paper's statement,
  ``measured`` our number, both as text (numbers are printed as given).  A JSON object
  ``{"claims": [...], "title": "..."}`` is accepted too.
* ``*.png`` - every figure is listed; figures without a claim are listed after the claims table.
* ``tables.md`` / ``*.md`` (other than index files) - linked, as they hold the detailed tables; for a
  directory without ``claims.json`` their text is copied into the index (they carry the paper's numbers
  beside ours).

Directories without ``claims.json`` still get their figures and tables listed.  A malformed
``claims.json`` is reported in the index (and on stderr) instead of stopping the index.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def _md(text) -> str:
    """One table cell: no line breaks, pipes escaped."""
    s = "" if text is None else str(text)
    return " ".join(s.split()).replace("|", "\\|")


def load_claims(path: str):
    """(claims list, title or None, error message or None) of one claims.json."""
    try:
        with open(path) as fh:
            data = json.load(fh)
    except (OSError, ValueError) as exc:
        return [], None, f"cannot read {os.path.basename(path)}: {exc}"
    title = None
    if isinstance(data, dict):
        title = data.get("title")
        data = data.get("claims")
    if not isinstance(data, list):
        return [], title, f"{os.path.basename(path)} must hold a list of {{figure, claim, measured}}"
    claims, bad = [], 0
    for item in data:
        if isinstance(item, dict) and ("claim" in item or "measured" in item):
            claims.append(item)
        else:
            bad += 1
    err = f"{bad} entr{'y' if bad == 1 else 'ies'} of {os.path.basename(path)} skipped (need claim/measured)" \
        if bad else None
    return claims, title, err


def section(fig_dir: str, name: str, rel_base: str) -> list[str]:
    files = sorted(os.listdir(os.path.join(fig_dir, name)))
    pngs = [f for f in files if f.lower().endswith(".png")]
    mds = [f for f in files if f.lower().endswith(".md") and f.lower() not in ("index.md", "readme.md")]
    claims, title, err = [], None, None
    cpath = os.path.join(fig_dir, name, "claims.json")
    if os.path.isfile(cpath):
        claims, title, err = load_claims(cpath)
    lines = [f"## {name}" + (f": {_md(title)}" if title else ""), ""]
    if err:
        lines += [f"> **claims.json problem:** {_md(err)}", ""]
        print(f"figures_index: {name}: {err}", file=sys.stderr)
    link = lambda f: f"[{f}]({rel_base}{name}/{f})"   # noqa: E731
    if claims:
        has_status = any("status" in c for c in claims)
        has_note = any("note" in c for c in claims)
        head = ["figure", "paper's claim", "measured"] + (["status"] if has_status else []) \
            + (["note"] if has_note else [])
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for c in claims:
            fig = str(c.get("figure", ""))
            cell = link(fig) if fig in files else _md(fig)
            row = [cell, _md(c.get("claim", "")), _md(c.get("measured", ""))]
            if has_status:
                row.append(_md(c.get("status", "")))
            if has_note:
                row.append(_md(c.get("note", "")))
            lines.append("| " + " | ".join(row) + " |")
        lines.append("")
    claimed = {str(c.get("figure", "")) for c in claims}
    rest = [f for f in pngs if f not in claimed]
    if rest:
        lines += ["Figures" + (" without a claim:" if claims else ":"), ""]
        lines += [f"* {link(f)}" for f in rest]
        lines.append("")
    if mds:
        lines += ["Tables: " + ", ".join(link(f) for f in mds), ""]
        if not claims:
            # no claims.json: the figure script's own tables (paper's numbers beside ours) go inline
            for f in mds:
                with open(os.path.join(fig_dir, name, f)) as fh:
                    body = fh.read().strip()
                body = "\n".join(("#" + ln) if ln.startswith("#") else ln for ln in body.splitlines())
                lines += [f"### {f}", "", body, ""]
    if not (claims or pngs or mds):
        lines += ["(no figures written)", ""]
    return lines


def write_index(fig_dir: str, out: str | None = None) -> str:
    fig_dir = os.path.abspath(fig_dir)
    out = out or os.path.join(fig_dir, "index.md")
    rel_base = os.path.relpath(fig_dir, os.path.dirname(os.path.abspath(out)))
    rel_base = "" if rel_base == "." else rel_base.rstrip("/") + "/"
    names = sorted(d for d in os.listdir(fig_dir) if os.path.isdir(os.path.join(fig_dir, d))
                   and not d.startswith(".")) if os.path.isdir(fig_dir) else []
    lines = ["# Paper reproductions: figures and claims", "",
             f"Generated by `scripts/figures/figures_index.py` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} "
             f"from {len(names)} figure director{'y' if len(names) == 1 else 'ies'}.  Each row puts the "
             "paper's claim beside the number measured here (from `<name>/claims.json`, written by the "
             "figure scripts); the detailed tables are linked per section.", ""]
    if not names:
        lines += ["(no figure directories found - run `make figures`)", ""]
    n_claims = 0
    for name in names:
        sec = section(fig_dir, name, rel_base)
        n_claims += sum(1 for ln in sec if ln.startswith("| ") and not ln.startswith("| figure"))
        lines += sec
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, "w") as fh:
        fh.write("\n".join(lines).rstrip() + "\n")
    print(f"wrote {out}: {len(names)} sections, {n_claims} claims")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("figures", nargs="?", default=os.path.join(ROOT, "figures"),
                    help="figures directory (default: figures/ of the repository)")
    ap.add_argument("--out", default=None, help="index file (default: FIGURES/index.md)")
    args = ap.parse_args(argv)
    write_index(args.figures, args.out)


if __name__ == "__main__":
    main()
