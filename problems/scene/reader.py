"""Scene files (TOML): loading, format migration and `--set dotted.key=value` overrides.

`load_scene` reads the file, migrates an older format (`problems.scene.model.migrate`, one
notice per migrated file in `Scene.notices`) and applies the overrides, remembering which
field each one set so that a validation error can name it. `Scene.validated(cls)` is the
scene checked by a plug-in's scene model (cached while `data` is unchanged).
"""

from __future__ import annotations

import copy
import json
import re
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from problems.errors import SceneError

from .model import SceneModel, did_you_mean, migrate, validate

SCENES_DIR = Path(__file__).parent.parent / "scenes"
# Tables and arrays nest at most this deep in a scene or a --set value (the deepest shipped
# scene nests 4; TOML's reader and the validation recurse once per level)
MAX_DEPTH = 16


def _too_deep(value: Any, depth: int = 0, path: str = "") -> str | None:
    """The dotted path of the first value nested deeper than MAX_DEPTH, or None (iterative:
    the check itself must not recurse without bound)."""
    stack = [(value, depth, path)]
    while stack:
        v, d, p = stack.pop()
        if d > MAX_DEPTH:
            return p or "(top)"
        if isinstance(v, dict):
            stack += [(x, d + 1, f"{p}.{k}" if p else str(k)) for k, x in v.items()]
        elif isinstance(v, list):
            stack += [(x, d + 1, f"{p}[{i}]") for i, x in enumerate(v)]
    return None


NESTING = f"tables and arrays nested at most {MAX_DEPTH} deep"


@dataclass
class Scene:
    """A read scene: the data (current format, overrides applied), where it came from, its
    short name, the overrides by field path and the migration notices."""

    data: dict
    path: str
    name: str
    overrides: dict[str, str] = field(default_factory=dict)
    notices: list[str] = field(default_factory=list)
    _cache: tuple | None = field(default=None, repr=False, compare=False)

    def validated(self, cls: type[SceneModel], dimension: int | None = None) -> SceneModel:
        """The scene validated by `cls` (SceneError naming the field), in `dimension` if given
        (else `cls.DIMENSION`, or its geometries' where that is None); cached while `data` is
        unchanged, revalidated after any edit of it."""
        c = self._cache
        if c is not None and c[0] == (cls, dimension) and c[1] == self.data:
            return c[2]
        model = validate(cls, self.data, self.path, self.overrides, dimension=dimension)
        self._cache = ((cls, dimension), copy.deepcopy(self.data), model)
        return model

    def files(self) -> list[tuple[str, Path]]:
        """(what, path) of every file the scene reads: the scene file itself (none for a scene
        made in Python) and each mesh or geometry file a table names (`mesh = FILE`,
        `geo = FILE`, relative to the scene file), as the inputs a run's outputs may not be."""
        from .imported import resolve

        made = self.path.startswith("<")
        out = [] if made else [("the scene file", Path(self.path))]
        folder = None if made else Path(self.path).parent
        todo: list[tuple[str, Any]] = [("", self.data)]
        while todo:
            where, node = todo.pop()
            if isinstance(node, dict):
                for key in ("mesh", "geo"):
                    if isinstance(node.get(key), str):
                        out.append((f"the file of {where}{key}", resolve(folder, node[key])))
                todo += [(f"{where}{k}.", v) for k, v in node.items()]
            elif isinstance(node, list):
                todo += [(f"{where[:-1]}[{i}].", v) for i, v in enumerate(node)]
        return out

    @classmethod
    def from_model(cls, model: SceneModel, name: str = "scene") -> Scene:
        """A scene made from a validated model (the Python API): its data is the model's."""
        data = model.model_dump(mode="json", by_alias=True, exclude_none=True)
        scene = cls(data=data, path=f"<{name}>", name=name)
        scene._cache = ((type(model), None), copy.deepcopy(data), model)
        return scene


