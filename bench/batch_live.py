"""What the other DUTs' live estimates cost a several-DUT run (issue 36 point 4: the Run tab
shows each DUT live; app.procedure.batch_live): one unpaced batch of N piezo DUTs on
sim/stand-fixture4.toml per estimator, run twice in the same process with the same seed: once
as the window runs it (`Procedure.batch_live`: each other DUT estimated after every period),
once without (the baseline: the CLI's batch, its members estimated only at the end).

Prints, per estimator:
- the run thread's CPU time (`time.thread_time`: what the run computed, which the machine's
  load does not inflate) of the whole batch with and without the live members, and the ratio;
- the CPU of the members' live estimates per acquired period (all members together, and per
  member), against the period's length: the share of real time a paced run spends on them;
- the live estimates sent (a count) and the largest |last live deviation - stored deviation|
  over the members' lines (%): the live curves end where the stored results are.
A first batch of each estimator, not counted, takes the imports and caches. Wall times with
`uptime`'s load average (re-measure at idle); CPU times and counts are the figures.

Run: python bench/batch_live.py [--duts N] [--periods P] [--smoke]
(--smoke: two DUTs, two periods, the lpm only)
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

log = logging.getLogger("bench.batch_live")

STAND = ROOT / "sim" / "stand-fixture4.toml"
POSITIONS = "ABCD"


@dataclass
class Timed:
    """CPU (s) spent in the members' live estimates, and the calls."""

    cpu_s: float = 0.0
    estimates: int = 0


@contextmanager
def timed_members(timed: Timed) -> Any:
    """Count the CPU of LiveMembers.add/estimates."""
    from app.procedure import batch_live

    add, estimates = batch_live.LiveMembers.add, batch_live.LiveMembers.estimates

    def timed_add(self: Any, *args: Any) -> None:
        started = time.thread_time()
        add(self, *args)
        timed.cpu_s += time.thread_time() - started

    def timed_estimates(self: Any) -> Any:
        started = time.thread_time()
        out = estimates(self)
        timed.cpu_s += time.thread_time() - started
        timed.estimates += 1
        return out

    batch_live.LiveMembers.add = timed_add  # type: ignore[method-assign]
    batch_live.LiveMembers.estimates = timed_estimates  # type: ignore[method-assign]
    try:
        yield
    finally:
        batch_live.LiveMembers.add, batch_live.LiveMembers.estimates = add, estimates


@dataclass(frozen=True)
class Run:
    cpu_s: float
    wall_s: float
    periods: int
    period_s: float
    live_cpu_s: float
    live_estimates: int
    worst_difference_percent: float


def one_batch(out: Path, estimator: str, duts: int, periods: int, live: bool) -> Run:
    """One batch of `duts` DUTs (seed 7) as the window runs it (open, the run, the stand
    closed, the end; `live`: the others estimated live), timed; the last live estimates
    against the stored."""
    from app.procedure.batch import MemberChoice, open_batch
    from app.procedure.events import PeriodEstimate
    from app.procedure.request import RunRequest
    from app.stand import config as stand_config

    config = stand_config.load(STAND)
    request = RunRequest(
        stand_file=STAND,
        out=out,
        seed=7,
        periods=periods,
        estimator=estimator,
        stored_response=False,
    )
    choices = [MemberChoice(p, f"BENCH-{p}") for p in POSITIONS[:duts]]
    events: list[Any] = []
    timed = Timed()
    with timed_members(timed):
        wall, cpu = time.perf_counter(), time.thread_time()
        opened = open_batch(request, choices, events.append, config=config)
        opened.procedure.batch_live = live
        try:
            ended = opened.procedure.run()
        finally:
            opened.stand.close()
        finished = opened.end(ended, events.append)
        cpu_s, wall_s = time.thread_time() - cpu, time.perf_counter() - wall
    statuses = {str(one.status) for _, one in finished.members}
    if statuses != {"complete"}:
        raise SystemExit(f"{estimator}: the batch did not complete: {statuses}")
    own = [e for e in events if isinstance(e, PeriodEstimate) and e.members]
    worst = float("nan")
    if own:
        last = {m.position: m.results for m in own[-1].members}
        worst = 0.0
        for choice, one in finished.members[1:]:
            shown = last[choice.position].lines
            for a, b in zip(shown, one.results.lines, strict=True):
                worst = max(worst, abs(a.deviation_percent - b.deviation_percent))
    record = finished.members[0][1].record
    period_s = float(record.plan["period_samples"]) / float(record.plan["sample_rate_hz"])
    return Run(cpu_s, wall_s, len(own), period_s, timed.cpu_s, timed.estimates, worst)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duts", type=int, default=4, help="DUTs in the batch (2-4)")
    parser.add_argument("--periods", type=int, default=8, help="periods acquired")
    parser.add_argument("--smoke", action="store_true", help="a short run (CI)")
    args = parser.parse_args(argv)
    if not 2 <= args.duts <= 4:
        parser.error("--duts: must be within 2 .. 4 (the fixture's positions)")
    if not 1 <= args.periods <= 200:
        parser.error("--periods: must be within 1 .. 200")
    estimators = ["lpm", "periodic"]
    if args.smoke:
        args.duts, args.periods, estimators = 2, 2, ["lpm"]
    logging.basicConfig(level=logging.WARNING)
    load_start = os.getloadavg()
    work = Path(tempfile.mkdtemp(prefix="bench-batch-live-"))
    os.environ.setdefault("ACCELCAL_DATA_DIR", str(work / "data"))  # never the user's
    others = args.duts - 1
    print(
        f"batch of {args.duts} piezo DUTs on {STAND.name} (unpaced, seed 7), {args.periods} "
        f"periods; the members' live estimates on, and off (baseline), in this process"
    )
    print(
        "| estimator | run CPU, live off | run CPU, live on | on / off | members' live CPU "
        "per period (per member) | share of the period | live estimates | largest "
        "abs(live - stored) deviation |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for estimator in estimators:  # a first batch of each, not counted: imports and caches
        one_batch(work / f"{estimator}-warm", estimator, 2, args.periods, True)
    for estimator in estimators:
        off = one_batch(work / f"{estimator}-off", estimator, args.duts, args.periods, False)
        on = one_batch(work / f"{estimator}-on", estimator, args.duts, args.periods, True)
        per_period = on.live_cpu_s / max(on.live_estimates, 1)
        print(
            f"| {estimator} | {off.cpu_s:.2f} s | {on.cpu_s:.2f} s | "
            f"{on.cpu_s / off.cpu_s:.2f}x | {1e3 * per_period:.1f} ms "
            f"({1e3 * per_period / others:.1f} ms) | {100 * per_period / on.period_s:.1f} % of "
            f"{on.period_s:g} s | {on.live_estimates} | {on.worst_difference_percent:.1e} % |"
        )
        print(
            f"  wall: live off {off.wall_s:.2f} s, on {on.wall_s:.2f} s (the load inflates "
            "these; the CPU times above are the figures)"
        )
    load_end = os.getloadavg()
    print(
        "load average (1, 5, 15 min) at start "
        + ", ".join(f"{v:.2f}" for v in load_start)
        + "; at end "
        + ", ".join(f"{v:.2f}" for v in load_end)
        + f"; {os.cpu_count()} cores"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
