"""`mixvi sweep`: one scene solved over a grid of parameter values.

    mixvi sweep SCENE --set-range KEY=START:STOP:N ... --set-list KEY=V1,V2,... ...
                      [--plot OUTPUT ...] [--set KEY=VALUE ...] [--level N] [--solver NAME]
                      [--tol T] [--linear-solver NAME] [--out DIR] [--no-progress]
                      [--workers N | --scheduler ADDRESS] [--overwrite] [--force]

`--set-range contact.F=0.1:1:10` gives N values evenly spaced from START to STOP (both
included; N = 1: START alone), `--set-list contact.g=1e7,1e8` the values listed (numbers or
TOML literals, as `--set` reads them). With several options the cases are every combination
(the first option varies slowest). Every case is validated by the scene's plug-in before
anything is solved: a value the scene refuses is named with its option (exit 2).

Each case is what `mixvi solve SCENE --set KEY=VALUE ...` computes (the nested iteration for
ssn, the scene's solver and tolerance unless given); its summary.json and the plug-in's files
go into DIR/case_NNN/. Then `sweep.json` and `sweep.csv` hold one row per case: the parameter
values and every scalar output of its summary.json, flattened to dotted keys (`contact.stick`,
`residual`, `contact.force_on_slave.1` for a vector's component; `mixvi sweep ... --plot`
without a key lists them). `--plot OUTPUT` draws that output against the first parameter, one
line per combination of the others (OUTPUT.png). A `--plot` key that the first solved case does
not have is refused then, before the other cases are solved.

With `--workers N` / `--scheduler ADDRESS` the cases run as Dask tasks, as in `mixvi study`
(optional extra: `pip install -e ".[dask]"`); the results are written here. Output folder
rules as for every command (`problems.output.files`): all files are committed together at the
end, so an interrupted or refused sweep leaves DIR as it was.

Exit status: 0 every case converged, 1 a case did not converge or failed (its row says why),
2 bad input.
"""

from __future__ import annotations

import argparse
import csv
import io
import itertools
import json
import math
import re
import sys
import time
from pathlib import Path
from typing import Any

from problems.errors import SceneError

from . import options

OUTPUT_NAME = re.compile(r"[^A-Za-z0-9_.-]+")  # characters of an output key kept in a file name
LEFT_OUT = (
    "files",
    "residual_history",
    "solver_info",
    "nested",
    "scene_file",
    "warnings",
    "sweep",
    "scaling",
)
VECTOR = 3  # lists of at most this many numbers are flattened into components


# ------------------------------------------------------------------ the parameters
def parse_range(text: str) -> tuple[str, list[float]]:
    """'contact.F=0.1:1:10' → ('contact.F', 10 values from 0.1 to 1); SceneError naming
    --set-range otherwise."""
    key, sep, spec = text.partition("=")
    allowed = (
        "KEY=START:STOP:N with numbers START, STOP and a whole number N ≥ 1 of values, "
        "e.g. contact.F=0.1:1:10"
    )
    parts = spec.split(":")
    key = key.strip()
    if not sep or not key or len(parts) != 3:
        raise SceneError("--set-range", text, allowed)
    try:
        start, stop = float(parts[0]), float(parts[1])
        n = int(parts[2])
    except ValueError:
        raise SceneError("--set-range", text, allowed) from None
    if not (math.isfinite(start) and math.isfinite(stop)) or n < 1:
        raise SceneError("--set-range", text, allowed)
    if n == 1:
        return key, [start]
    return key, [start + (stop - start) * i / (n - 1) for i in range(n)]


def parse_list(text: str) -> tuple[str, list[Any]]:
    """'contact.g=1e7,1e8' → ('contact.g', [1e7, 1e8]): each value a TOML literal (a number,
    true/false, a quoted string) or else a bare word; SceneError naming --set-list otherwise."""
    from problems.scene import parse_override

    key, sep, spec = text.partition("=")
    key = key.strip()
    items = [s.strip() for s in spec.split(",")]
    if not sep or not key or not all(items):
        raise SceneError(
            "--set-list", text, "KEY=V1,V2,... with at least one value, e.g. contact.g=1e7,1e8"
        )
    return key, [parse_override(f"{key}={v}")[1] for v in items]


def parameters(args: argparse.Namespace) -> dict[str, tuple[str, str, list]]:
    """{key: (option, its text, values)} in the order given on the command line; SceneError
    for a key swept twice or also fixed with --set, and for no parameter at all."""
    out: dict[str, tuple[str, str, list]] = {}
    fixed = {s.partition("=")[0].strip() for s in args.set or []}
    for option, text in getattr(args, "swept", None) or []:
        key, values = (parse_range if option == "--set-range" else parse_list)(text)
        if key in out:
            raise SceneError(option, text, f"a key not swept already ({key}: {out[key][1]})")
        if key in fixed:
            raise SceneError(option, text, f"a key not also fixed by --set ({key})")
        out[key] = (option, text, values)
    if not out:
        raise SceneError(
            "--set-range", None, "at least one --set-range KEY=START:STOP:N or --set-list KEY=V,..."
        )
    return out