def find_scene(name_or_path: str) -> Path:
    """A scene file by path, by the name of a local file without `.toml` (`x` for ./x.toml),
    or by the name of a shipped scene (`mixvi scenes`). A name that is both a local x.toml and
    a shipped scene is refused (SceneError naming both and how to pick each): neither wins
    silently."""
    p = Path(name_or_path)
    try:  # a name too long for the file system, or otherwise unusable: not found
        if p.is_file():
            return p
        local = p.with_name(f"{p.name}.toml") if p.name and p.suffix != ".toml" else None
        local = local if local is not None and local.is_file() else None
        shipped = SCENES_DIR / f"{name_or_path}.toml"
        shipped = shipped if shipped.is_file() else None
    except (OSError, ValueError):
        local = shipped = None
    if local is not None and shipped is not None:
        raise SceneError(
            "scene",
            name_or_path,
            f"one scene; this name is both the file {local} and a shipped scene: write "
            f"{local} for the file, or {shipped} for the shipped scene",
        )
    if local is not None or shipped is not None:
        return local or shipped
    names = sorted(q.stem for q in SCENES_DIR.glob("*.toml"))
    raise SceneError(
        "scene",
        name_or_path,
        f"an existing file (x.toml may be named x) or a shipped scene: {', '.join(names)}"
        + did_you_mean(name_or_path, names),
    )


def parse_override(text: str) -> tuple[list[str], Any]:
    """'contact.g=5e7' → (['contact', 'g'], 5e7); values are TOML literals, else strings."""
    if "=" not in text:
        raise SceneError("--set", text, "dotted.key=value, e.g. contact.g=5e7")
    key, raw = text.split("=", 1)
    parts = [p.strip() for p in key.strip().split(".")]
    if not all(parts):
        raise SceneError("--set", text, "dotted.key=value, e.g. contact.g=5e7")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    except RecursionError:
        raise SceneError(f"--set {key.strip()}", _short(raw), NESTING) from None
    if len(parts) > MAX_DEPTH or _too_deep(value, len(parts)) is not None:
        raise SceneError(f"--set {key.strip()}", _short(raw), NESTING)
    return parts, value


BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def toml_literal(v: Any) -> str:
    """A value of a scene as a TOML literal (inline tables and arrays): what `parse_override`
    reads back as `v` (the Python API's overrides, the scene reference's examples)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_literal(x)}" for k, x in v.items()) + " }"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_literal(x) for x in v) + "]"
    if isinstance(v, float | int):
        return repr(v)  # inf, -inf and nan are TOML's own
    return json.dumps(v, ensure_ascii=False)


def toml_key(k: str) -> str:
    """A key of an inline table: bare where TOML allows it, else quoted."""
    return k if BARE_KEY.fullmatch(k) else json.dumps(k, ensure_ascii=False)


def _short(text: str) -> str:
    return text if len(text) <= 60 else text[:28] + "..." + text[-28:]


def load_scene(name_or_path: str, overrides: Iterable[str] = ()) -> Scene:
    """Read a scene file and apply `--set` overrides (SceneError on any problem)."""
    path = find_scene(name_or_path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise SceneError("(file)", path.name, f"valid TOML ({err})", str(path)) from None
    except RecursionError:
        raise SceneError("(file)", path.name, NESTING, str(path)) from None
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError("(file)", path.name, f"a readable text file ({err})", str(path)) from None
    deep = _too_deep(data)
    if deep is not None:
        raise SceneError(deep, "(nested value)", NESTING, str(path))
    data, notices = migrate(data, str(path)) if isinstance(data, dict) else (data, [])
    scene = Scene(data=data, path=str(path), name=path.stem, notices=notices)
    apply_overrides(scene, overrides)
    return scene


def apply_overrides(scene: Scene, overrides: Iterable[str]) -> None:
    """Apply `--set dotted.key=value` overrides to `scene.data`, remembering each one's field
    (SceneError for a malformed one or a key inside a table that does not exist)."""
    for text in overrides:
        parts, value = parse_override(text)
        node = scene.data
        for i, p in enumerate(parts[:-1]):
            if not isinstance(node, dict) or p not in node or not isinstance(node[p], dict):
                table, rest = ".".join(parts[: i + 1]), ".".join(parts[i + 1 :])
                raise SceneError(
                    f"--set {'.'.join(parts)}",
                    value,
                    f"a key inside existing tables ({p!r} missing; to add the table give it "
                    f"whole: --set '{table}={{{rest} = ...}}')",
                    scene.path,
                )
            node = node[p]
        if not isinstance(node, dict):
            raise SceneError(f"--set {'.'.join(parts)}", value, "a key of a table", scene.path)
        node[parts[-1]] = value
        scene.overrides[".".join(parts)] = text
