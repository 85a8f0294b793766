"""MkDocs hook: the page reference/cli.md gets the command-line reference generated from the
argument parsers (`problems.commands.reference.cli_reference`) in place of its marker."""

from __future__ import annotations

MARKER = "<!-- generated: mixvi command-line reference -->"


def on_page_markdown(markdown: str, page, **kwargs) -> str:
    """The generated reference in place of MARKER (other pages unchanged)."""
    if MARKER not in markdown:
        return markdown
    from problems.commands.reference import cli_reference

    return markdown.replace(MARKER, cli_reference())
