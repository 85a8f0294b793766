"""The `mixvi` command line.

mixvi solve [SCENE] [--level N] [--solver NAME] [--linear-solver NAME] [--tol T]
            [--set key=value ...] [--out DIR]
mixvi validate SCENE [--set key=value ...]    check a scene without solving
mixvi schema | scenes | check | figures | study | bench | extremes    (`mixvi --help`: one line
each)

Exit status (every command): 0 all good, 1 ran but a case failed or did not converge, 2 bad
input (one line naming the option or scene key, the value and what is allowed), 3 internal
error (one line; `--debug` anywhere on the command line prints the traceback), 130 / 143
interrupted by SIGINT / SIGTERM (one line; output folders as they were before the run).
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

from problems.errors import SceneError
from problems.output import signals

from . import failures, options
from .options import DEFAULT_SCENE

# Nothing heavy is imported at the top (NumPy, SciPy, pydantic, cvxpy, matplotlib: seconds):
# `mixvi --help` builds only the list of commands (`parser(full=False)`); a command's module is
# imported when it runs (`_command`). tests/problems/commands/test_startup.py checks it.

SET_HELP = "override a scene value, e.g. contact.g=5e7 (repeatable)"


def add_force(p: argparse.ArgumentParser) -> None:
    """--force: skip the memory estimate's refusal and the scene's level cap."""
    p.add_argument(
        "--force",
        action="store_true",
        help="try levels above the scene's memory cap or the memory available now",
    )


OVERWRITE_HELP = (
    "write where files mixvi did not write are: into a folder that holds them (only mixvi's "
    "files are replaced, nothing is deleted), or over such a single file (replaced)"
)


def add_output_options(p: argparse.ArgumentParser) -> None:
    """--overwrite and --force, shared by every command that writes outputs."""
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    add_force(p)


# every command with its one line of `mixvi --help`
COMMANDS = {
    "solve": "solve a scene; write results (JSON, CSV, VTU, PNG)",
    "scenes": "list the shipped scenes with their plug-in and title",
    "schema": "print the JSON Schema of scenes (every plug-in's section)",
    "validate": "check a scene, its --set overrides and its mesh files without solving",
    "new": "write a commented scene template, copied from a shipped scene or a scene file",
    "check": "solve with every applicable method and compare",
    "figures": "solve for a few values of one scene parameter (the friction bound g: Fig. 5.4) "
    "and plot them side by side",
    "study": "accuracy and cost of every solver over levels and tolerances",
    "sweep": "solve a scene over a grid of parameter values; a table and plots of chosen outputs",
    "bench": "time the nonlinear solve against one linear solve",
    "extremes": "the shipped scenes pushed to extreme data, each row checked",
}
# the commands with their own argument parsers: module, entry function (dispatched before
# `parser()` runs)
OWN_PARSERS = {
    "study": ("study", "study_main"),
    "sweep": ("sweep", "sweep_main"),
    "bench": ("bench", "bench_main"),
    "extremes": ("extremes", "extremes_main"),
}
EPILOG = (
    "Run 'mixvi COMMAND --help' for a command's options. Exit status: 0 all good, 1 ran but "
    "did not converge or a case failed, 2 bad input, 3 internal error (--debug anywhere prints "
    "the traceback), 130/143 interrupted. Scenes, conventions and the design: docs/design.md."
)


def parser(full: bool = True) -> argparse.ArgumentParser:
    """The argument parser of solve, scenes, schema, validate, new, check and figures (and the
    list of all commands); `full=False`: the list of commands only (`mixvi --help`, nothing
    heavy imported)."""
    p = argparse.ArgumentParser(
        prog="mixvi",
        description="mixvi: mixed variational inequalities; frictional contact of "
        "elasto-piezoelectric bodies (dual mortar).",
        epilog=EPILOG,
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    if not full:
        for name, helptext in COMMANDS.items():
            sub.add_parser(name, help=helptext, add_help=False)
        return p
    from vi_core.linear_solvers import LINEAR_SOLVERS

    from .engine import ENGINES
    from .options import ACCURACY

    s = sub.add_parser(
        "solve",
        help=COMMANDS["solve"],
        description="Solve a scene and write its results (summary.json, contact.csv, one VTU "
        "per body, contact.vtu, results.pvd, PNG plots) into a folder.",
    )
    s.add_argument("scene", nargs="?", help=f"scene file or shipped name (default {DEFAULT_SCENE})")
    s.add_argument(
        "--level", type=options.level, default=None, help="refinement level (default: scene's)"
    )
    s.add_argument(
        "--solver",
        default=None,
        help="ssn (default), conic, homotopy, auto, or fixed_point (Coulomb/unilateral contact)",
    )
    s.add_argument(
        "--linear-solver",
        choices=LINEAR_SOLVERS,
        default="auto",
        help="Newton steps: direct (auto = PARDISO if installed and the system is large, else "
        "splu; splu; pardiso) or amg = GMRES with algebraic multigrid, inexact early steps, "
        "direct fallback where it stagnates (default auto)",
    )
    s.add_argument(
        "--engine",
        choices=ENGINES,
        default="serial",
        help="serial (default) or petsc: the Newton loop on PETSc over the ranks of "
        "`mpiexec -n P mixvi solve ... --engine petsc` (petsc4py, mpi4py: the [petsc] extra)",
    )
    s.add_argument(
        "--tol", type=options.tol, default=None, help="relative residual (default 1e-10)"
    )
    s.add_argument(
        "--accuracy",
        type=options.accuracy,
        default=None,
        help="preset level and tolerance: "
        + ", ".join(f"{k} = level {lv}, tol {t:g}" for k, (lv, t) in ACCURACY.items())
        + "; or a number in (0, 1): adaptive refinement to that relative error estimate",
    )
    s.add_argument(
        "--contact-zone",
        action="store_true",
        help="with --accuracy NUMBER only: each adaptive cycle also refines every cell at a "
        "touching contact node, so the whole contact zone is refined evenly (steadier nodal "
        "pressures, e.g. the Hertz peak pressure; more unknowns per cycle)",
    )
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help=SET_HELP)
    s.add_argument("--out", default=None, help="output directory (default out/SCENE)")
    add_output_options(s)
    s.add_argument(
        "--cold",
        action="store_true",
        help="no nested iteration: start Newton from λ = 0 on the requested level only",
    )
    s.add_argument(
        "--write-levels",
        action="store_true",
        help="also write the results of every coarser level of the nested iteration into "
        "levels/L/ and add their VTU files to results.pvd (one time step per level)",
    )
    s.add_argument(
        "--allow-defect",
        action="store_true",
        help="exit 0 even if a contact interface's mortar patch defect exceeds 1e-8",
    )
    s.set_defaults(func="solve:cmd_solve")
    sc = sub.add_parser("scenes", help=COMMANDS["scenes"])
    sc.set_defaults(func="scenes:cmd_scenes")
    sh = sub.add_parser("schema", help=COMMANDS["schema"])
    sh.add_argument(
        "--markdown",
        action="store_true",
        help="print the scene reference (Markdown tables) generated from the schema instead",
    )
    sh.set_defaults(func="schema:cmd_schema")
    v = sub.add_parser(
        "validate",
        help=COMMANDS["validate"],
        description="Check a scene, its overrides and the mesh files it names (groups, cells, "
        "contact curves) as a solve's build would, at level 0; nothing is solved or written.",
    )
    v.add_argument("scene", help="scene file or shipped name")
    v.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a scene value")
    v.set_defaults(func="validate:cmd_validate")
    from .template import add_new_parser

    add_new_parser(sub, COMMANDS["new"])
    for name, fn in (("check", "check:cmd_check"), ("figures", "figures:cmd_figures")):
        helptext = COMMANDS[name]
        c = sub.add_parser(name, help=helptext, description=helptext[0].upper() + helptext[1:])
        c.add_argument("scene", nargs="?", help=f"scene (default {DEFAULT_SCENE})")
        c.add_argument(
            "--level", type=options.level, default=None, help="refinement level (default: scene's)"
        )
        c.add_argument("--set", action="append", metavar="KEY=VALUE", help=SET_HELP)
        if name == "check":
            c.add_argument(
                "--tol", type=options.tol, default=1e-10, help="relative residual (default 1e-10)"
            )
            c.add_argument("--levels", default=None, help="several levels, e.g. 0..2")
            c.add_argument("--json", default=None, help="also write the table as JSON")
        else:
            c.add_argument(
                "--out", default=None, help="output directory (default out/SCENE_figures)"
            )
        add_output_options(c)
        c.set_defaults(func=fn)
    for name in OWN_PARSERS:  # listed here, parsed by their own parsers
        sub.add_parser(name, help=COMMANDS[name], add_help=False)
    return p


# options whose value may start with '-' ("--levels -1..2", "--tol -1"): argparse would take
# the value for an option and print its own message; glued as "--levels=-1..2" the value
# reaches the option's own check, which names the option and what is allowed
VALUE_OPTIONS = {"--level", "--levels", "--tol", "--tols", "--timeout", "--only", "--scenes"}
VALUE_OPTIONS |= {"--solvers", "--solver", "--json", "--out", "--accuracy", "--linear-solver"}
VALUE_OPTIONS |= {"--linear-solvers", "--engine"}


def _glue_values(argv: list[str]) -> list[str]:
    out, i = [], 0
    while i < len(argv):
        a = argv[i]
        if a in VALUE_OPTIONS and i + 1 < len(argv) and argv[i + 1].startswith("-"):
            nxt = argv[i + 1]
            if nxt not in VALUE_OPTIONS and not nxt.startswith("--"):
                out.append(f"{a}={nxt}")
                i += 2
                continue
        out.append(a)
        i += 1
    return out


def _command(target: str):
    """The function `"module:name"` of a command module, imported now."""
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(f"{__package__}.{module}"), name)


def _dispatch(argv: list[str]) -> int:
    argv = _glue_values(argv)
    if argv[:1] and argv[0] in OWN_PARSERS:  # its own argument parser
        _prepare()
        return _command(":".join(OWN_PARSERS[argv[0]]))(argv[1:])
    if not argv or argv[0] not in COMMANDS:  # `mixvi --help`, no command, an unknown one
        parser(full=False).parse_args(argv)  # prints the help or the error and exits
    _prepare()
    args = parser().parse_args(argv)
    return _command(args.func)(args)


def _prepare() -> None:
    """Before a command runs: glibc's mmap threshold fixed (`resources.fix_mmap_threshold`)."""
    from .resources import fix_mmap_threshold

    fix_mmap_threshold()


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `mixvi` command: the one place that maps failures to exit statuses
    (SceneError → 2, SIGINT/SIGTERM → 130/143, stdout's reader gone → 141, exhausted
    resources → 2 or 1 and anything else → 3 with a hint at --debug: `failures.report`)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    signals.install()
    try:
        with failures.guarded_stdout():  # a full or closed stdout: StdoutError, mapped below
            return _dispatch(argv)
    except SceneError as err:
        print(f"mixvi: error: {err}", file=sys.stderr)
        signals.exit_if_alone(2)  # one rank of several, stopped mid-solve: end now
        return 2
    except signals.Interrupted as sig:
        print(f"mixvi: interrupted by {sig}", file=sys.stderr)
        signals.exit_if_abandoned(sig.exit_status)  # work still inside compiled code: end now
        return sig.exit_status
    except KeyboardInterrupt:  # raised before the handler was installed
        print("mixvi: interrupted by SIGINT", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of stdout left (`mixvi scenes | head -1`): no error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # exit's flush is quiet
        return 128 + signal.SIGPIPE  # 141, as for a tool the shell saw ended by SIGPIPE
    except Exception as err:  # exhausted resources (exit 2 or 1) and internal errors (3)
        status = failures.report(err, debug)
        signals.exit_if_alone(status)  # one rank of several, stopped mid-solve: end now
        return status


if __name__ == "__main__":
    sys.exit(main())
