"""`mixvi new SCENE NAME.toml`: a scene template to edit, copied from a shipped scene or a scene
file, with a header saying where it came from and what to do next.

The copy keeps the source's text and comments (every shipped scene explains its setting and
units). Mesh and geometry files (`mesh = "…"`, `geo = "…"`) named relative to the source's
folder are rewritten as absolute paths when NAME.toml is written elsewhere, so the template
reads the same files until they are replaced by the user's own. NAME.toml is never overwritten:
an existing file is refused (exit 2), and the file appears whole or not at all (written beside
it under a temporary name and linked into place, which fails if the name was taken meanwhile).
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from problems.errors import SceneError
from problems.output.paths import write_file

# a mesh or geometry file named in a scene: key = "path" or key = 'path' (TOML basic or literal
# strings; a path with quotes or escapes inside is left as it is)
FILE_KEY = re.compile(r"""(\b(?:mesh|geo)\s*=\s*)(["'])([^"'\\\n]+)\2""")


def add_new_parser(sub, helptext: str) -> None:
    """The `mixvi new` subcommand on the subparsers `sub` of `problems.commands.main`."""
    n = sub.add_parser(
        "new",
        help=helptext,
        description="Write NAME.toml, a scene to edit: a copy of a shipped scene (`mixvi "
        "scenes` lists them) or of a scene file, with a header naming its source and the next "
        "commands; mesh files named relative to the source become absolute paths. An existing "
        "NAME.toml is never overwritten.",
    )
    n.add_argument("source", metavar="SCENE", help="shipped scene name or scene file to copy")
    n.add_argument("target", metavar="NAME.toml", help="the new scene file (must not exist)")
    n.set_defaults(func="template:cmd_new")


def template_text(source: Path, text: str, target: Path, label: str) -> str:
    """The template written to `target` from the scene `text` read at `source` (`label`: how
    the source was named on the command line)."""
    src_dir, dst_dir = source.resolve().parent, target.resolve().parent
    moved = []

    def absolute(m: re.Match) -> str:
        name = m.group(3)
        if Path(name).expanduser().is_absolute() or src_dir == dst_dir:
            return m.group(0)
        path = (src_dir / name).resolve()
        moved.append(path)
        return f"{m.group(1)}{m.group(2)}{path.as_posix()}{m.group(2)}"

    body = FILE_KEY.sub(absolute, text)
    stem = target.stem
    head = [
        f"# {target.name}: a mixvi scene written by `mixvi new {label} {target.name}` from",
        f"# {source.resolve()}.",
        "# Edit it, then:",
        f"#   mixvi validate {target.name}",
        "#       check it and the mesh files it names (nothing solved)",
        f"#   mixvi solve {target.name}",
        f"#       solve it; results in out/{stem}/ (open out/{stem}/results.pvd in ParaView)",
        "# Every key with its type, default and allowed values: `mixvi schema --markdown`;",
        "# a value can also be changed for one run: --set section.key=VALUE.",
    ]
    if moved:
        head.append("# Mesh files this template reads (replace them by your own .msh or .geo):")
        head += [f"#   {p}" for p in dict.fromkeys(moved)]
    return "\n".join(head) + "\n\n" + body


def cmd_new(args: argparse.Namespace) -> int:
    """Write the template; exit 0, or 2 (SceneError) for an unknown source or a target that
    exists, does not end in .toml, or cannot be written."""
    from problems.scene import find_scene

    target = Path(args.target)
    if target.suffix != ".toml" or not target.stem:
        raise SceneError("NAME.toml", args.target, "a scene file name ending in .toml")
    if target.exists() or target.is_symlink():
        raise SceneError(
            "NAME.toml",
            args.target,
            "a new file; this one exists and mixvi new never overwrites (choose another name)",
        )
    if not target.parent.resolve().is_dir():
        raise SceneError(
            "NAME.toml", args.target, f"a file in an existing folder ({target.parent})"
        )
    source = find_scene(args.source)
    try:
        text = source.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError("SCENE", args.source, f"a readable scene file ({err})") from None
    _write_new(target, template_text(source, text, target, args.source))
    print(f"wrote {target} (from {source}); next: mixvi validate {target}")
    return 0


def _write_new(target: Path, text: str) -> None:
    """Create `target` with `text`, whole or not at all, never replacing a file
    (`paths.write_file` without replace: a temporary file hard-linked to the target name)."""
    try:
        write_file(target, text, replace=False)
    except FileExistsError:
        raise SceneError(
            "NAME.toml", str(target), "a new file; it was created meanwhile (not overwritten)"
        ) from None
    except OSError as err:
        raise SceneError("NAME.toml", str(target), f"a file mixvi can write ({err})") from None