def grid(params: dict[str, tuple[str, str, list]]) -> list[dict[str, Any]]:
    """Every combination of the parameters' values, the first parameter varying slowest."""
    keys = list(params)
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(
        *(params[k][2] for k in keys))]  # fmt: skip


def override(key: str, value: Any) -> str:
    """The `--set` text that sets `key` to `value` (a TOML literal)."""
    if isinstance(value, str):
        return f"{key}={json.dumps(value)}"
    if isinstance(value, bool):
        return f"{key}={'true' if value else 'false'}"
    return f"{key}={value!r}"


def load_case(
    scene: str, fixed: list[str], case: dict, params: dict[str, tuple[str, str, list]]
) -> Any:
    """The case's scene, validated (`pipeline.Loaded`); a value the scene refuses is a
    SceneError naming the sweep's option, its text and the scene's refusal."""
    import problems.pipeline as pipeline

    try:
        return pipeline.load(scene, [*fixed, *(override(k, v) for k, v in case.items())])
    except SceneError as err:
        swept = [k for k in case if err.key == k or err.key.startswith((k + ".", k + "["))]
        swept += [k for k in case if err.key.endswith(" " + k) or k.startswith(err.key + ".")]
        if not swept:
            raise
        option, text, _ = params[swept[0]]
        why = re.sub(r" \((set by|after) --set [^)]*\)$", "", err.allowed)
        raise SceneError(
            f"{option} {swept[0]}",
            text,
            f"values the scene accepts; {err.key} = {err.value!r} is refused: {why}",
            err.file,
        ) from None


# ------------------------------------------------------------------ one case
def solve_case(scene: Any, level: int, solver: dict, keep_model: bool = True) -> Any:
    """One case: the validated `scene` solved by `pipeline.solve` as `mixvi solve` solves it
    (BLAS single-threaded, so serial and Dask runs give the same numbers). A failure other than
    bad input is returned as its text (the case's row says why); with `keep_model` False (a
    Dask task) the model is dropped from the run (rebuilt where the results are written)."""
    from threadpoolctl import threadpool_limits

    import problems.pipeline as pipeline

    with threadpool_limits(1):
        try:
            run = pipeline.solve(pipeline.validated(scene), level, **solver)
        except SceneError:
            raise
        except Exception as err:  # a failed case is a failed row, with its cause
            return f"{type(err).__name__}: {err}"
    if not keep_model:
        run.model = None
    return run


def case_summary(loaded: Any, run: Any, case: dict, name: str, tmp: Path) -> dict:
    """The case's summary.json, written into tmp/name/ with the files `mixvi solve` writes for
    the state (`problems.pipeline.written`): what `mixvi solve` records of a run, and the
    case's parameter values ("sweep")."""
    from problems.output.collection import vtu_datasets
    from problems.output.jsonable import jsonable
    from problems.pipeline import written

    folder = tmp / name
    folder.mkdir()
    extras, files, warnings = written.state_files(loaded, run, folder)
    files += written.collection(folder, vtu_datasets(run.model.level, files), "results.pvd")
    before = {"sweep": {"case": name, "set": case}}
    after = {"condition_estimate": run.solution.info.get("condition_estimate")}
    summary = written.summary_of(loaded, run, extras, files, warnings, before, after)
    written.write_summary(folder, summary)
    return jsonable(summary)


def flatten(summary: dict, prefix: str = "") -> dict[str, Any]:
    """The scalar outputs of a summary by dotted key: numbers, booleans and strings; lists of
    at most VECTOR numbers as components KEY.0, KEY.1, ...; LEFT_OUT entries and other lists
    left out."""
    out: dict[str, Any] = {}
    for k, v in summary.items():
        key = f"{prefix}{k}"
        if not prefix and k in LEFT_OUT:
            continue
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        elif isinstance(v, list):
            if 0 < len(v) <= VECTOR and all(_is_number(x) for x in v):
                out.update({f"{key}.{i}": x for i, x in enumerate(v)})
        elif v is None or isinstance(v, bool | int | float | str):
            out[key] = v
    return out


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def check_plots(keys: list[str], outputs: dict[str, Any]) -> None:
    """SceneError naming --plot for a key that is not a numeric output of a case."""
    numeric = [k for k, v in outputs.items() if _is_number(v)]
    for k in keys:
        if k not in numeric:
            raise SceneError("--plot", k, "a numeric output of a case: " + ", ".join(numeric))


