"""`mixvi schema`: the JSON Schema of scenes (every installed plug-in's scene model), for
editors that complete and check TOML/JSON scenes (`mixvi validate` checks one scene:
problems.commands.validate)."""

from __future__ import annotations

import argparse
import json
import sys

from problems.plugins import registry
from problems.scene.model import json_schema


def scene_schema() -> dict:
    """The JSON Schema of the scenes of every installed plug-in."""
    return json_schema({name: p.SCENE_MODEL for name, p in registry.plugins().items()})


def cmd_schema(args: argparse.Namespace) -> int:
    """Print the JSON Schema of scenes (or, with --markdown, the scene reference from it)."""
    schema = scene_schema()
    if getattr(args, "markdown", False):
        sys.stdout.write(scene_reference(schema))
    else:
        sys.stdout.write(json.dumps(schema, indent=2, ensure_ascii=False) + "\n")
    return 0


def _type(spec: dict) -> str:
    """A schema node as a short type text (links to the sections of referenced models)."""
    if "$ref" in spec:
        name = spec["$ref"].rsplit("/", 1)[-1]
        return f"[{name}](#{name.lower()})"
    if "const" in spec:
        return f"`{json.dumps(spec['const'], ensure_ascii=False)}`"
    if "enum" in spec:
        return " or ".join(f"`{json.dumps(v, ensure_ascii=False)}`" for v in spec["enum"])
    for key in ("anyOf", "oneOf"):
        if key in spec:
            return " or ".join(_type(s) for s in spec[key] if s.get("type") != "null")
    if spec.get("type") == "array":
        items = spec.get("items")
        inner = _type(items) if isinstance(items, dict) else "value"
        n = spec.get("minItems")
        size = f"{n} × " if n is not None and n == spec.get("maxItems") else ""
        return f"list of {size}{inner}"
    if spec.get("type") == "object" and isinstance(spec.get("additionalProperties"), dict):
        return f"table of {_type(spec['additionalProperties'])}"
    return str(spec.get("type", "any"))


def _allowed(spec: dict) -> str:
    bounds = [
        ("minimum", "≥"),
        ("exclusiveMinimum", ">"),
        ("maximum", "≤"),
        ("exclusiveMaximum", "<"),
    ]
    out = [f"{sym} {spec[k]:g}" for k, sym in bounds if isinstance(spec.get(k), int | float)]
    for key in ("anyOf", "oneOf"):
        for sub in spec.get(key, []):
            out += [f"{sym} {sub[k]:g}" for k, sym in bounds if isinstance(sub.get(k), int | float)]
    return ", ".join(out)


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def scene_reference(schema: dict) -> str:
    """The scene reference (Markdown) generated from the JSON Schema: one section per model,
    one row per key with its type, default, allowed range and description."""
    lines = [
        "# Scene reference",
        "",
        "Generated from the JSON Schema of scenes by `mixvi schema --markdown` (do not edit by",
        "hand; `tests/problems/commands/test_schema.py` checks that this file is current).",
        "",
        _cell(schema.get("description", "")),
        "",
        "Plug-in scene models: "
        + ", ".join(_type(s) for s in schema.get("oneOf", []))
        + ". Units: SI (m, Pa, V, C) unless a scene says otherwise; expressions are text.",
        "",
    ]
    for name, spec in sorted(schema.get("$defs", {}).items()):
        lines += [f"## {name}", ""]
        if spec.get("description"):
            lines += [_cell(spec["description"]), ""]
        props = spec.get("properties")
        if not props:
            lines += [f"Type: {_type(spec)}", ""]
            continue
        required = set(spec.get("required", []))
        lines += ["| key | type | default | allowed | description |", "|---|---|---|---|---|"]
        for key, sub in props.items():
            default = (
                "required"
                if key in required
                else f"`{json.dumps(sub['default'], ensure_ascii=False)}`"
                if "default" in sub
                else ""
            )
            lines.append(
                f"| `{key}` | {_cell(_type(sub))} | {_cell(default)} | {_cell(_allowed(sub))} "
                f"| {_cell(sub.get('description', ''))} |"
            )
        lines.append("")
    return "\n".join(lines)
