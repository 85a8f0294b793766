"""The manual's command-line reference is generated from the parsers: every command's section
holds its usage and every option its --help lists."""

from __future__ import annotations

import re

from problems.commands import reference
from problems.commands.main import COMMANDS, parser


def _options(text: str) -> set[str]:
    return set(re.findall(r"^\s+(--[a-z][a-z0-9-]*)", text, re.M))


def test_every_command_has_a_section_with_its_usage_and_options():
    doc = reference.cli_reference()
    sections = re.split(r"^## mixvi ", doc, flags=re.M)
    assert [s.split("\n", 1)[0] for s in sections[1:]] == list(COMMANDS)
    for name, body in zip(COMMANDS, sections[1:], strict=True):
        assert f"usage: mixvi {name}" in body, name
    solve = parser()._subparsers._group_actions[0].choices["solve"]
    declared = {o for a in solve._actions for o in a.option_strings if o.startswith("--")}
    assert declared - {"--help"} <= _options(sections[1])  # every option of solve


def test_the_help_is_formatted_at_the_reference_width(monkeypatch):
    monkeypatch.setenv("COLUMNS", "40")
    text = reference.help_text(["solve"])
    assert max(len(ln) for ln in text.splitlines()) > 40  # not the caller's terminal
    assert max(len(ln) for ln in text.splitlines()) <= int(reference.WIDTH)
    assert reference.os.environ["COLUMNS"] == "40"  # restored


def test_mutation_a_command_left_out_is_caught(monkeypatch):
    monkeypatch.setattr(reference, "COMMANDS", {k: v for k, v in COMMANDS.items() if k != "new"})
    sections = re.split(r"^## mixvi ", reference.cli_reference(), flags=re.M)
    assert [s.split("\n", 1)[0] for s in sections[1:]] != list(COMMANDS)