# ------------------------------------------------------------------ the sweep
def run_sweep(
    args: argparse.Namespace, cases: list[dict], loaded: list, level: int, tmp: Path, client
) -> list[dict]:
    """Solve every case (here, or as Dask tasks on `client`), its files into tmp/case_NNN/;
    the rows of sweep.json. A --plot key is checked against the first case solved."""
    from problems.output import signals

    from .progress import bar as progress_bar

    solver = options.solver_options(args)
    width = len(str(len(cases) - 1))
    names = [f"case_{i:0{width}d}" for i in range(len(cases))]
    rows: list[dict | None] = [None] * len(cases)
    bar = progress_bar(total=len(cases), shown=not args.no_progress, unit="case")

    def record(i: int, run: Any) -> None:
        row = {"case": names[i], "set": cases[i]}
        if isinstance(run, str):
            row.update(converged=False, error=run, outputs={})
        else:
            if run.model is None:  # a Dask task's run: the model rebuilt here for the files
                run.model = signals.interruptible(loaded[i].plugin.build, loaded[i].scene, level)
            summary = case_summary(loaded[i], run, cases[i], names[i], tmp)
            row.update(converged=bool(summary["converged"]), outputs=flatten(summary))
            if not any(r is not None and r["outputs"] for r in rows):
                check_plots(args.plot or [], row["outputs"])
            run.model = None
        rows[i] = row
        bar.update(1)

    try:
        if client is None:
            for i in range(len(cases)):
                bar.set_description(", ".join(f"{k}={_fmt(v)}" for k, v in cases[i].items()))
                record(i, signals.interruptible(solve_case, loaded[i].scene, level, solver))
        else:
            from dask.distributed import as_completed

            futures = {
                client.submit(solve_case, loaded[i].scene, level, solver, False, pure=False): i
                for i in range(len(cases))
            }
            for future in as_completed(futures):
                record(futures[future], future.result())  # bad input (SceneError) raised here
    finally:
        bar.close()
    return [r for r in rows if r is not None]


def _fmt(v: Any) -> str:
    return f"{v:.4g}" if _is_number(v) else str(v)


# ------------------------------------------------------------------ reporting
BASE_COLUMNS = ("converged", "iterations", "residual", "time_s.solve")


def table(result: dict) -> str:
    """The cases as a text table: parameters, converged, iterations, residual, solve time and
    the --plot outputs."""
    keys = list(result["parameters"])
    cols = [*BASE_COLUMNS, *(k for k in result["plot"] if k not in BASE_COLUMNS)]
    head = ["case", *keys, *cols]
    lines = [[r["case"], *(_fmt(r["set"][k]) for k in keys)] for r in result["cases"]]
    for r, cells in zip(result["cases"], lines, strict=True):
        if "error" in r:
            cells.append(f"failed: {r['error']}")
            continue
        cells += [_fmt(r["outputs"].get(c, "-")) for c in cols]
    widths = [max(len(h), *(len(c[i]) for c in lines if i < len(c))) for i, h in enumerate(head)]
    text = [" ".join(h.rjust(w) for h, w in zip(head, widths, strict=True))]
    text += [" ".join(c.rjust(w) for c, w in zip(cells, widths, strict=False)) for cells in lines]
    return "\n".join(text)


def csv_text(result: dict) -> str:
    """sweep.csv: one row per case, the parameters then every output any case has."""
    keys = list(result["parameters"])
    outputs = list(dict.fromkeys(k for r in result["cases"] for k in r["outputs"]))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["case", *keys, "error", *outputs])
    for r in result["cases"]:
        w.writerow(
            [r["case"], *(r["set"][k] for k in keys), r.get("error", "")]
            + [_cell(r["outputs"].get(k)) for k in outputs]
        )
    return buf.getvalue()


def _cell(v: Any) -> str:
    return "" if v is None else repr(v) if isinstance(v, float) else str(v)


def plot_file(key: str) -> str:
    """The PNG of output `key`: its name with characters outside [A-Za-z0-9_.-] as '_'."""
    return OUTPUT_NAME.sub("_", key) + ".png"


# ------------------------------------------------------------------ command line
class _Swept(argparse.Action):
    """--set-range and --set-list, recorded together in the order given: `args.swept`, a list
    of (option, text)."""

    def __call__(self, parser, namespace, values, option_string=None):
        namespace.swept = [*(getattr(namespace, "swept", None) or []), (option_string, values)]


