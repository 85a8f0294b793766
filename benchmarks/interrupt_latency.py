"""How fast each `mixvi` command ends on a signal sent inside a compiled call.

    python benchmarks/interrupt_latency.py [--repeat N] [--json FILE] [CASE ...]

For each case (default: all of CASES) the real `mixvi` command runs in a fresh temporary
folder with the test hook MIXVI_MARK (vi_core.marks) set; as soon as the hook reports the
case's compiled call (a SuperLU factorisation of more than the case's size)
the signal is sent, and the time to the one-line message on stderr and to the process's exit
are measured (wall clock: the latency a user sees; the machine may be shared, so repeat).
Prints a table (median and largest of N runs, the thread the call was made in) and writes the
rows as JSON (default interrupt_latency.json). Each run also checks what the tests check:
exit status 128 + signal, and nothing left in the folder.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MIXVI = str(Path(sys.executable).with_name("mixvi"))
PAPER = ["paper_two_body", "--level", "4"]
PAPER3 = ["paper_two_body", "--level", "3"]  # level 4 with the defaults: amg, no SuperLU
STUDY = ["study", "paper_two_body", "--solvers", "ssn", "--tols", "1e-6", "--no-progress"]
# name → (arguments, signal, compiled call, least size of the call)
CASES = {
    "solve": (["solve", *PAPER, "--cold", "--linear-solver", "splu", "--out", "o"],
              signal.SIGINT, "splu", 50_000),
    "check": (["check", *PAPER, "--json", "r.json"], signal.SIGINT, "splu", 50_000),
    "figures": (["figures", *PAPER3, "--out", "o"], signal.SIGTERM, "splu", 20_000),
    "study": ([*STUDY, "--levels", "3..3", "--out", "o"], signal.SIGINT, "splu", 20_000),
    "study-dask": ([*STUDY, "--levels", "2..3", "--workers", "2", "--out", "o"],
                   signal.SIGINT, "splu", 20_000),
    "extremes": (["extremes", "--only", "(thin layer)", "--out", "o"], signal.SIGINT, "splu", 0),
    "bench": (["bench", "--scenes", "paper_two_body", "--levels", "4..4", "--linear-solvers",
               "splu", "--out", "b.json"], signal.SIGTERM, "splu", 50_000),
}  # fmt: skip


def _called(mark: Path, what: str, n_min: int) -> str | None:
    """The thread of the first `what` call of more than n_min unknowns (None: none yet)."""
    text = mark.read_text() if mark.exists() else ""
    for line in text[: text.rfind("\n") + 1].splitlines():
        w, n, thread = line.split()
        if w == what and int(n) > n_min:
            return thread
    return None


def run_once(name: str) -> dict:
    """One run of case `name`: seconds from the signal to the message and to the exit."""
    argv, sig, what, n_min = CASES[name]
    with tempfile.TemporaryDirectory() as tmp:
        case, mark = Path(tmp) / "case", Path(tmp) / "mark"
        case.mkdir()
        proc = subprocess.Popen(
            [MIXVI, *argv], cwd=case, env={**os.environ, "MIXVI_MARK": str(mark)},
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        while (thread := _called(mark, what, n_min)) is None:
            if proc.poll() is not None:
                raise RuntimeError(f"{name}: ended before the call ({proc.stderr.read()})")
            time.sleep(0.002)
        t0 = time.monotonic()
        proc.send_signal(sig)
        line = proc.stderr.readline()  # notices before the signal would come first
        while line and not line.startswith("mixvi: interrupted"):
            line = proc.stderr.readline()
        t1 = time.monotonic()
        proc.wait()
        t2 = time.monotonic()
        left = sorted(p.name for p in case.iterdir())
    ok = proc.returncode == 128 + sig and line.startswith("mixvi: interrupted") and not left
    return {"case": name, "message_s": t1 - t0, "exit_s": t2 - t0, "thread": thread, "ok": ok}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("cases", nargs="*", default=list(CASES), help=", ".join(CASES))
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--json", default="interrupt_latency.json")
    args = p.parse_args(argv)
    rows = []
    print(f"{'case':<12}{'signal':>8}{'call':>9}{'thread':>12}{'exit median':>13}"
          f"{'exit max':>10}{'message max':>13}{'clean':>7}")  # fmt: skip
    for name in args.cases:
        runs = [run_once(name) for _ in range(args.repeat)]
        exits = sorted(r["exit_s"] for r in runs)
        row = {
            "case": name,
            "signal": signal.Signals(CASES[name][1]).name,
            "call": CASES[name][2],
            "thread": runs[0]["thread"],
            "exit_median_s": exits[len(exits) // 2],
            "exit_max_s": exits[-1],
            "message_max_s": max(r["message_s"] for r in runs),
            "clean": all(r["ok"] for r in runs),
            "runs": runs,
        }
        rows.append(row)
        print(f"{name:<12}{row['signal']:>8}{row['call']:>9}{row['thread'][:11]:>12}"
              f"{row['exit_median_s']:>13.2f}{row['exit_max_s']:>10.2f}"
              f"{row['message_max_s']:>13.2f}{str(row['clean']):>7}", flush=True)  # fmt: skip
    Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    return 0 if all(r["clean"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
