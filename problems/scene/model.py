"""The typed scene model (pydantic v2): the whole scene validated before anything is built.

A scene file is read (`problems.scene.reader`), migrated to the current FORMAT, its `--set`
overrides applied, and then validated in one go by its plug-in's scene model (a subclass of
`SceneModel`, the plug-in's `SCENE_MODEL`): unknown keys, types, ranges and cross-references
(body and boundary names, materials). Plug-ins build from the validated model only.

`validate` turns the first pydantic error into a SceneError naming the dotted field path
(`bodies.block.geometry.cells`), the value, what is allowed and, when a `--set` override
caused it, the override. Validation errors of the model's own checks (cross-references) are
raised with `refuse(field, value, allowed)`.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from problems.errors import SceneError

from .fields import Expression, Integer, Number, Text

FORMAT = 2  # the current scene format; format 1 (no `format` key) is migrated on loading
MAX_LEVEL = 12
METHODS = ("auto", "ssn", "conic", "homotopy")  # vi_core.METHODS (a test keeps them equal)


def did_you_mean(word: str, options: Iterable[str]) -> str:
    """' (did you mean 'x'?)' for the closest of `options`, else ''."""
    hint = difflib.get_close_matches(str(word), list(options), n=1)
    return f" (did you mean {hint[0]!r}?)" if hint else ""


def refuse(field: Sequence[str | int], value: Any, allowed: str) -> PydanticCustomError:
    """The error a model's own check raises: `field` relative to the model it checks."""
    return PydanticCustomError(
        "scene_value", "{allowed}", {"field": list(field), "value": value, "allowed": allowed}
    )


class Section(BaseModel):
    """A table of a scene: unknown keys are refused with a did-you-mean and the known keys."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)
    _path: str = PrivateAttr("")

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if isinstance(data, dict):
            known = [f.alias or n for n, f in cls.model_fields.items()]
            for k in data:
                if k not in known:
                    raise PydanticCustomError(
                        "unknown_key",
                        "unknown key{hint}; allowed keys here: {known}",
                        {"key": k, "hint": did_you_mean(k, known), "known": ", ".join(known)},
                    )
        return data

    def key(self, name: str) -> str:
        """The dotted scene path of this table's key `name` (for errors raised while building)."""
        return f"{self._path}.{name}" if self._path else name


Level = Annotated[Integer, Field(ge=0, le=MAX_LEVEL)]


class Head(Section):
    """The [scene] table. Plug-ins subclass it (`head(NAME, default_level)`)."""

    title: Text = ""
    description: Text = ""
    plugin: Text
    level: Level = 1


def head(name: str, default_level: int) -> type[Head]:
    """The [scene] table of plug-in `name`: plugin = NAME, level defaults to `default_level`."""
    from pydantic import create_model

    return create_model(
        f"Head_{name}",
        __base__=Head,
        plugin=(Literal[name], Field(description="the plug-in this scene is for")),
        level=(Level, Field(default_level, description="default refinement level")),
    )


class Solver(Section):
    """The optional [solver] table: method and tolerance (each only if given)."""

    method: Literal[METHODS] | None = None
    tol: Annotated[Number, Field(gt=0.0, lt=1.0)] | None = None

    def options(self) -> dict:
        """{"method": ..., "tol": ...} with the keys given."""
        return {k: v for k, v in (("method", self.method), ("tol", self.tol)) if v is not None}


class SceneModel(Section):
    """The root of a scene: format, [scene], [solver]; plug-ins add their sections."""

    format: Literal[2] = Field(description="the scene format (2)")
    scene: Head
    solver: Solver | None = None

    def options(self) -> dict:
        """Solver options from the scene (only the keys it gives)."""
        return self.solver.options() if self.solver is not None else {}


def one_or_many(v: Any) -> Any:
    """A single table where an array of tables is expected counts as an array of one."""
    return [v] if isinstance(v, dict) else v


# ------------------------------------------------------------------ validation and errors
def validate(
    cls: type[Section],
    data: dict,
    file: str | None = None,
    overrides: dict[str, str] | None = None,
    prefix: tuple[str | int, ...] = (),
) -> Section:
    """`data` validated by `cls`, every expression told its field path (SceneError naming the
    field, the value, what is allowed and the override that caused it, if one did). `prefix`:
    where `data` sits in the scene when `cls` is one section (e.g. ("exact",))."""
    try:
        model = cls.model_validate(data, context={"file": file})
    except ValidationError as err:
        e = err.errors()[0]
        e = {**e, "loc": (*prefix, *e["loc"])}
        root = data
        for p in reversed(prefix):
            root = {p: root}
        raise _scene_error(e, root, file, overrides or {}) from None
    assign_paths(model, path_text(prefix))
    return model


def path_text(loc: Sequence[str | int]) -> str:
    """('bodies', 'b', 'displacement', 0, 'value') → 'bodies.b.displacement[0].value'."""
    out = ""
    for p in loc:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def _at(data: Any, loc: Sequence[str | int]) -> Any:
    for p in loc:
        try:
            data = data[p]
        except (KeyError, IndexError, TypeError):
            return None
    return data


# (field, tag) of tagged unions (geometry and material kinds): pydantic puts the tag into an
# error's loc after the field; it is not a key of the scene
UNION_TAGS: set[tuple[str, str]] = set()


def _clean(loc: Sequence[str | int]) -> list[str | int]:
    """Pydantic's loc without the tags it inserts for tagged unions and function validators."""
    out: list[str | int] = []
    for p in loc:
        if isinstance(p, str) and p.startswith("function-"):
            continue
        if out and isinstance(p, str) and (out[-1], p) in UNION_TAGS:
            continue
        out.append(p)
    return out


