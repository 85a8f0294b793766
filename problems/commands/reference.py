"""The command-line reference of the manual (docs/reference/cli.md), generated from the
argument parsers themselves: `mixvi --help` and `mixvi COMMAND --help` of every command, as a
terminal 100 columns wide shows them. The manual's build puts it into the page
(docs/hooks/cli_reference.py), so the page cannot fall behind the parsers."""

from __future__ import annotations

import contextlib
import io
import os

from .main import COMMANDS, _dispatch

WIDTH = "100"  # the terminal width the help is formatted for


def help_text(argv: list[str]) -> str:
    """What `mixvi ARGV --help` prints (argparse's help, formatted WIDTH columns wide)."""
    out = io.StringIO()
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            _dispatch([*argv, "--help"])
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return out.getvalue().rstrip() + "\n"


def cli_reference() -> str:
    """The reference in Markdown: the command list, then one section per command (its
    one-line purpose and its full help)."""
    parts = ["```text", help_text([]).rstrip(), "```", ""]
    for name, purpose in COMMANDS.items():
        parts += [f"## mixvi {name}", "", purpose[0].upper() + purpose[1:] + ".", ""]
        parts += ["```text", help_text([name]).rstrip(), "```", ""]
    return "\n".join(parts)
