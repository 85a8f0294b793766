"""How long `mixvi --help` takes (the target: under 0.5 s), against a bare interpreter.

    python benchmarks/bench_cli_startup.py [--repeat N] [--json FILE]

Each command runs N times in a fresh process (wall clock and the CPU time of the child, from
os.wait4; the machine may be shared: the CPU time is the steadier number, the ratio to the bare
interpreter's the portable one). Prints a table (median and largest) with each command's peak
resident memory and writes the rows as JSON (default cli_startup.json).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

PY = sys.executable
CASES = {
    "python -c pass": [PY, "-c", "pass"],
    "mixvi --help": [PY, "-m", "problems.commands.entry", "--help"],
    "mixvi solve --help": [PY, "-m", "problems.commands.entry", "solve", "--help"],
}


def run_once(argv: list[str]) -> tuple[float, float, float]:
    """(wall s, CPU s, peak RSS MiB) of one run of `argv` in a fresh process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)}: exit {proc.returncode}: {proc.stderr.read()}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--json", default="cli_startup.json")
    args = p.parse_args(argv)
    rows = []
    print(f"{'command':<20}{'wall median':>12}{'wall max':>10}{'CPU median':>12}"
          f"{'× python':>10}{'peak MiB':>10}")  # fmt: skip
    base = None
    for name, cmd in CASES.items():
        runs = [run_once(cmd) for _ in range(args.repeat)]
        wall = sorted(r[0] for r in runs)
        cpu = sorted(r[1] for r in runs)
        row = {
            "command": name,
            "wall_median_s": wall[len(wall) // 2],
            "wall_max_s": wall[-1],
            "cpu_median_s": cpu[len(cpu) // 2],
            "peak_rss_mib": max(r[2] for r in runs),
            "repeat": args.repeat,
        }
        base = base or row["cpu_median_s"]
        row["cpu_ratio_to_python"] = row["cpu_median_s"] / base
        rows.append(row)
        print(f"{name:<20}{row['wall_median_s']:>12.3f}{row['wall_max_s']:>10.3f}"
              f"{row['cpu_median_s']:>12.3f}{row['cpu_ratio_to_python']:>10.1f}"
              f"{row['peak_rss_mib']:>10.1f}", flush=True)  # fmt: skip
    Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
