"""The documentation lives in the repository: every relative link resolves, and no text file
points to design notes outside it."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SOURCES = [
    p
    for pattern in ("*.py", "*.md", "*.toml")
    for p in ROOT.rglob(pattern)
    if not any(part.startswith(".") or part.endswith(".egg-info") for part in p.parts)
    and p != Path(__file__).resolve()
]
OUTSIDE = re.compile(r"DESIGN\.md|/work/shared")


def _links(path: Path) -> list[str]:
    text = path.read_text()
    return [m for m in re.findall(r"\]\(([^)#\s]+)", text) if "://" not in m]


def test_the_design_document_exists_and_is_linked_from_the_readme():
    assert (ROOT / "docs" / "design.md").is_file()
    assert "docs/design.md" in _links(ROOT / "README.md")


def test_every_relative_link_in_the_docs_resolves():
    broken = [
        f"{p.relative_to(ROOT)} → {link}"
        for p in DOCS
        for link in _links(p)
        if not (p.parent / link).exists()
    ]
    assert broken == []


def test_nothing_points_outside_the_repository():
    hits = [
        f"{p.relative_to(ROOT)}:{i + 1}"
        for p in SOURCES
        for i, line in enumerate(p.read_text(errors="replace").splitlines())
        if OUTSIDE.search(line)
    ]
    assert hits == []


def test_mutation_a_reference_outside_is_found(tmp_path):
    bad = tmp_path / "x.py"
    bad.write_text('"""See DESIGN.md §6."""\n')
    assert OUTSIDE.search(bad.read_text())
