"""`mixvi schema`: the JSON Schema of scenes (every installed plug-in's scene model), for
editors that complete and check TOML/JSON scenes (`mixvi validate` checks one scene:
problems.commands.validate)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from problems.plugins import registry
from problems.scene.model import json_schema
from problems.scene.reader import toml_key, toml_literal


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


def _fits(spec: dict, data: Any, defs: dict) -> bool:
    """Whether `data` (a table) can be an instance of the model `spec`: its required keys
    present, no key it does not know, its constant keys (a `kind`) equal (a union: one of
    its models)."""
    if "anyOf" in spec or "oneOf" in spec:
        subs = spec.get("anyOf", spec.get("oneOf"))
        return any(_fits(defs.get(x["$ref"].rsplit("/", 1)[-1], {}), data, defs) for x in subs)
    props = spec.get("properties")
    if not isinstance(data, dict) or not props:
        return False
    if not set(spec.get("required", [])) <= set(data) or not set(data) <= set(props):
        return False
    return all(
        data[k] == sub["const"] or data[k] in sub.get("enum", [data[k]])
        for k, sub in props.items()
        if k in data and "const" in sub
    )


def collect_examples(schema: dict, data: Any, path: tuple, found: dict, spec: dict) -> None:
    """Walk a scene's `data` along the schema node `spec`; the first table met for each model
    of $defs goes into `found` as (its TOML path, the table; path parts are keys, and "[]"
    after a key marks an array of tables)."""
    defs = schema.get("$defs", {})
    if "$ref" in spec:
        name = spec["$ref"].rsplit("/", 1)[-1]
        target = defs.get(name, {})
        if isinstance(data, dict) and target.get("properties") and name not in found:
            found[name] = (path, data)
        collect_examples(schema, data, path, found, target)
        return
    for key in ("anyOf", "oneOf"):
        if key in spec:
            subs = spec[key]
            refs = [x for x in subs if "$ref" in x]
            fit = [x for x in refs if _fits(defs.get(x["$ref"].rsplit("/", 1)[-1], {}), data, defs)]
            for sub in fit[:1] or [x for x in subs if "$ref" not in x]:
                collect_examples(schema, data, path, found, sub)
            return
    if isinstance(data, dict) and spec.get("properties"):
        for k, v in data.items():
            if k in spec["properties"]:
                collect_examples(schema, v, (*path, k), found, spec["properties"][k])
    elif isinstance(data, dict) and isinstance(spec.get("additionalProperties"), dict):
        for k, v in data.items():
            collect_examples(schema, v, (*path, k), found, spec["additionalProperties"])
    elif isinstance(data, list) and isinstance(spec.get("items"), dict):
        for v in data:
            collect_examples(schema, v, (*path, "[]"), found, spec["items"])


def shipped_examples(schema: dict) -> dict[str, tuple[str, tuple, dict]]:
    """Per model of $defs, its first table in the shipped scenes (in name order): (scene
    name, TOML path, table)."""
    import tomllib

    from problems.scene import SCENES_DIR, load_scene

    found: dict[str, tuple[str, tuple, dict]] = {}
    for f in sorted(SCENES_DIR.glob("*.toml")):
        data = tomllib.loads(f.read_text())
        model = registry.for_scene(load_scene(str(f))).SCENE_MODEL.__name__
        mine: dict = {}
        collect_examples(schema, data, (), mine, {"$ref": f"#/$defs/{model}"})
        for name, (path, table) in mine.items():
            found.setdefault(name, (f.stem, path, table))
    return found


def example_block(scene: str, path: tuple, table: dict) -> list[str]:
    """A model's example as Markdown: the table under its TOML header, from which scene."""
    if not path:
        return []
    array = path[-1] == "[]"
    parts = [p for p in path if p != "[]"]
    header = ".".join(toml_key(p) for p in parts)
    head = f"[[{header}]]" if array else f"[{header}]"
    body = [f"{toml_key(k)} = {toml_literal(v)}" for k, v in table.items()]
    return [f"Example (from the shipped scene `{scene}`):", "", "```toml", head, *body, "```", ""]


def scene_reference(schema: dict) -> str:
    """The scene reference (Markdown) generated from the JSON Schema: one section per model,
    one row per key with its type, default, allowed range and description, and an example
    from a shipped scene where one uses the model (`shipped_examples`)."""
    examples = shipped_examples(schema)
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
        if name in examples:
            lines += example_block(*examples[name])
    return "\n".join(lines)
