"""The manual (docs/ with mkdocs.yml) builds with MkDocs in strict mode: a broken link, a
missing anchor, a page left out of the navigation or an API reference that no longer imports
fails the build, and so this test. Skipped where MkDocs is not installed (it comes with the
[test] and [docs] extras)."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mkdocs")
pytest.importorskip("mkdocstrings")

ROOT = Path(__file__).resolve().parents[1]


def _build(config: Path, site: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config), "-d", str(site)],
        capture_output=True,
        text=True,
        timeout=600,
    )


def _copy(tmp_path: Path) -> Path:
    """The manual copied to `tmp_path` (its API reference still read from the repository)."""
    shutil.copytree(ROOT / "docs", tmp_path / "docs")
    text = (ROOT / "mkdocs.yml").read_text().replace("paths: [.]", f"paths: [{ROOT}]")
    (tmp_path / "mkdocs.yml").write_text(text)
    return tmp_path / "mkdocs.yml"


def test_the_manual_builds_without_a_warning(tmp_path):
    r = _build(ROOT / "mkdocs.yml", tmp_path / "site")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "site" / "reference" / "vi_core" / "index.html").exists()
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    assert "usage: mixvi sweep" in cli and "generated: mixvi" not in cli  # the hook ran


@pytest.mark.slow  # four builds (~4 s each): the mutation tier
@pytest.mark.parametrize(
    "fault",
    ["a broken link", "a missing anchor", "a page outside the navigation", "a vanished API name"],
)
def test_a_fault_in_the_manual_fails_the_build(tmp_path, fault):
    """Mutations: each fault the strict build is meant to catch, injected into a copy."""
    config = _copy(tmp_path)
    docs = tmp_path / "docs"
    if fault == "a broken link":
        with open(docs / "index.md", "a") as f:
            f.write("\nSee [nowhere](nowhere.md).\n")
    elif fault == "a missing anchor":
        with open(docs / "index.md", "a") as f:
            f.write("\nSee [a section](design.md#no-such-section).\n")
    elif fault == "a page outside the navigation":
        (docs / "orphan.md").write_text("# Orphan\n")
    else:
        with open(docs / "reference" / "fem.md", "a") as f:
            f.write("\n::: fem.no_such_module\n")
    r = _build(config, tmp_path / "site")
    assert r.returncode != 0, f"{fault} passed the strict build"
