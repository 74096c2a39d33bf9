"""The size rules of the project's standards, enforced: no function over 100 lines outside numba kernels, no
module over 500 lines unless its docstring says why.

A function's length runs from its ``def`` line to its last line (docstring and comments included,
decorators not); methods and nested functions count on their own.  Numba kernels (decorated with
``njit``, ``jit``, ``vectorize``, ``guvectorize``, ``cfunc`` or ``stencil``, bare or called, ``numba.``
prefixed or not) are exempt: a compiled epoch loop is one function by design.  A module over 500 lines
passes when its docstring holds a sentence starting "Why this module is long:" that gives the reason.
"""
from __future__ import annotations

import ast
import functools
import re
import textwrap
from pathlib import Path

from repo_paths import ROOT

PKG = ROOT / "receiver"
MAX_FUNCTION_LINES = 100
MAX_MODULE_LINES = 500
REASON = re.compile(r"why this module is long:\s*\S", re.IGNORECASE)
NUMBA_DECORATORS = {"njit", "jit", "vectorize", "guvectorize", "cfunc", "stencil"}

#: known exceptions (path::name -> why); test_allow_lists_hold_only_current_violations fails on an entry that
#: no longer violates the rule, so none can outlive its fix.  Empty: every function and module meets the rule.
FUNCTION_ALLOW: dict[str, str] = {}
#: modules over the limit without a written reason (path -> why); emptied like FUNCTION_ALLOW
MODULE_ALLOW: dict[str, str] = {}


def _is_numba(dec: ast.expr) -> bool:
    node = dec.func if isinstance(dec, ast.Call) else dec
    name = node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")
    return name in NUMBA_DECORATORS


def long_functions(root: Path, base: Path) -> list[tuple[str, int]]:
    """[("path::name", lines)] of the functions over MAX_FUNCTION_LINES that are not numba kernels."""
    out = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES and not any(_is_numba(d) for d in node.decorator_list):
                    out.append((f"{path.relative_to(base).as_posix()}::{node.name}", n))
    return out


def long_modules(root: Path, base: Path) -> list[tuple[str, int]]:
    """[(path, lines)] of the modules over MAX_MODULE_LINES whose docstring gives no reason."""
    out = []
    for path in sorted(root.rglob("*.py")):
        text = path.read_text()
        n = len(text.splitlines())
        if n > MAX_MODULE_LINES and not REASON.search(ast.get_docstring(ast.parse(text)) or ""):
            out.append((path.relative_to(base).as_posix(), n))
    return out


@functools.lru_cache(maxsize=1)
def _package() -> tuple[list, list]:
    """(long functions, long modules) of receiver/, parsed once for the tests below."""
    return long_functions(PKG, ROOT), long_modules(PKG, ROOT)


def test_no_function_over_100_lines_outside_numba_kernels():
    bad = [f"{name}: {n} lines" for name, n in _package()[0] if name not in FUNCTION_ALLOW]
    assert not bad, "split these functions (or, for a numba kernel, decorate it):\n" + "\n".join(bad)


def test_no_module_over_500_lines_without_a_reason():
    bad = [f"{p}: {n} lines" for p, n in _package()[1] if p not in MODULE_ALLOW]
    assert not bad, ("split these modules or write 'Why this module is long: <reason>' in the docstring:\n"
                     + "\n".join(bad))


def test_allow_lists_hold_only_current_violations():
    """An allowed function or module that meets the rule again must leave the allow-list."""
    funcs = {name for name, _ in _package()[0]}
    mods = {p for p, _ in _package()[1]}
    stale = [k for k in FUNCTION_ALLOW if k not in funcs] + [k for k in MODULE_ALLOW if k not in mods]
    assert not stale, "no longer over the limit, remove from the allow-list: " + ", ".join(stale)


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))


def test_the_rules_catch_a_synthetic_violation(tmp_path):
    """The detectors on a made-up package: a 101-line function, a long method and a long nested function
    fail; a 100-line function and long numba kernels (bare, called, numba.-prefixed) pass; a 501-line module
    fails without the reason sentence, passes with it, and a 500-line module passes."""
    body = "\n".join(f"    x{i} = {i}" for i in range(100))            # def line + 100 = 101 lines
    short = "\n".join(f"    x{i} = {i}" for i in range(99))             # def line + 99 = 100 lines
    pkg = tmp_path / "receiver"
    _write(pkg / "a.py", f'"""Module a."""\n\n\ndef too_long():\n{body}\n\n\ndef fits():\n{short}\n')
    _write(pkg / "b.py", "from numba import njit\nimport numba\n\n\n"
                         f"@njit\ndef k1():\n{body}\n\n\n@njit(cache=True)\ndef k2():\n{body}\n\n\n"
                         f"@numba.jit(nopython=True)\ndef k3():\n{body}\n")
    nested = "\n".join(f"        y{i} = {i}" for i in range(100))
    _write(pkg / "sub" / "c.py", f"class C:\n    def method(self):\n{textwrap.indent(body, '    ')}\n\n\n"
                                 f"def outer():\n    def inner():\n{nested}\n    return inner\n")
    found = {name for name, _ in long_functions(pkg, tmp_path)}
    assert found == {"receiver/a.py::too_long", "receiver/sub/c.py::method", "receiver/sub/c.py::inner",
                     "receiver/sub/c.py::outer"}

    filler = "\n".join(f"v{i} = {i}" for i in range(600))
    lines = filler.splitlines()
    _write(pkg / "m1.py", '"""A long module."""\n' + "\n".join(lines[:500]) + "\n")            # 501 lines
    _write(pkg / "m2.py", '"""A long module.\n\nWhy this module is long: one state machine.\n"""\n'
                          + "\n".join(lines[:600]) + "\n")
    _write(pkg / "m3.py", '"""Short enough."""\n' + "\n".join(lines[:499]) + "\n")            # 500 lines
    _write(pkg / "m4.py", '"""Why this module is long:"""\n' + "\n".join(lines[:600]) + "\n")  # no reason given
    mods = {p for p, _ in long_modules(pkg, tmp_path)}
    assert mods == {"receiver/m1.py", "receiver/m4.py"}
