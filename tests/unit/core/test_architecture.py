"""The package layout is the architecture: imports go down the layers, never up, and never in a circle.

Parses (ast) every module under receiver/, collects every import of another receiver module -- at module
level and inside functions alike -- and checks
  * the layer rule: a module imports only from its own layer or lower ones (LAYERS, bottom first; the same
    order is written in docs/how-it-works/index.md, "Layers");
  * no import cycle between modules (Tarjan's strongly connected components over the import graph);
  * the extra rules below (the simulator does not depend on the receiver stages; batch metrics do not
    depend on the simulator).
"""
from __future__ import annotations

import ast
from pathlib import Path

from repo_paths import ROOT
import pytest
PKG = ROOT / "receiver"

#: bottom -> top; a module's layer is that of the longest prefix listed here (``receiver`` itself: the
#: package's __init__ only).  A new top-level module must be placed here (and in docs/how-it-works/index.md) explicitly.
LAYERS: list[tuple[str, ...]] = [
    ("receiver", "receiver.errors", "receiver.config", "receiver.plugins", "receiver.logs", "receiver.safeio",
     "receiver.threads", "receiver.interrupt", "receiver.stagetimes", "receiver._numba_start", "receiver._malloc",
     "receiver.suggest"),
    ("receiver.gnss",),
    ("receiver.estimation",),
    ("receiver.runfile",),
    ("receiver.source",),
    ("receiver.acquisition",),
    ("receiver.tracking",),
    ("receiver.navigation",),
    ("receiver.pipeline", "receiver.schema", "receiver.summary", "receiver.dualband"),
    ("receiver.sim", "receiver.leo", "receiver.batch", "receiver.export", "receiver.evaluate", "receiver.probe",
     "receiver.validate", "receiver.snapshot"),
    ("receiver.cli", "receiver.api"),
]

#: (importer prefix, imported prefix): imports that the layer order alone would allow but the design forbids
FORBIDDEN: list[tuple[str, str, str]] = [
    ("receiver.sim", "receiver.acquisition", "the simulator must not depend on the receiver stages"),
    ("receiver.sim", "receiver.tracking", "the simulator must not depend on the receiver stages"),
    ("receiver.sim", "receiver.navigation", "the simulator must not depend on the receiver stages"),
    ("receiver.sim", "receiver.pipeline", "the simulator must not depend on the receiver stages"),
    ("receiver.batch.metrics", "receiver.sim", "metrics are computed from run and truth files only"),
]

#: explicit, commented exceptions to the rules above: (importer, imported)
ALLOWED_EXCEPTIONS: set[tuple[str, str]] = set()


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> list[tuple[str, int]]:
    """(imported receiver module, line) for every import statement in the file, at any depth."""
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "receiver":
                    out.append((a.name, node.lineno))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "receiver":
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                out.append((sub if sub in modules else mod, node.lineno))
    return out


def layer_of(name: str) -> int:
    best, best_len = None, -1
    for i, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if (name == p or (p != "receiver" and name.startswith(p + "."))) and len(p) > best_len:
                best, best_len = i, len(p)
    assert best is not None, f"{name} is in no layer: add it to LAYERS (and to docs/how-it-works/index.md)"
    return best


def _graph():
    modules = all_modules()
    return modules, {m: imports_of(m, p, modules) for m, p in modules.items()}


def _under(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def test_every_module_has_a_layer():
    for m in all_modules():
        layer_of(m)


@pytest.mark.slow
def test_imports_go_down_the_layers():
    modules, graph = _graph()
    bad = []
    for m, deps in graph.items():
        for d, line in deps:
            if d not in modules:
                bad.append(f"{m}:{line} imports {d}, which does not exist")
            elif layer_of(d) > layer_of(m) and (m, d) not in ALLOWED_EXCEPTIONS:
                bad.append(f"{m}:{line} (layer {layer_of(m)}) imports {d} (layer {layer_of(d)})")
            for src, dst, why in FORBIDDEN:
                if _under(m, src) and _under(d, dst) and (m, d) not in ALLOWED_EXCEPTIONS:
                    bad.append(f"{m}:{line} imports {d}: {why}")
    assert not bad, "\n".join(bad)


#: modules allowed to call print(): the command-line front ends, and (listed with the reason) others
PRINT_ALLOWED_SUFFIX = ".cli"
PRINT_EXCEPTIONS: set[str] = set()


@pytest.mark.slow
def test_library_code_does_not_print():
    """Library code reports through logging (receiver.logs); only the CLI modules print."""
    bad = []
    for m, path in all_modules().items():
        if m == "receiver.cli" or m.endswith(PRINT_ALLOWED_SUFFIX) or m in PRINT_EXCEPTIONS:
            continue
        tree = ast.parse(path.read_text(), str(path))
        called = {id(n.func) for n in ast.walk(tree) if isinstance(n, ast.Call)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "print":
                bad.append(f"{m}:{node.lineno} calls print()")
            if (isinstance(node, ast.Attribute) and node.attr in ("redirect_stdout", "redirect_stderr")):
                bad.append(f"{m}:{node.lineno} redirects a process-wide stream")
            elif isinstance(node, ast.Name) and node.id == "print" and id(node) not in called:
                bad.append(f"{m}:{node.lineno} uses print as a callable (e.g. log=print)")
    assert not bad, "\n".join(sorted(set(bad)))


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):                      # recursion depth is bounded by the module count (~100)
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            out.append(comp)

    for v in graph:
        if v not in index:
            visit(v)
    return out


@pytest.mark.slow
def test_no_import_cycles():
    _, graph = _graph()
    edges = {m: {d for d, _ in deps if d != m} for m, deps in graph.items()}
    cycles = [sorted(c) for c in strongly_connected(edges) if len(c) > 1]
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_cycle_detector_finds_a_cycle():
    """The detector itself: a 3-cycle and a self-contained chain."""
    comps = strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}})
    assert sorted(map(sorted, comps)) == [["a", "b", "c"], ["d"]]


def test_layer_rule_sees_an_upward_import(tmp_path):
    """The import parser resolves relative imports at any depth, inside functions too."""
    modules = {"receiver.gnss.x": None, "receiver.tracking.scalar": None, "receiver.tracking": None}
    src = tmp_path / "x.py"
    src.write_text("def f():\n    from ..tracking import scalar\n")
    deps = imports_of("receiver.gnss.x", src, modules)
    assert deps == [("receiver.tracking.scalar", 2)]
    assert layer_of("receiver.tracking.scalar") > layer_of("receiver.gnss.x")
