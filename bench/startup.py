"""Start-up time of the command line: `accelcal --help` against `import numpy` (issue 14 point 4).

Each figure is the median wall time of RUNS fresh interpreters (`python -m app --help`, and the
baseline `python -c "import numpy"`), run in turn so that a load on the machine hits both
alike. Target: ratio at most 2. `--also PATH` times the same command from another checkout
(e.g. an export of an older commit) in the same run, for a before/after figure.

Run: python bench/startup.py [--runs 15] [--also /path/to/other/checkout] [--smoke]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def wall(command: list[str], root: Path) -> float:
    """Wall time of one fresh interpreter running `command` in `root`."""
    env = dict(os.environ, PYTHONPATH=str(root))
    t0 = time.perf_counter()
    subprocess.run(command, cwd=root, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15, help="interpreters per figure")
    parser.add_argument("--also", type=Path, action="append", default=[], help="other checkout")
    parser.add_argument("--smoke", action="store_true", help="--runs 1: checks it still runs")
    args = parser.parse_args()
    if args.smoke:
        args.runs = 1
    python = sys.executable
    cases = {"import numpy (baseline)": ([python, "-c", "import numpy"], ROOT)}
    cases["accelcal --help"] = ([python, "-m", "app", "--help"], ROOT)
    for other in args.also:
        cases[f"accelcal --help ({other})"] = ([python, "-m", "app", "--help"], other.resolve())
    for command, root in cases.values():  # warm the file cache
        wall(command, root)
    times: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(args.runs):
        for name, (command, root) in cases.items():
            times[name].append(wall(command, root))
    base = statistics.median(times["import numpy (baseline)"])
    print(f"| command | median of {args.runs} | ratio to import numpy |")
    print("| --- | --- | --- |")
    for name, values in times.items():
        median = statistics.median(values)
        print(f"| {name} | {median:.3f} s | {median / base:.2f} |")


if __name__ == "__main__":
    main()