def _allowed(e: dict) -> str:
    t, ctx = e["type"], e.get("ctx") or {}
    if t in ("unknown_key", "scene_value", "expression", "number", "integer", "string"):
        return e["msg"]
    simple = {
        "greater_than": f"a number > {ctx.get('gt')}",
        "greater_than_equal": f"a number ≥ {ctx.get('ge')}",
        "less_than": f"a number < {ctx.get('lt')}",
        "less_than_equal": f"a number ≤ {ctx.get('le')}",
        "missing": "required",
        "model_type": "a table",
        "model_attributes_type": "a table",
        "dict_type": "a table",
        "list_type": "a list",
        "too_short": f"a list of {ctx.get('min_length')} or more entries",
        "too_long": f"a list of {ctx.get('max_length')} or fewer entries",
    }
    if t in simple:
        return simple[t]
    if t == "literal_error":
        expected = ctx.get("expected", "")
        value = e.get("input")
        names = [s.strip().strip("'") for s in expected.replace(" or ", ", ").split(",")]
        return f"one of {', '.join(names)}{did_you_mean(value, names)}"
    return e["msg"]


def _scene_error(e: dict, data: dict, file: str | None, overrides: dict[str, str]) -> SceneError:
    loc = _clean(e["loc"])
    ctx = e.get("ctx") or {}
    value = e.get("input")
    t = e["type"]
    if t == "unknown_key":
        loc.append(ctx["key"])
        value = _at(data, loc)
    elif t == "scene_value":
        loc += ctx["field"]
        value = ctx["value"]
    elif t in ("union_tag_invalid", "union_tag_not_found"):
        loc.append("kind")
        value = _at(data, loc)
        msg = "one of " + ctx.get("expected_tags", "")
        return _with_override(SceneError(path_text(loc), value, msg, file), loc, overrides)
    elif t == "missing":
        value = None
    if isinstance(value, dict | list) and t not in ("unknown_key", "scene_value"):
        shown = _at(data, loc)
        value = shown if shown is not None else value
    return _with_override(SceneError(path_text(loc), value, _allowed(e), file), loc, overrides)


def _with_override(err: SceneError, loc: list, overrides: dict[str, str]) -> SceneError:
    path = path_text(loc)
    for key, text in overrides.items():
        if path == key or path.startswith(key + ".") or path.startswith(key + "["):
            return SceneError(err.key, err.value, f"{err.allowed} (set by --set {text})", err.file)
        if key.startswith(path + "."):  # the override made a table invalid
            return SceneError(err.key, err.value, f"{err.allowed} (after --set {text})", err.file)
    return err


def assign_paths(obj: Any, path: str) -> None:
    """Tell every table and expression of a validated model its dotted scene path."""
    if isinstance(obj, Expression):
        obj.path = path
    elif isinstance(obj, BaseModel):
        if isinstance(obj, Section):
            obj._path = path
        for name, f in type(obj).model_fields.items():
            key = f.alias or name
            assign_paths(getattr(obj, name), f"{path}.{key}" if path else key)
    elif isinstance(obj, list | tuple):
        for i, v in enumerate(obj):
            assign_paths(v, f"{path}[{i}]")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            assign_paths(v, f"{path}.{k}" if path else str(k))


# ------------------------------------------------------------------ format migration
def migrate(data: dict, file: str) -> tuple[dict, list[str]]:
    """A scene's data in the current FORMAT, and the notices about what was migrated.

    Format 1 (no `format` key, or `format = 1`): `[scene] plugin` defaulted to piezo_contact.
    Format 2 adds `format = 2` and requires `plugin`. Other formats are refused.
    """
    fmt = data.get("format", 1)
    if fmt == FORMAT and not isinstance(fmt, bool):
        return data, []
    if fmt != 1 or isinstance(fmt, bool):
        raise SceneError("format", fmt, f"{FORMAT} (the current scene format)", file)
    out = {k: v for k, v in data.items() if k != "format"}
    head_ = out.get("scene")
    if isinstance(head_, dict) and "plugin" not in head_:
        out["scene"] = {**head_, "plugin": "piezo_contact"}
    notice = (
        f"{file}: a format-1 scene (deprecated), read through the migration to format {FORMAT}; "
        f"add `format = {FORMAT}` at its top and `plugin = ...` under [scene] to update it"
    )
    return {"format": FORMAT, **out}, [notice]


# ------------------------------------------------------------------ JSON Schema
def json_schema(models: dict[str, type[SceneModel]]) -> dict:
    """The JSON Schema of scenes: one of the plug-ins' scene models (by `[scene] plugin`)."""
    from pydantic.json_schema import models_json_schema

    refs, defs = models_json_schema([(m, "validation") for m in models.values()])
    defs = _standard_bounds(defs)
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "mixvi scene",
        "description": f"A mixvi scene (format {FORMAT}); `[scene] plugin` picks the section "
        "model of one plug-in: " + ", ".join(models),
        "oneOf": [refs[(m, "validation")] for m in models.values()],
        **defs,
    }


_BOUNDS = {"ge": "minimum", "gt": "exclusiveMinimum", "le": "maximum", "lt": "exclusiveMaximum"}


def _standard_bounds(node: Any) -> Any:
    """Pydantic writes a bound it could not fold into the type (our numbers are checked by a
    validator first) as "ge"/"gt"/"le"/"lt": the JSON Schema keywords are minimum etc."""
    if isinstance(node, dict):
        typed = node.get("type") in ("number", "integer")
        return {
            (_BOUNDS[k] if typed and k in _BOUNDS else k): _standard_bounds(v)
            for k, v in node.items()
        }
    if isinstance(node, list):
        return [_standard_bounds(v) for v in node]
    return node
