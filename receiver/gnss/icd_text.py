"""The Galileo OS SIS ICD as text: where the shared copy is and its text through ``pdftotext -layout``
(poppler-utils), for the scripts that take the codes from it (``scripts/tools/gal_e1_codes_from_icd.py``,
``scripts/tools/gal_e5a_codes_from_icd.py``) and their tests.  The receiver itself reads only the data files
those scripts write."""
from __future__ import annotations

import argparse
import re
import shutil
import subprocess
from pathlib import Path

#: the ICD inside ../shared (OS SIS ICD issue 1.1, 2010)
ICD_IN_SHARED = Path("shared") / "reference" / "galileo_os_sis_icd_issue1.1_2010.pdf"


def find_icd(root: Path) -> Path | None:
    """The ICD in ../shared beside the checkout ``root`` (or beside its folder of git worktrees), or None."""
    return next((d / ICD_IN_SHARED for d in (root.parent, root.parent.parent) if (d / ICD_IN_SHARED).exists()),
                None)


def pdf_text(pdf: Path) -> str:
    """The PDF's text with its layout kept (``pdftotext -layout``); SystemExit when pdftotext is missing or
    fails."""
    exe = shutil.which("pdftotext")
    if exe is None:
        raise SystemExit("pdftotext (poppler-utils) not found: apt-get install poppler-utils")
    r = subprocess.run([exe, "-layout", str(pdf), "-"], capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"pdftotext failed on {pdf}: {r.stderr.strip()}")
    return r.stdout


def extraction_args(doc: str, root: Path, default_out: Path, argv=None) -> tuple[Path, Path]:
    """The command line of an extraction script, ``[ICD.pdf] [-o OUT]`` (the ICD of :func:`find_icd` by
    default): (pdf, out)."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("pdf", nargs="?", default=str(find_icd(root) or root.parent / ICD_IN_SHARED))
    ap.add_argument("-o", "--out", default=str(default_out))
    a = ap.parse_args(argv)
    return Path(a.pdf), Path(a.out)


_HEX_LINE = re.compile(r"^\s*([0-9A-F]+)\s*$")
_ANNEX_SECTION = re.compile(r"^\s*C\.(\d+)\.\s")


def annex_hex_codes(text: str, head: re.Pattern, n_hex: int, label: str) -> dict[tuple[str, int], str]:
    """The codes Annex C prints as hex: each under a heading matched by ``head`` (groups: component letter,
    code number), its digits the hex-only lines after it until ``n_hex`` digits (a code's print-out ends at the
    next Annex C section).  {(component, code no): digits}; SystemExit on a code printed twice or longer than
    n_hex (``label`` names the codes in the message, e.g. "E1" -> "E1B code 3")."""
    codes: dict[tuple[str, int], str] = {}
    cur = None            # key of the code being read
    digits: list[str] = []
    for line in text.splitlines():
        m = head.match(line)
        if m:
            cur, digits = (m.group(1), int(m.group(2))), []
            if cur in codes:
                raise SystemExit(f"{label}{cur[0]} code {cur[1]} appears twice")
            continue
        if cur is None:
            continue
        if _ANNEX_SECTION.match(line):      # the next Annex C section (C.8 after C.7, Annex D after C.8)
            cur = None
            continue
        m = _HEX_LINE.match(line)
        if m:
            digits.append(m.group(1))
            n = sum(len(d) for d in digits)
            if n == n_hex:
                codes[cur] = "".join(digits)
                cur = None
            elif n > n_hex:
                raise SystemExit(f"{label}{cur[0]} code {cur[1]}: more than {n_hex} hex digits ({n})")
    return codes