def parser() -> argparse.ArgumentParser:
    """The argument parser of `mixvi sweep`."""
    from vi_core.linear_solvers import LINEAR_SOLVERS

    p = argparse.ArgumentParser(
        prog="mixvi sweep",
        description=__doc__.splitlines()[0],
        epilog="Cases: every combination of the swept values (first option slowest). Output: "
        "DIR/case_NNN/ (summary.json and the plug-in's files), sweep.json, sweep.csv and one "
        "OUTPUT.png per --plot.",
    )
    p.add_argument("scene", help="scene file or shipped name")
    p.add_argument(
        "--set-range",
        action=_Swept,
        metavar="KEY=START:STOP:N",
        dest="swept",
        help="sweep a scene number over N evenly spaced values, both ends included, e.g. "
        "contact.F=0.1:1:10 (repeatable)",
    )
    p.add_argument(
        "--set-list",
        action=_Swept,
        metavar="KEY=V1,V2,...",
        dest="swept",
        help="sweep a scene value over the values listed, e.g. contact.g=1e7,1e8 (repeatable)",
    )
    p.add_argument(
        "--plot",
        nargs="+",
        metavar="OUTPUT",
        help="outputs of summary.json to plot against the first parameter, dotted, e.g. "
        "contact.stick iterations (a wrong key lists the outputs)",
    )
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="fix a scene value")
    p.add_argument(
        "--level", type=options.level, default=None, help="refinement level (default: scene's)"
    )
    p.add_argument("--solver", default=None, help="as mixvi solve's --solver (default: scene's)")
    p.add_argument(
        "--tol", type=options.tol, default=None, help="relative residual (default 1e-10)"
    )
    p.add_argument(
        "--linear-solver", choices=LINEAR_SOLVERS, default="auto", help="as mixvi solve's"
    )
    p.add_argument(
        "--cold", action="store_true", help="no nested iteration (as mixvi solve's --cold)"
    )
    p.add_argument("--out", default=None, help="output directory (default out/SCENE_sweep)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    options.add_run_options(p)
    return p


def sweep_main(argv: list[str] | None = None) -> int:
    """Entry point of `mixvi sweep`: 0 if every case converged, 1 if not, 2 on bad input."""
    from problems.output.files import output_folder
    from problems.output.sweep_plots import plot_output

    from . import resources
    from .study import DASK_WORKER_BYTES, _client, worker_count

    args = parser().parse_args(argv)
    params = parameters(args)
    cases = grid(params)
    fixed = list(args.set or [])
    loaded = [load_case(args.scene, fixed, c, params) for c in cases]  # all validated first
    first = loaded[0]
    for note in first.notices:
        print(f"mixvi: note: {note}", file=sys.stderr)
    if first.spec.load_path is not None:
        raise SceneError(
            "scene",
            args.scene,
            "a scene without [load_path] (mixvi sweep solves one state per case; sweep the "
            "load path's end value instead, e.g. --set-list with the values of t)",
        )
    plugin = first.plugin
    if args.solver is not None:
        import problems.pipeline as pipeline

        if args.solver not in pipeline.SOLVERS:
            raise SceneError("--solver", args.solver, "one of " + ", ".join(pipeline.SOLVERS))
    level, option = resources.requested_level(args.level, plugin, first.scene)
    sizes = None
    for case in dict.fromkeys([0, len(cases) - 1]):  # the grid's ends: sizes may vary with it
        sizes = resources.check_levels(
            plugin,
            loaded[case].scene,
            (level, level),
            option,
            str(level),
            args.force,
            args.linear_solver,
        )
    if args.workers is not None:
        per_worker = sizes.estimate(level).upper_bytes + DASK_WORKER_BYTES
        args.workers, note = worker_count(args.workers, per_worker, len(cases), "mixvi sweep")
        if note:
            print(note, file=sys.stderr)
    name = first.scene.name
    out = Path(args.out) if args.out else Path("out") / f"{name}_sweep"
    inputs = first.scene.files()
    t0 = time.perf_counter()
    with output_folder(out, "--out", overwrite=args.overwrite, inputs=inputs) as folder:
        with folder.staging() as tmp:
            with _client(args) as client:
                rows = run_sweep(args, cases, loaded, level, tmp, client)
            result = {
                "scene": name,
                "plugin": plugin.NAME,
                "level": level,
                "parameters": {k: v[2] for k, v in params.items()},
                "plot": list(args.plot or []),
                "cases": rows,
                "time_s": time.perf_counter() - t0,
            }
            (tmp / "sweep.json").write_text(json.dumps(result, indent=2) + "\n")
            (tmp / "sweep.csv").write_text(csv_text(result))
            for key in result["plot"]:
                plot_output(result, key, tmp / plot_file(key))
    print(table(result))
    if not args.plot:
        numeric = [k for k, v in next((r["outputs"] for r in rows if r["outputs"]), {}).items()
                   if _is_number(v)]  # fmt: skip
        print("outputs to --plot: " + ", ".join(numeric))
    print(f"wrote {out}/: sweep.json, sweep.csv, {', '.join(map(plot_file, result['plot']))}"
          f"{', ' if result['plot'] else ''}case_*/")  # fmt: skip
    return 0 if all(r["converged"] for r in rows) else 1
