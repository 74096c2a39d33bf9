"""Galileo E1-B / E1-C primary codes and CS25 against the Galileo OS SIS ICD issue 1.1 (2010).

The first and last eight hex digits below were read from the ICD's Annex C.7 / C.8 print-out (facts of the
standard, typed in here); the shipped table is produced from the PDF by scripts/tools/gal_e1_codes_from_icd.py.
"""
import shutil
import subprocess
import sys

import numpy as np
import pytest

from receiver.gnss import gal_codes as G

from repo_paths import ROOT

from receiver.gnss.icd_text import find_icd
ICD_PDF = find_icd(ROOT)

# (component, code number): (first 8 hex digits, last 8 hex digits) as printed in the ICD
ICD_PRINTED = {
    ("B", 1): ("F5D71013", "6699421A"), ("B", 2): ("96B856A6", "05A18204"), ("B", 7): ("A91F5701", "EE7A2D2C"),
    ("B", 11): ("AFA7FBAC", "2653ED80"), ("B", 19): ("ABA759AE", "8C7AFD48"), ("B", 24): ("BF5202D3", "FD9721CC"),
    ("B", 30): ("B85B6E75", "4D8EDEE4"), ("B", 36): ("87F0D84B", "1A607A24"), ("B", 43): ("F2CE3D09", "841A505E"),
    ("B", 50): ("97051FC6", "DE493020"),
    ("C", 1): ("B39340CA", "431FD340"), ("C", 2): ("A64F94BB", "FE24F5E4"), ("C", 7): ("FB227530", "FF32106A"),
    ("C", 11): ("9D7B1CF0", "5A068A80"), ("C", 19): ("BDA2B72F", "DA4E9028"), ("C", 24): ("A9366308", "2437270C"),
    ("C", 30): ("FDCF36E6", "80BE4E72"), ("C", 36): ("FB2C4002", "41B2ECB6"), ("C", 43): ("A1B9E8AB", "276CF25C"),
    ("C", 50): ("ADDCEDB5", "8601BD0C"),
}


@pytest.mark.parametrize("key", sorted(ICD_PRINTED))
def test_codes_match_the_icd_printout(key):
    comp, prn = key
    first, last = ICD_PRINTED[key]
    h = G.code_hex(comp, prn)
    assert len(h) == 1023
    assert h[:8] == first and h[-8:] == last
    bits = G.e1_code_bits(comp, prn)
    assert bits.shape == (4092,)
    # the first chip in time is the MSB of the first hex digit
    assert list(bits[:8]) == [int(c) for c in f"{int(first[:2], 16):08b}"]
    assert list(bits[-8:]) == [int(c) for c in f"{int(last[-2:], 16):08b}"]


def test_all_100_codes_are_present_distinct_and_balanced():
    seen = set()
    for comp in "BC":
        for prn in G.GAL_PRNS:
            b = G.e1_code_bits(comp, prn)
            assert b.shape == (G.E1_CODE_LEN,)
            assert int(b.sum()) == G.E1_CODE_LEN // 2         # 2046 ones, 2046 zeros
            seen.add(b.tobytes())
    assert len(seen) == 100
    with pytest.raises(ValueError):
        G.code_hex("B", 51)
    with pytest.raises(ValueError):
        G.code_hex("A", 1)


def test_correlation_bounds():
    """Even (periodic) correlation over the 100 codes: auto-correlation sidelobes and every cross-correlation
    below 0.07 N (-23 dB).  The ICD codes are optimised: the largest of ~2e7 such values for random +/-1 codes
    of this length would be ~5.5 sigma = 0.086 N, so a table mangled into noise fails."""
    codes = np.array([G.e1b_code(p) for p in G.GAL_PRNS] + [G.e1c_code(p) for p in G.GAL_PRNS], np.float64)
    n = codes.shape[1]
    F = np.fft.rfft(codes, axis=1)
    auto = np.fft.irfft(F * np.conj(F), n=n, axis=1)
    assert np.allclose(auto[:, 0], n)
    assert np.abs(auto[:, 1:]).max() < 0.07 * n
    worst = 0.0
    for i in range(len(codes) - 1):
        x = np.fft.irfft(F[i] * np.conj(F[i + 1:]), n=n, axis=1)
        worst = max(worst, float(np.abs(x).max()))
    assert worst < 0.07 * n


def test_cs25_is_the_icd_sequence():
    # ICD section 3.5.1 spells CS25_1 out in binary
    icd = "0 0 1 1 1 0 0 0 0 0 0 0 1 0 1 0 1 1 0 1 1 0 0 1 0".split()
    assert list(G.cs25_bits()) == [int(c) for c in icd]
    assert G._table()["CS25"] == "380AD90"          # Table 19: 7 digits, 3 fill zeros
    s = G.cs25_signs()
    assert s.shape == (25,) and s[0] == 1.0 and s[2] == -1.0


def test_boc_and_cboc_subcarriers():
    c = G.e1b_code(1)
    b = G.boc11(c)
    assert b.shape == (8184,) and np.all(b[0::2] == c) and np.all(b[1::2] == -c)
    x = G.cboc(c[:3], "B")
    assert x.shape == (36,)
    # E1-B: alpha + beta where both sub-carriers are high (start of the chip), E1-C: alpha - beta
    assert np.isclose(x[0], c[0] * (G.CBOC_ALPHA + G.CBOC_BETA))
    assert np.isclose(G.cboc(c[:1], "C")[0], c[0] * (G.CBOC_ALPHA - G.CBOC_BETA))
    # unit power, and the BOC(1,1) replica captures alpha^2 = 10/11 of it in amplitude squared
    assert np.isclose(np.mean(x.astype(np.float64) ** 2), 1.0, atol=1e-6)
    rep = np.repeat(b[:6], 6)
    assert np.isclose(np.dot(x, rep) / len(x), G.CBOC_ALPHA, atol=1e-6)


@pytest.mark.slow                    # pdftotext over the ICD (~4 s)
@pytest.mark.skipif(ICD_PDF is None or shutil.which("pdftotext") is None,
                    reason="the Galileo ICD PDF (../shared/reference) or pdftotext (poppler-utils) is absent")
def test_extraction_script_reproduces_the_shipped_table(tmp_path):
    out = tmp_path / "codes.txt"
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "tools" / "gal_e1_codes_from_icd.py"), str(ICD_PDF),
                        "-o", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert out.read_text() == (ROOT / "receiver" / "gnss" / "data" / "gal_e1_codes.txt").read_text()
