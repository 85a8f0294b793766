"""The manual (docs/) states what is there: every code name it cites in backticks
(`vi_core.…`, `fem.…`, `problems.…`) imports, no former plug-in name is cited as a module
(`piezo_contact.…`, `contact3d.…`: they are aliases of the scene's `plugin` key only), and no
page carries an issue number (history lives in git). docs/scenes.md is generated
(`mixvi schema --markdown`) and left out. The mutation tests inject each fault into a copy of
a page's text and see it found."""

from __future__ import annotations

import importlib
import re
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
ISSUE = re.compile(r"\bissues? \d+|\(#\d+\)", re.I)


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
