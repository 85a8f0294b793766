"""The manual (docs/) states what is there: every code name it cites in backticks
(`vi_core.…`, `fem.…`, `problems.…`) imports, no former plug-in name is cited as a module
(`piezo_contact.…`, `contact3d.…`: they are aliases of the scene's `plugin` key only), and no
page carries an issue number (history lives in git), nor does any comment or docstring of the
installed packages (vi_core, fem, problems). docs/scenes.md is generated (`mixvi schema
--markdown`) and left out. The mutation tests inject each fault into a copy of a page's text or
of a module's source and see it found."""

from __future__ import annotations

import ast
import importlib
import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GENERATED = {"scenes.md"}
PAGES = sorted(
    p
    for p in [*ROOT.glob("docs/*.md"), *ROOT.glob("docs/tutorials/*.md")]
    if p.name not in GENERATED
)
ROOTS = ("vi_core", "fem", "problems")
RETIRED = ("piezo_contact", "contact3d")  # plug-in names kept as scene aliases, not modules
PREFIXES = "|".join(ROOTS + RETIRED)
CODE_NAME = re.compile(rf"`((?:{PREFIXES})(?:\.[A-Za-z_]\w*)+)(?=[`(\[ ,])")
ISSUE = re.compile(r"\bissues? #?\d+|#\d+\b", re.I)  # issue 30, issues 29, (#42), #27
MODULES = sorted(p for root in ROOTS for p in (ROOT / root).rglob("*.py"))


def _resolves(dotted: str) -> bool:
    """Whether `dotted` is an importable module, or attributes reached from the longest
    importable prefix."""
    parts = dotted.split(".")
    if parts[0] in RETIRED:
        return False
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def _cited(text: str) -> list[tuple[int, str]]:
    """(line, name) of each backticked code name of the page, except the first two columns of
    a table whose header has an "old name" column (a list of renamed code, old → new)."""
    out, old_table = [], False
    for n, line in enumerate(text.splitlines(), 1):
        if not line.startswith("|"):
            old_table = False
        elif not old_table and "old name" in line.lower():
            old_table = True
        cells = line.split("|")
        checked = "|".join(cells[3:]) if old_table and len(cells) > 3 else line
        out += [(n, m.group(1)) for m in CODE_NAME.finditer(checked)]
    return out


def unresolved(text: str) -> list[tuple[int, str]]:
    """(line, name) of the cited code names that do not import."""
    return [(n, name) for n, name in _cited(text) if not _resolves(name)]


def issue_numbers(text: str) -> list[tuple[int, str]]:
    return [
        (n, m.group(0)) for n, line in enumerate(text.splitlines(), 1) for m in ISSUE.finditer(line)
    ]


def comments_and_docstrings(source: str) -> list[tuple[int, str]]:
    """(first line, text) of each comment (its # dropped) and each docstring (module, class,
    function) of a module's source."""
    tokens = tokenize.generate_tokens(io.StringIO(source).readline)
    out = [(t.start[0], t.string[1:]) for t in tokens if t.type == tokenize.COMMENT]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            doc = ast.get_docstring(node, clean=False)
            if doc is not None:
                out.append((node.body[0].lineno, doc))
    return out


def issues_in_code(source: str) -> list[tuple[int, str]]:
    """(line, match) of each issue number in a comment or docstring of a module's source."""
    return sorted(
        (first + n - 1, found)
        for first, text in comments_and_docstrings(source)
        for n, found in issue_numbers(text)
    )


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT / "docs")))
def test_every_cited_code_name_exists(page):
    assert unresolved(page.read_text()) == []


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT / "docs")))
def test_no_page_carries_an_issue_number(page):
    assert issue_numbers(page.read_text()) == []


def test_the_pages_cite_code_names():
    """The check has something to check: the pages cite code names, and they resolve."""
    cited = [name for p in PAGES for _, name in _cited(p.read_text())]
    assert len(cited) > 100
    assert "fem.mortar.mortar_coupling" in cited


@pytest.mark.parametrize(
    "name",
    [
        "fem.mortar.no_such_function",  # a made-up function of a real module
        "problems.plugins.contact.no_such_module",  # a made-up module
        "contact3d.incremental",  # a former plug-in cited as a module
        "piezo_contact.build",
    ],
)
def test_a_made_up_name_is_found(name):
    """Mutation: a name that does not exist, written into a copy of a page, is reported."""
    page = ROOT / "docs" / "fem3d.md"
    text = page.read_text() + f"\nThe rows are built by `{name}`.\n"
    assert unresolved(text) == [(len(text.splitlines()), name)]


def test_a_made_up_name_in_the_new_column_of_a_rename_table_is_found():
    """Mutation: in a table of renamed code the old names are exempt, the new ones are not."""
    table = (
        "| old module | old name | now |\n|---|---|---|\n"
        "| `fem.mesh3d` | `Mesh3D` | `fem.mesh.Mesh3D` |\n"
    )
    assert unresolved(table) == [(3, "fem.mesh.Mesh3D")]
    assert unresolved(table.replace("fem.mesh.Mesh3D", "fem.mesh.Mesh")) == []


@pytest.mark.parametrize(
    "fault", ["# 3D dual mortar (issue 18, item 3)", "since issue 30's rewrite", "(#42)"]
)
def test_an_issue_number_is_found(fault):
    """Mutation: an issue number written into a copy of a page is reported."""
    text = (ROOT / "docs" / "fem3d.md").read_text() + f"\n{fault}\n"
    assert len(issue_numbers(text)) == 1


def test_no_comment_or_docstring_of_the_packages_carries_an_issue_number():
    found = {
        str(p.relative_to(ROOT)): hits for p in MODULES if (hits := issues_in_code(p.read_text()))
    }
    assert found == {}


def test_the_packages_have_comments_and_docstrings_to_check():
    """The check has something to check: every package's modules, their docstrings and
    comments."""
    assert {p.relative_to(ROOT).parts[0] for p in MODULES} == set(ROOTS)
    read = [comments_and_docstrings(p.read_text()) for p in MODULES]
    assert sum(map(len, read)) > 2000


@pytest.mark.parametrize(
    ("line", "fault"),
    [
        (0, '"""Tresca everywhere (issue 30)."""'),  # the module docstring, replaced
        (1, "x = 1  # since issue 17"),  # a comment after code
        (1, "# see #27"),  # a comment line
        (2, 'def f():\n    """As (#33) asked."""'),  # a function's docstring
        (2, 'class C:\n    """Issues 29 and 31."""'),  # a class's docstring
    ],
)
def test_an_issue_number_in_code_is_found(line, fault):
    """Mutation: an issue number written into a copy of a module's source, in place of its
    docstring (line 0: reported at line 1) or `line` lines after it, is reported at its
    line."""
    source = (ROOT / "fem" / "mortar.py").read_text()
    _, doc, rest = source.split('"""', 2)
    end = doc.count("\n") + 1  # the docstring's last line
    if line == 0:
        mutated, expected = fault + rest, 1
    else:
        mutated, expected = f'"""{doc}"""\n{fault}{rest}', end + line
    assert issues_in_code(source) == []
    assert [n for n, _ in issues_in_code(mutated)] == [expected]
