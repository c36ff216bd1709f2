"""Several DUTs in one run (issue 36 point 1): what a batch of N DUTs costs against one run.

On the simulated stand with sim/stand-fixture4.toml (rigid fixture), the same request (seed 5,
the piezo preset, lpm, --periods P, a fresh stand response each time) run once as a single-DUT
run and once as a batch of N = 2, 3, 4 DUTs at the fixture's positions. Printed per row:
- the simulated excitation time (s): the shaker's running time, independent of the machine's
  load (one excitation: it must not grow with N);
- the wall time (s) and its ratio to the single run measured in the same invocation (with
  `uptime`'s load average: the lead re-measures the ratios at idle);
- the Python heap's peak (tracemalloc, MB) and its ratio to the single run's;
- the wall time per DUT and its ratio (what a batch saves per sensor in the sweep alone; the
  handling the issue's point 7 models comes after the merge).
One single run and one batch of 2 run first as a warm-up (imports, caches), not measured.

Run: python bench/batch_run.py [--periods P] [--repeat R] [--smoke]
(--smoke: N = 2 only, 1 period, once: checks it runs; figures not meaningful)
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.procedure.batch import MemberChoice, execute_batch
from app.procedure.request import RunRequest
from app.procedure.run import execute
from app.stand import config as stand_config

STAND = Path(__file__).resolve().parents[1] / "sim" / "stand-fixture4.toml"


def _measure(run) -> tuple[float, float, float]:
    """(excitation s, wall s, heap peak MB) of one call of `run` (it returns a Finished)."""
    tracemalloc.start()
    start = time.perf_counter()
    finished = run()
    wall = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return float(finished.record.excitation_time_s), wall, peak


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--periods", type=int, default=4)
    parser.add_argument("--repeat", type=int, default=3, help="best of R per row")
    parser.add_argument("--smoke", action="store_true")
    args = parser.parse_args()
    counts = [2] if args.smoke else [2, 3, 4]
    periods = 1 if args.smoke else args.periods
    repeat = 1 if args.smoke else max(1, args.repeat)
    config = stand_config.load(STAND)
    out = Path(tempfile.mkdtemp(prefix="batch-bench-"))

    def request() -> RunRequest:
        return RunRequest(
            stand_file=STAND, out=out, seed=5, periods=periods, stored_response=False,
            dut="piezo", dut_id="SN-0",
        )  # fmt: skip

    def single():
        return execute(request(), config=config)

    def batch(n: int):
        choices = [MemberChoice(p, f"SN-{p}") for p in "ABCD"[:n]]
        return execute_batch(request(), choices, config=config).members[0][1]

    single()  # warm-up, not measured: imports, caches
    batch(counts[0])
    rows = []
    best = min((_measure(single) for _ in range(repeat)), key=lambda m: m[1])
    rows.append((1, *best))
    for n in counts:
        rows.append((n, *min((_measure(lambda n=n: batch(n)) for _ in range(repeat)),
                             key=lambda m: m[1])))  # fmt: skip
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; periods {periods}, best of "
          f"{repeat}")  # fmt: skip
    print(
        "DUTs  excitation s  wall s  wall/single  heap MB  heap/single  wall per DUT  per-DUT ratio"
    )
    _, ex1, wall1, heap1 = rows[0]
    for n, ex, wall, heap in rows:
        print(
            f"{n:>4}  {ex:>12.2f}  {wall:>6.2f}  {wall / wall1:>11.2f}  {heap:>7.1f}  "
            f"{heap / heap1:>11.2f}  {wall / n:>12.2f}  {(wall / n) / wall1:>13.2f}"
        )
        if abs(ex - ex1) > 1e-9:
            print(f"  excitation differs from the single run's ({ex:g} s vs {ex1:g} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
