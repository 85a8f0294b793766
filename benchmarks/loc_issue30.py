"""Lines of code of vi_core + fem + problems for issue 30 ("lines of non-test code go down").

    python benchmarks/loc_issue30.py [--old a15b507] [--new 06ccf85] [--json OUT.json]

Counts the .py lines (blank and comment lines included, as `wc -l`) of vi_core, fem and problems
at OLD (where issue 30 started) and NEW, read from git (no checkout), and splits NEW into
(i) the modules other issues added since OLD (FEATURES) and (ii) the rest: the code that existed
at OLD, in its modules or their renamed successors (docs/design.md, renamed modules). A second
split of (ii) by `git blame -w -M -C -C NEW`: the lines last written by a commit that came in
through another issue's branch (BRANCHES; a commit on main's own line: the issue its message
names) are features added inside old modules.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
from collections import Counter
from pathlib import Path

FOLDERS = ("vi_core", "fem", "problems")
FEATURES = {  # (i): modules added since a15b507 by other issues
    "estimator (32)": ["fem/estimator.py", "problems/plugins/contact/error_estimate.py"],
    "bisection, marking (32)": ["fem/bisection.py", "fem/marking.py"],
    "adaptive loop (32)": ["problems/pipeline/adaptive.py", "problems/commands/adapt.py"],
    "unilateral manufactured (32)": ["problems/scene/manufactured_unilateral.py"],
    "petsc engine (33)": ["vi_core/petsc/", "vi_core/engine.py", "problems/commands/engine.py"],
    "sweep (31)": ["problems/commands/sweep.py", "problems/output/sweep_plots.py"],
    "mixvi new (31)": ["problems/commands/template.py"],
    "Results.write (31)": ["problems/pipeline/written.py"],
    "CLI reference page (31)": ["problems/commands/reference.py"],
    "bench --baseline (lead)": ["problems/commands/bench_compare.py"],
}
BRANCHES = {"states2": 29, "interrupts": 29, "tie": 0, "usermeshbench": 34, "est34": 34}


def git(*args: str) -> str:
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout


def files(rev: str) -> list[str]:
    names = git("ls-tree", "-r", "--name-only", rev, "--", *FOLDERS).split()
    return [f for f in names if f.endswith(".py")]


def lines(rev: str, path: str) -> int:
    return len(git("show", f"{rev}:{path}").splitlines())


def issue_of(old: str, new: str) -> dict[str, int]:
    """Each commit in OLD..NEW → the issue its branch (or, on main's own line, its message)
    names; 0 where neither names one."""
    out: dict[str, int] = {}
    for line in git("log", "--first-parent", "--format=%H %P|%s", f"{old}..{new}").splitlines():
        shas, subject = line.split("|", 1)
        head, *parents = shas.split()
        branch = re.search(r"Merge branch '([^']+)'", subject)
        if branch:
            name = branch[1]
            digits = re.search(r"(\d\d)", name)
            issue = BRANCHES.get(name, int(digits[1]) if digits else 30)
            for c in git("rev-list", parents[1], f"^{parents[0]}").split():
                out.setdefault(c, issue)
        else:
            named = re.search(r"issue (\d+)", git("log", "-1", "--format=%B", head))
            issue = int(named[1]) if named else 0
        out[head] = issue
    return out


def blamed(rev: str, path: str, issues: dict[str, int]) -> Counter:
    """Lines of `path` at `rev` by the issue of the commit that last wrote them (-1: before)."""
    porcelain = git("blame", "-w", "-M", "-C", "-C", "--line-porcelain", rev, "--", path)
    shas = re.findall(r"^([0-9a-f]{40}) \d+ \d+", porcelain, flags=re.M)
    return Counter(issues.get(s, -1) for s in shas)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", default="a15b507")
    parser.add_argument("--new", default="06ccf85")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    old = sum(lines(args.old, f) for f in files(args.old))
    new = {f: lines(args.new, f) for f in files(args.new)}
    feature = {
        k: sum(n for f, n in new.items() if f.startswith(tuple(v))) for k, v in FEATURES.items()
    }
    rest = [f for f in new if not any(f.startswith(tuple(v)) for v in FEATURES.values())]
    issues = issue_of(args.old, args.new)
    by_issue = sum((blamed(args.new, f, issues) for f in rest), Counter())
    other = sum(n for i, n in by_issue.items() if i not in (-1, 0, 30))
    table = {
        f"vi_core+fem+problems at {args.old}": old,
        f"vi_core+fem+problems at {args.new}": sum(new.values()),
        **{f"(i) {k}": n for k, n in feature.items()},
        "(i) all": sum(feature.values()),
        "(ii) the rest (modules of OLD and their successors)": sum(new[f] for f in rest),
        "(ii) of which last written by issues 29, 31-34 (blame)": other,
        "(ii) without those lines": sum(new[f] for f in rest) - other,
    }
    for key, n in table.items():
        print(f"{n:7d}  {key}")
    print("(ii) lines by the issue that last wrote them (-1: before OLD, 0: none named):")
    print("  " + ", ".join(f"{i}: {n}" for i, n in sorted(by_issue.items())))
    if args.json:
        args.json.write_text(json.dumps({"table": table, "blame": dict(by_issue)}, indent=1))


if __name__ == "__main__":
    main()
