#!/usr/bin/env python3
"""Extract the Galileo E1-B and E1-C primary codes from the Galileo OS SIS ICD (issue 1.1, Annex C, sections
C.7 and C.8) and write them as a packed hex text file shipped with the package
(receiver/gnss/data/gal_e1_codes.txt).

The ICD prints each code as 1023 hexadecimal digits (4092 chips; the first chip is the most significant bit of
the first digit) under the heading "E1B Code No N" / "E1C Code No N".  The PDF is turned into text by
``pdftotext -layout`` (poppler-utils); each code's digits are the hex-only lines after its heading, up to 1023
digits.  Every code must come out at exactly 1023 digits and all 50 + 50 must be found, otherwise the script
stops.  The secondary code CS25_1 of E1-C (ICD Table 19) is written too.

Usage:  python scripts/tools/gal_e1_codes_from_icd.py [ICD.pdf] [-o receiver/gnss/data/gal_e1_codes.txt]
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

from receiver.gnss.icd_text import annex_hex_codes, extraction_args, pdf_text

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "receiver" / "gnss" / "data" / "gal_e1_codes.txt"
N_HEX = 1023
N_PRN = 50

_HEAD = re.compile(r"^\s*E1([BC]) Code No\s+(\d+)\s*$")
_CS25 = re.compile(r"^\s*CS251\s+25\s+7\s+3\s+([0-9A-F]{7})\s*$")


def parse(text: str) -> tuple[dict[tuple[str, int], str], str]:
    """{("B"|"C", prn): 1023 hex digits}, and the CS25 hex string (7 digits, 3 fill zeros)."""
    codes = annex_hex_codes(text, _HEAD, N_HEX, "E1")
    found = [m.group(1) for m in map(_CS25.match, text.splitlines()) if m]
    cs25 = found[-1] if found else None
    if cs25 is None:
        raise SystemExit("CS25_1 (Table 19) not found")
    for comp in "BC":
        missing = [p for p in range(1, N_PRN + 1) if (comp, p) not in codes]
        if missing:
            raise SystemExit(f"E1{comp} codes not found (or not {N_HEX} digits): {missing}")
    return codes, cs25


def write(codes, cs25, out: Path, source: str) -> None:
    lines = ["# Galileo E1 primary codes, extracted from the Galileo OS SIS ICD issue 1.1 (2010), Annex C.7 (E1-B)",
             "# and C.8 (E1-C), by scripts/tools/gal_e1_codes_from_icd.py from " + source + ".",
             "# One code per line: component (E1B / E1C), code number (= PRN), 1023 hex digits = 4092 chips,",
             "# first chip = most significant bit of the first digit (logic 1 -> -1, logic 0 -> +1 in the signal).",
             "# CS25: the E1-C secondary code CS25_1 (ICD Table 19), 7 digits, the last 3 bits are fill zeros.",
             f"CS25 {cs25}"]
    for comp in "BC":
        for p in range(1, N_PRN + 1):
            lines.append(f"E1{comp} {p:02d} {codes[(comp, p)]}")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")


def main(argv=None) -> int:
    pdf, out = extraction_args(__doc__, ROOT, DEFAULT_OUT, argv)
    if not pdf.exists():
        print(f"error: {pdf} not found", file=sys.stderr)
        return 2
    codes, cs25 = parse(pdf_text(pdf))
    write(codes, cs25, out, pdf.name)
    print(f"wrote {len(codes)} codes and CS25 {cs25} to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
