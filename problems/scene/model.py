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
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from problems.errors import SceneError

from .fields import NO_LOAD_PATH, Z_IN_2D, Expression, Integer, Number, Text

FORMAT = 2  # the current scene format; format 1 (no `format` key) is migrated on loading
MAX_LEVEL = 12
MAX_STEPS = 1000  # load steps of a [load_path]: each one is a full solve
# every method `vi_core.solve` takes (vi_core.METHODS for fixed convex sets, CONTACT_METHODS for
# contact blocks): the one list of a scene's [solver] method and of `mixvi solve --solver`
# (problems.pipeline.SOLVERS); a test keeps it equal to vi_core's
METHODS = ("auto", "ssn", "conic", "homotopy", "fixed_point")


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


def head(name: str, default_level: int, *aliases: str) -> type[Head]:
    """The [scene] table of plug-in `name`: plugin = NAME (or one of its deprecated `aliases`),
    level defaults to `default_level`."""
    from pydantic import create_model

    return create_model(
        "Head_" + "_".join((name, *aliases)),
        __base__=Head,
        plugin=(Literal[(name, *aliases)], Field(description="the plug-in this scene is for")),
        level=(Level, Field(default_level, description="default refinement level")),
    )


class Solver(Section):
    """The optional [solver] table: method and tolerance (each only if given)."""

    method: Literal[METHODS] | None = None
    tol: Annotated[Number, Field(gt=0.0, lt=1.0)] | None = None

    def options(self) -> dict:
        """{"method": ..., "tol": ...} with the keys given."""
        return {k: v for k, v in (("method", self.method), ("tol", self.tol)) if v is not None}


Step = Annotated[Number, Field(ge=0.0)]


class LoadPath(Section):
    """The optional [load_path] table: the load steps of a quasi-static path (docs/load_paths.md).

    Every expression of the scene may then use the load parameter t. The path starts from the
    unloaded reference state and solves one state per value of t, each warm-started from the
    one before (ssn and fixed_point; conic, homotopy and auto start every step from zero) and,
    with a plug-in that declares `incremental`, in the incremental form (a friction law acts
    on the slip since the previous step). Either `steps = N`: t = end·k/N
    for k = 1 … N (end = 1 unless given), or `t = [t1, t2, ...]`: increasing values ≥ 0.
    """

    steps: Annotated[Integer, Field(ge=1, le=MAX_STEPS)] | None = Field(
        None, description="number of equal steps from t = 0 to t = end"
    )
    end: Annotated[Number, Field(gt=0.0)] | None = Field(
        None, description="the last t with `steps` (default 1)"
    )
    t: Annotated[list[Step], Field(min_length=1, max_length=MAX_STEPS)] | None = Field(
        None, description="the values of t, increasing (instead of `steps`)"
    )

    @model_validator(mode="after")
    def _one_form(self) -> LoadPath:
        if self.steps is None and self.t is None:
            raise refuse(["steps"], None, "required: `steps = N` or `t = [t1, t2, ...]`")
        if self.steps is not None and self.t is not None:
            raise refuse(["t"], self.t, "absent with `steps = N` (give one of the two)")
        if self.t is not None:
            if self.end is not None:
                raise refuse(
                    ["end"], self.end, "absent with `t = [...]` (its last value is the end)"
                )
            for i in range(1, len(self.t)):
                if self.t[i] <= self.t[i - 1]:
                    raise refuse(
                        ["t", i], self.t[i], f"a value above the one before ({self.t[i - 1]!r})"
                    )
        return self

    def values(self) -> list[float]:
        """The load parameter of each step, in order."""
        if self.t is not None:
            return [float(v) for v in self.t]
        end = 1.0 if self.end is None else float(self.end)
        return [end * k / self.steps for k in range(1, self.steps + 1)]


class SceneModel(Section):
    """The root of a scene: format, [scene], [solver], [load_path]; plug-ins add their
    sections. DIMENSION: that of the scene's geometries (an expression may use z only in 3D);
    None where the geometries tell it at validation (`dimension`)."""

    DIMENSION: ClassVar[int | None] = 2

    format: Literal[2] = Field(description="the scene format (2)")
    scene: Head
    solver: Solver | None = None
    load_path: LoadPath | None = None

    @property
    def dimension(self) -> int:
        """The scene's dimension (2 or 3): DIMENSION (a scene model whose geometries tell it
        overrides this)."""
        return self.DIMENSION

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
    dimension: int | None = None,
) -> Section:
    """`data` validated by `cls`, every expression told its field path (SceneError naming the
    field, the value, what is allowed and the override that caused it, if one did). `prefix`:
    where `data` sits in the scene when `cls` is one section (e.g. ("exact",)); `dimension`:
    the scene's, told to its bodies (default `cls.DIMENSION`)."""
    try:
        if dimension is None:
            dimension = getattr(cls, "DIMENSION", None)
        model = cls.model_validate(data, context={"file": file, "dimension": dimension})
    except ValidationError as err:
        e = err.errors()[0]
        e = {**e, "loc": (*prefix, *e["loc"])}
        root = data
        for p in reversed(prefix):
            root = {p: root}
        raise _scene_error(e, root, file, overrides or {}) from None
    assign_paths(model, path_text(prefix))
    if isinstance(model, SceneModel):
        _variables(model, file, overrides or {})
    return model


def expressions(obj: Any) -> list[Expression]:
    """Every expression of a validated model (or part of one), in field order."""
    if isinstance(obj, Expression):
        return [obj]
    if isinstance(obj, BaseModel):
        return [e for name in type(obj).model_fields for e in expressions(getattr(obj, name))]
    if isinstance(obj, list | tuple):
        return [e for v in obj for e in expressions(v)]
    if isinstance(obj, dict):
        return [e for v in obj.values() for e in expressions(v)]
    return []


def _variables(model: SceneModel, file: str | None, overrides: dict[str, str]) -> None:
    """Refuse z in an expression of a 2D scene and t in one of a scene without [load_path]
    (naming the field); with a load path, tell every expression its last t (its value
    outside a load step)."""
    path = model.load_path
    t_end = path.values()[-1] if path is not None else None
    for e in expressions(model):
        for used, allowed in (
            (e.uses_z and model.dimension == 2, Z_IN_2D),
            (e.uses_t and path is None, NO_LOAD_PATH),
        ):
            if used:
                err = SceneError(e.path, e.source, allowed, file)
                raise _with_override(err, e.path, overrides)
        e.t_end = t_end


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
        return _with_override(
            SceneError(path_text(loc), value, msg, file), path_text(loc), overrides
        )
    elif t == "missing":
        value = None
    if isinstance(value, dict | list) and t not in ("unknown_key", "scene_value"):
        shown = _at(data, loc)
        value = shown if shown is not None else value
    err = SceneError(path_text(loc), value, _allowed(e), file)
    return _with_override(err, path_text(loc), overrides)


def _with_override(err: SceneError, path: str, overrides: dict[str, str]) -> SceneError:
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

    Format 1 (no `format` key, or `format = 1`): `[scene] plugin` defaulted to piezo_contact,
    now the 2D front of `contact`.
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
        out["scene"] = {**head_, "plugin": "contact"}
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
