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

The rooms (issue 30): no module is named for a dimension (`…3d`: one code serves 2D and 3D), a
plug-in's modules live in its own subpackage of problems/plugins rather than side by side under
a name prefix (`piezo_*`), and tests/ mirrors the folders of the code it tests.

The installed packages hold no research scripts: a module runnable as `python -m` (an
`if __name__ == "__main__":` block) is the `mixvi` command or a generator of a shipped scene
(SCRIPTS); measurements and studies live in benchmarks/, which none of the packages imports
(nor tests/).
"""

from __future__ import annotations

import ast
import functools
from collections.abc import Iterable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("vi_core", "fem", "problems")
# the modules of the packages that may run as `python -m`: the mixvi command, and the generators
# of shipped scenes (their output is a file in problems/scenes)
SCRIPTS = {
    "problems.commands.main",
    "problems.commands.entry",
    "problems.scene.manufactured",
    "problems.scene.manufactured_unilateral",
}
OUTSIDE = ("benchmarks", "tests")  # never imported by the packages
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


def graph() -> dict[str, frozenset[str]]:
    """module → the project modules it imports (names that are packages or modules); a fresh
    dict each call (a test may add edges), the files parsed once per process."""
    return dict(_graph())


@functools.cache
def _graph() -> dict[str, frozenset[str]]:
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
        g[module_name(p)] = frozenset(targets)
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


def _package_files() -> list[Path]:
    return [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]


def scripts(sources: dict[str, str]) -> set[str]:
    """The modules (name → source) with an `if __name__ == "__main__":` block."""
    out = set()
    for name, text in sources.items():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.If) and isinstance(node.test, ast.Compare):
                sides = [node.test.left, *node.test.comparators]
                if any(isinstance(x, ast.Name) and x.id == "__name__" for x in sides) and any(
                    isinstance(x, ast.Constant) and x.value == "__main__" for x in sides
                ):
                    out.add(name)
    return out


def outside_imports(sources: dict[str, str]) -> list[str]:
    """`module → name` for each import of benchmarks/ or tests/ in the modules (name → source)."""
    bad = []
    for name, text in sources.items():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names = [node.module or ""]
            else:
                continue
            bad += [f"{name} → {n}" for n in names if n.split(".")[0] in OUTSIDE]
    return sorted(bad)


def _sources() -> dict[str, str]:
    return {module_name(p): p.read_text() for p in _package_files()}


def test_the_packages_hold_no_research_scripts():
    assert scripts(_sources()) <= SCRIPTS


def test_the_packages_do_not_import_benchmarks_or_tests():
    assert outside_imports(_sources()) == []


def test_benchmarks_are_not_installed():
    """setuptools finds the three packages only (benchmarks/ and tests/ stay in the repository)."""
    import tomllib

    find = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    assert sorted(find["find"]["include"]) == sorted(f"{p}*" for p in PACKAGES)
    assert (ROOT / "benchmarks" / "bench_ordering.py").is_file()


@pytest.mark.parametrize(
    "text",
    [
        'import sys\n\nif __name__ == "__main__":\n    sys.exit(0)\n',
        "if '__main__' == __name__:\n    pass\n",
    ],
)
def test_a_research_script_in_a_package_is_caught(text):
    """Mutation: a study runnable as `python -m problems.commands.study_x` in the package."""
    sources = {**_sources(), "problems.commands.study_x": text}
    assert "problems.commands.study_x" in scripts(sources) - SCRIPTS


@pytest.mark.parametrize(
    "text",
    [
        "from benchmarks.bench_ordering import VARIANTS\n",
        "def f():\n    import benchmarks.hertz_table\n",
        "from tests.vi_core.newton_systems import lower_vi\n",
    ],
)
def test_an_import_of_benchmarks_is_caught(text):
    sources = {**_sources(), "vi_core.ssn": _sources()["vi_core.ssn"] + text}
    assert outside_imports(sources)


# ---------------------------------------------------------------- the rooms (issue 30)
DATA_DIRS = {"tests/baselines", "tests/data", "tests/thirdparty"}  # no test modules mirrored


def _repo_modules() -> list[Path]:
    return [p for top in (*PACKAGES, *OUTSIDE) for p in (ROOT / top).rglob("*.py")]


def named_3d(paths: Iterable[Path], exempt: tuple[str, ...] = ()) -> list[str]:
    """The modules among `paths` (repository-relative posix paths returned) whose name ends in
    `3d` — a 3D twin of a 2D module — outside the `exempt` folders."""
    out = []
    for p in paths:
        rel = p.relative_to(ROOT).as_posix()
        if p.stem.lower().endswith("3d") and not rel.startswith(exempt):
            out.append(rel)
    return sorted(out)


def prefixed_plugin_modules(names: Iterable[str], exempt: Iterable[str] = ()) -> list[str]:
    """The module names directly in problems/plugins that share a `prefix_` with another one
    (a plug-in's parts side by side instead of in its subpackage), outside `exempt`."""
    names = sorted(names)
    by_prefix: dict[str, list[str]] = {}
    for n in names:
        by_prefix.setdefault(n.split("_")[0], []).append(n)
    return sorted(
        n
        for prefix, group in by_prefix.items()
        if prefix not in exempt and (len(group) > 1 and any("_" in g for g in group))
        for n in group
    )


def _plugin_modules() -> list[str]:
    return [p.stem for p in (ROOT / "problems" / "plugins").glob("*.py") if p.stem != "__init__"]


def unmirrored_test_dirs(test_dirs: Iterable[str]) -> list[str]:
    """The folders of tests/ holding test modules (posix, relative to the repository) that do
    not mirror a folder of the code (tests/fem ↔ fem, tests/problems/scene ↔ problems/scene)."""
    return sorted(
        d
        for d in test_dirs
        if d != "tests" and not (ROOT / d.removeprefix("tests/")).is_dir() and d not in DATA_DIRS
    )


def _test_dirs() -> set[str]:
    return {p.parent.relative_to(ROOT).as_posix() for p in (ROOT / "tests").rglob("test_*.py")}


def test_no_module_is_named_for_3d():
    assert named_3d(_repo_modules()) == []


@pytest.mark.parametrize(
    "rel",
    [
        "fem/mortar3d.py",
        "problems/scene/fields3d.py",
        "vi_core/krylov3d.py",
        "benchmarks/bench_assembly3d.py",
        "tests/fem/test_mesh3d.py",
        "tests/problems/commands/test_check3d.py",
    ],
)
def test_a_module_named_for_3d_is_caught(rel):
    """Mutation: a 3D twin module added anywhere outside the exempt folders."""
    assert named_3d([*_repo_modules(), ROOT / rel]) == [rel]


def test_plugin_modules_live_in_their_subpackage():
    assert prefixed_plugin_modules(_plugin_modules()) == []


def test_plugin_modules_side_by_side_are_caught():
    """Mutation: a plug-in `sheet` with its output beside it (sheet.py, sheet_output.py)."""
    assert prefixed_plugin_modules([*_plugin_modules(), "sheet", "sheet_output"]) == [
        "sheet",
        "sheet_output",
    ]


def test_tests_mirror_the_code():
    assert unmirrored_test_dirs(_test_dirs()) == []


def test_a_test_folder_for_no_code_is_caught():
    """Mutation: tests/problems/solvers (no problems/solvers)."""
    assert unmirrored_test_dirs({*_test_dirs(), "tests/problems/solvers"}) == [
        "tests/problems/solvers"
    ]


def test_the_core_layers_import_nothing_of_ours():
    """vi_core imports neither fem nor problems, fem does not import problems (nor vi_core): the
    table above says so, and an edge from either is caught."""
    assert ALLOWED["vi_core"] == set() and ALLOWED["fem"] == set()
    for a, b in [
        ("vi_core.krylov", "problems.plugins.registry"),
        ("vi_core.sets", "fem.assembly"),
        ("fem.assembly", "problems.scene.materials"),
        ("fem.facets", "vi_core.sets"),
    ]:
        g = graph()
        g[a] = g[a] | {b}
        assert upward(g) == [f"{a} → {b} ({layer(a)} may not import {layer(b)})"]
