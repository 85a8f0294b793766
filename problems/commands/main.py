"""The `mixvi` command line.

mixvi solve [SCENE] [--level N] [--solver NAME] [--tol T] [--set key=value ...] [--out DIR]
mixvi scenes | check | figures | study | bench | extremes
"""

from __future__ import annotations

import argparse
import sys

from problems.errors import SceneError

from . import options
from .check import cmd_check
from .figures import cmd_figures
from .options import DEFAULT_SCENE
from .scenes import cmd_scenes
from .solve import ACCURACY, cmd_solve


def parser() -> argparse.ArgumentParser:
    """The argument parser of solve, scenes, check and figures."""
    p = argparse.ArgumentParser(prog="mixvi", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("solve", help="solve a scene and write summary.json, VTU and PNG files")
    s.add_argument("scene", nargs="?", help=f"scene file or shipped name (default {DEFAULT_SCENE})")
    s.add_argument(
        "--level", type=options.level, default=None, help="refinement level (default: scene's)"
    )
    s.add_argument("--solver", default=None, help="ssn (default) or another vi_core method")
    s.add_argument(
        "--tol", type=options.tol, default=None, help="relative residual (default 1e-10)"
    )
    s.add_argument(
        "--accuracy",
        choices=list(ACCURACY),
        default=None,
        help="preset level and tolerance: "
        + ", ".join(f"{k} = level {lv}, tol {t:g}" for k, (lv, t) in ACCURACY.items()),
    )
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a scene value")
    s.add_argument("--out", default=None, help="output directory (default out/SCENE)")
    s.add_argument(
        "--cold",
        action="store_true",
        help="no nested iteration: start Newton from λ = 0 on the requested level only",
    )
    s.add_argument(
        "--allow-defect",
        action="store_true",
        help="exit 0 even if a contact interface's mortar patch defect exceeds 1e-8",
    )
    s.set_defaults(func=cmd_solve)
    sc = sub.add_parser("scenes", help="list the scenes that ship")
    sc.set_defaults(func=cmd_scenes)
    for name, fn, helptext in (
        ("check", cmd_check, "solve with every applicable method and compare"),
        ("figures", cmd_figures, "Fig. 5.4: multiplier and jump for g = 1.5e8, 1e8, 0.6e8"),
    ):
        c = sub.add_parser(name, help=helptext)
        c.add_argument("scene", nargs="?", help=f"scene (default {DEFAULT_SCENE})")
        c.add_argument("--level", type=options.level, default=None)
        c.add_argument("--set", action="append", metavar="KEY=VALUE")
        if name == "check":
            c.add_argument("--tol", type=options.tol, default=1e-10)
            c.add_argument("--levels", default=None, help="several levels, e.g. 0..2")
            c.add_argument("--json", default=None, help="also write the table as JSON")
        else:
            c.add_argument("--out", default=None)
        c.set_defaults(func=fn)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `mixvi` command; exit status 2 on bad input."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["bench"]:  # its own argument parser (benchmark options)
        from .bench import bench_main

        return bench_main(argv[1:])
    if argv[:1] == ["extremes"]:  # its own argument parser
        from .extremes import extremes_main

        return extremes_main(argv[1:])
    if argv[:1] == ["study"]:  # its own argument parser (study options)
        from .study import study_main

        return study_main(argv[1:])
    args = parser().parse_args(argv)
    try:
        return args.func(args)
    except SceneError as err:
        print(f"mixvi: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
