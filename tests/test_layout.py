"""The package graph: data flows one way, and no module imports upwards or in a cycle.

Layers, lowest first (a module may import its own layer and the layers below it):

    vi_core                      the generic mixed VI layer (imports neither fem nor problems)
    fem                          meshes, spaces, assembly, mortar (does not import problems)
    problems.errors              the input error classes
    problems.scene               scene files, expressions, materials, geometry
    problems.output              writers: files, JSON, plots
    problems.plugins             the contract, the registry, one module per plug-in
    problems.pipeline            scene → validated model → build → solve → results
    problems.commands            the command line, study, bench, extremes
    problems (top-level modules) the Python API

`vi_core` and `fem` are side by side: neither imports the other. Every import counts, including
those inside functions (a lazy import is still a dependency).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("vi_core", "fem", "problems")
# layer name → the layers it may import (besides itself)
ALLOWED = {
    "vi_core": set(),
    "fem": set(),
    "problems.errors": set(),
    "problems.scene": {"problems.errors", "fem"},
    "problems.output": {"problems.errors", "fem"},
    "problems.plugins": {
        "problems.errors",
        "problems.scene",
        "problems.output",
        "fem",
        "vi_core",
    },
    "problems.pipeline": {
        "problems.errors",
        "problems.scene",
        "problems.output",
        "problems.plugins",
        "fem",
        "vi_core",
    },
    "problems.commands": {
        "problems.errors",
        "problems.scene",
        "problems.output",
        "problems.plugins",
        "problems.pipeline",
        "fem",
        "vi_core",
    },
    "problems": {
        "problems.errors",
        "problems.scene",
        "problems.output",
        "problems.plugins",
        "problems.pipeline",
        "problems.commands",
        "fem",
        "vi_core",
    },
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer(module: str) -> str:
    """The layer of a dotted module name (the longest prefix in ALLOWED)."""
    parts = module.split(".")
    for k in range(len(parts), 0, -1):
        if ".".join(parts[:k]) in ALLOWED:
            return ".".join(parts[:k])
    raise KeyError(module)


def imports(path: Path) -> set[str]:
    """Project modules imported anywhere in the file (absolute names)."""
    tree = ast.parse(path.read_text())
    me = module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            names = [mod] + [f"{mod}.{a.name}" for a in node.names]
        else:
            continue
        out |= {n for n in names if n.split(".")[0] in PACKAGES}
    return out


def graph() -> dict[str, set[str]]:
    """module → the project modules it imports (names that are packages or modules)."""
    files = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]
    known = {module_name(p) for p in files}
    g = {}
    for p in files:
        targets = set()
        for name in imports(p):
            # `from a.b import c` names a.b.c: keep it if it is a module, else keep a.b
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name and name != module_name(p):
                targets.add(name)
        g[module_name(p)] = targets
    return g


def upward(g: dict[str, set[str]]) -> list[str]:
    """Edges that import a layer the importer may not import."""
    bad = []
    for a, targets in g.items():
        la = layer(a)
        for b in targets:
            lb = layer(b)
            if lb != la and lb not in ALLOWED[la]:
                bad.append(f"{a} → {b} ({la} may not import {lb})")
    return sorted(bad)


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
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
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def _without_package_inits(g: dict[str, set[str]]) -> dict[str, set[str]]:
    """Drop edges into a package's own `__init__` from inside it (re-exports are not cycles)."""
    return {a: {b for b in t if not a.startswith(b + ".")} for a, t in g.items()}


def test_nothing_imports_upwards():
    assert upward(graph()) == []


def test_no_import_cycles():
    assert cycles(_without_package_inits(graph())) == []


@pytest.mark.parametrize(
    "edge",
    [
        ("vi_core.ssn", "fem.mesh"),
        ("fem.mortar", "problems.errors"),
        ("problems.scene.reader", "problems.plugins.registry"),
        ("problems.output.plots", "problems.commands.main"),
        ("problems.plugins.registry", "problems.commands.solve"),
    ],
)
def test_an_upward_import_is_caught(edge):
    g = graph()
    a, b = edge
    g[a] = g[a] | {b}
    assert upward(g), edge


def test_a_cycle_is_caught():
    g = _without_package_inits(graph())
    g["problems.commands.study"] = g["problems.commands.study"] | {"problems.commands.main"}
    g["problems.commands.main"] = g["problems.commands.main"] | {"problems.commands.study"}
    assert cycles(g)
