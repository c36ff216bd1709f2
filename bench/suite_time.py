"""The test suite's own speed (issue 31: `make test` at most 5 min, `make test-fast` at most
45 s of wall time on the 2-core machine when it is otherwise idle).

Runs each make target REPEATS times in turn, in this checkout, and prints per run the wall
time, the CPU time of the suite's processes (user + system of every process it waited for) and
the 1-minute load average before and after (the suite's own workers raise it: with nothing
else running it stays near their number). The figures mean something only on an otherwise
idle machine: check `uptime` first.

Run: python bench/suite_time.py [REPEATS] [TARGET ...]   (default: 3 test-fast test;
about 20 minutes)     Smoke: python bench/suite_time.py --smoke   (one `make --dry-run`)
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGETS = ("test-fast", "test")
LIMITS_S = {"test-fast": 45.0, "test": 300.0}
SUMMARY = re.compile(r"(\d+ passed.*?) in [\d.]+s")


def children_cpu_s() -> float:
    """User + system CPU seconds of every child process waited for so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def time_target(target: str, dry_run: bool = False) -> tuple[float, float, str, int]:
    """(wall s, CPU s, pytest's summary line, exit status) of one `make TARGET`."""
    command = ["make", "--dry-run", target] if dry_run else ["make", target]
    cpu0, wall0 = children_cpu_s(), time.perf_counter()
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, check=False)
    wall, cpu = time.perf_counter() - wall0, children_cpu_s() - cpu0
    found = SUMMARY.findall(done.stdout)
    return wall, cpu, found[-1] if found else "-", done.returncode


def main(argv: list[str]) -> int:
    smoke = "--smoke" in argv
    words = [a for a in argv if a != "--smoke"]
    repeats = int(words[0]) if words and words[0].isdigit() else 3
    targets = [w for w in words if not w.isdigit()] or list(TARGETS)
    if smoke:
        repeats, targets = 1, ["test-fast"]
    print(f"{'target':<10} {'run':>3} {'wall':>9} {'CPU':>9} {'load before':>11} "
          f"{'after':>6}  limit  pytest")  # fmt: skip
    status = 0
    for target in targets:
        for run in range(1, repeats + 1):
            before = os.getloadavg()[0]
            wall, cpu, summary, code = time_target(target, dry_run=smoke)
            after = os.getloadavg()[0]
            limit = LIMITS_S.get(target)
            within = "-" if limit is None or smoke else ("met" if wall <= limit else "NOT met")
            print(
                f"{target:<10} {run:>3} {wall:8.1f}s {cpu:8.1f}s {before:11.2f} {after:6.2f}"
                f"  {within:<6} {summary} (exit {code})"
            )
            status = status or code
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
