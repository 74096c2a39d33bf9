"""RINEX text helpers shared by the navigation-file readers and writers (receiver.gnss.rinex, rinex_gal):
Fortran-style fixed-width numbers, record splitting, the checks of a navigation file's first line and the
corrections of its header."""
from __future__ import annotations

from pathlib import Path

from ..errors import UserError


def _num(text: str) -> float:
    """Fortran-style number (D or E exponent, blank = 0)."""
    text = text.strip().replace("D", "E").replace("d", "E")
    if not text:
        return 0.0
    return float(text)


def _fixed(line: str, start: int, width: int, count: int):
    return [_num(line[start + k * width:start + (k + 1) * width]) for k in range(count)]


def _records(lines, is_start):
    rec = []
    for line in lines:
        if not line.strip():
            continue
        if is_start(line):
            if rec:
                yield rec
            rec = [line]
        elif rec:
            rec.append(line)
    if rec:
        yield rec


_SYSTEM_NAME = {"C": "BeiDou", "E": "Galileo"}


def _wanted_name(systems) -> str:
    """The name of the system group a reader call asks for, for its messages (GPS for G/J)."""
    return next((_SYSTEM_NAME[s] for s in systems if s in _SYSTEM_NAME), "GPS")


def _nav_lines(path: Path, systems) -> tuple[list, float]:
    """The lines of a navigation file and its RINEX version, after the checks of its first line."""
    try:
        text = path.read_text(errors="replace")
    except OSError as exc:
        raise UserError(f"cannot read RINEX navigation file {path}: {exc.strerror or exc}") from None
    lines = text.splitlines()
    if not lines or "RINEX VERSION / TYPE" not in lines[0]:
        raise UserError(f"{path}: not a RINEX file (no 'RINEX VERSION / TYPE' header line)")
    try:
        version = float(lines[0][:9])
    except ValueError:
        raise UserError(f"{path}: unreadable RINEX version in first line") from None
    ftype = lines[0][20:21].upper()
    system = lines[0][40:41].upper()
    if version < 3 and "G" not in systems:
        raise UserError(f"{path}: RINEX {version:g} navigation files hold GPS only "
                        f"({'Galileo' if 'E' in systems else 'BeiDou'} needs RINEX 3)")
    if version < 3:
        if ftype != "N":
            raise UserError(f"{path}: RINEX {version:g} file of type '{ftype}' is not a GPS navigation file")
    else:
        if ftype != "N":
            raise UserError(f"{path}: RINEX {version:g} file of type '{ftype}' is not a navigation file")
        if system not in tuple(systems) + ("M", " ", ""):
            raise UserError(f"{path}: RINEX {version:g} navigation file for system '{system}', not "
                            f"{_wanted_name(systems)}")
    return lines, version


def _header_values(path: Path, lines, version: float, systems) -> tuple[dict, int]:
    """The corrections of a navigation file's header and the index of its END OF HEADER line.

    Keys: ``alpha``/``beta`` (Klobuchar: GPS lines, or with ``C`` in ``systems`` the BeiDou ones when the
    file has no GPS set before them), ``gput`` (a0, a1, tot, wnt), ``leap`` (dt_ls, dt_lsf, wn_lsf, dn), and
    with ``E`` in ``systems`` ``gal`` (ai0, ai1, ai2), ``gaut`` and ``gpga`` (a0, a1, t, week)."""
    h: dict = {"alpha": None, "beta": None, "gput": None, "leap": None}
    gal = "E" in systems
    end = None
    try:
        for i, line in enumerate(lines):
            label = line[60:].strip()
            if label == "END OF HEADER":
                end = i
                break
            if label == "ION ALPHA":
                h["alpha"] = tuple(_fixed(line, 2, 12, 4))
            elif label == "ION BETA":
                h["beta"] = tuple(_fixed(line, 2, 12, 4))
            elif label == "DELTA-UTC: A0,A1,T,W":
                a0, a1 = _fixed(line, 3, 19, 2)
                h["gput"] = (a0, a1, int(_num(line[41:50])), int(_num(line[50:59])))
            elif label == "IONOSPHERIC CORR":
                key = line[:4].strip().upper()
                if key == "GPSA" or (key == "BDSA" and "C" in systems and h["alpha"] is None):
                    h["alpha"] = tuple(_fixed(line, 5, 12, 4))
                elif key == "GPSB" or (key == "BDSB" and "C" in systems and h["beta"] is None):
                    h["beta"] = tuple(_fixed(line, 5, 12, 4))
                elif key == "GAL" and gal:
                    h["gal"] = tuple(_fixed(line, 5, 12, 3))
            elif label == "TIME SYSTEM CORR":
                key = line[:4].strip().upper()
                if key == "GPUT" or (gal and key in ("GAUT", "GPGA")):
                    h[key.lower()] = (_num(line[5:22]), _num(line[22:38]), int(_num(line[38:45])),
                                      int(_num(line[45:50])))
            elif label == "LEAP SECONDS":
                v = [line[k * 6:(k + 1) * 6].strip() for k in range(4)]
                h["leap"] = tuple(int(x) if x and (k == 0 or version >= 3) else None for k, x in enumerate(v))
    except ValueError as exc:
        raise UserError(f"{path}: bad RINEX header line {i + 1}: {exc}") from None
    if end is None:
        raise UserError(f"{path}: no 'END OF HEADER' line")
    return h, end


def _d19(x: float) -> str:
    """Number in a 19-character field, scientific notation with 12 decimals."""
    return f"{x: .12E}".rjust(19)


def _d12(x: float) -> str:
    return f"{x: .4E}".rjust(12)


def _hdr(content: str, label: str) -> str:
    return content.ljust(60)[:60] + label.ljust(20) + "\n"
