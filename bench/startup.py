"""Start-up and wall time of the command line against `import numpy` (issue 14 point 4,
issue 34 point 3).

Each figure is the median wall time (and CPU time, user + system, which a load stretches
less) of RUNS fresh interpreters, the cases run in turn so that a load on the machine hits
them all alike; every figure is also given as a ratio to the baseline `python -c "import
numpy"` measured in the same run, with the load average:

    import numpy (baseline); import sqlalchemy, import sqlalchemy.orm, import
        app.records.db.models (the ORM and the records' declarative models, on which the
        records' verification before use is built) and app.records.db.lab (all a records
        command imports before it reads): the records commands' floor
    accelcal --help
    accelcal plan --preset piezo            (shipped phases: nothing optimised)
    accelcal customers list                 (on a records file made once by `db upgrade`)
    accelcal run --sim --dut piezo --target-ua 0.2% --estimator lpm, warm, unpaced: its whole
        wall time, and the simulated excitation seconds it reports (excitation_time_s); without
        records in use, and again with them (--db: the records' gate, index and audit)
    the same run --paced (simulated stand in real time): wall time minus the excitation, and
        minus the time the amplifier was on (run.log: output on .. output off)

Targets (SPEC.md section 12): --help, plan and customers list at most 2x the baseline; the
warm run at most 1.5 s in all on an idle machine; a paced run ends within 1.5 s of its
excitation. `--also PATH` times the same commands from another checkout (an export of an
older commit, e.g. `git archive a4a82f7 | tar -x -C /tmp/main-a4a82f7`) in the same run, for a
before/after figure. The data (stored stand response, records) live in a temporary folder.

Run: python bench/startup.py [--runs 15] [--paced-runs 3] [--also /path/to/checkout] [--smoke]
     python bench/startup.py --commands-only [--runs 15]   (the start-up figures alone)
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUN = ["run", "--sim", "--dut", "piezo", "--target-ua", "0.2%", "--estimator", "lpm"]
log = logging.getLogger("bench.startup")


@dataclass
class Case:
    """One command timed in fresh interpreters: its wall times (s) and what it reported."""

    name: str
    command: list[str]
    root: Path = ROOT
    walls: list[float] = field(default_factory=list)
    cpus: list[float] = field(default_factory=list)  # user + system seconds of the process
    reports: list[dict] = field(default_factory=list)  # type: ignore[type-arg]

    def once(self, env: dict[str, str]) -> None:
        """Run once; its wall time, and its JSON report when it prints one (a run)."""
        env = dict(env, PYTHONPATH=str(self.root))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        done = subprocess.run(
            self.command, cwd=self.root, env=env, check=True, capture_output=True, text=True
        )
        self.walls.append(time.perf_counter() - t0)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        self.cpus.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
        if "--json" in self.command and done.stdout.strip().startswith("{"):
            self.reports.append(json.loads(done.stdout))

    @property
    def median(self) -> float:
        return statistics.median(self.walls)

    @property
    def cpu(self) -> float:
        return statistics.median(self.cpus)


def amplifier_on_s(run_folder: Path) -> float:
    """Seconds between 'power amplifier: output on' and 'output off' in a run's run.log."""
    on = off = None
    for line in (run_folder / "run.log").read_text().splitlines():
        stamp, _, message = line.partition(" ")
        if message.startswith("power amplifier: output on") and on is None:
            on = datetime.fromisoformat(stamp)
        elif message.startswith("power amplifier: output off"):
            off = datetime.fromisoformat(stamp)
    if on is None or off is None:
        raise RuntimeError(f"{run_folder}/run.log: amplifier on/off not logged")
    return (off - on).total_seconds()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15, help="interpreters per figure")
    parser.add_argument("--paced-runs", type=int, default=3, help="paced runs (each ~10 s)")
    parser.add_argument("--also", type=Path, action="append", default=[], help="other checkout")
    parser.add_argument("--smoke", action="store_true", help="--runs 1: checks it still runs")
    parser.add_argument(
        "--commands-only",
        action="store_true",
        help="time the commands' start-up alone (no warm or paced runs)",
    )
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if args.smoke:
        args.runs, args.paced_runs = 1, 1
    python = sys.executable
    with tempfile.TemporaryDirectory(prefix="accelcal-startup-") as tmp:
        data = Path(tmp) / "data"
        runs = Path(tmp) / "runs"
        env = {k: v for k, v in os.environ.items() if k != "ACCELCAL_DB"}
        env["ACCELCAL_DATA_DIR"] = str(data)  # no records there: the runs use none
        records = f"sqlite:///{Path(tmp) / 'records.sqlite'}"
        accelcal = [python, "-m", "app"]
        # once: the records file, and the stand's response stored by a cold run (warm after)
        subprocess.run(
            [*accelcal, "db", "upgrade", "--db", records],
            cwd=ROOT,
            env=env,
            check=True,
            capture_output=True,
        )
        for paced in () if args.commands_only else ([], ["--paced"]):
            subprocess.run(
                [*accelcal, *RUN, *paced, "--out", str(runs)],
                cwd=ROOT,
                env=env,
                check=True,
                capture_output=True,
            )
        cases = [
            Case("import numpy (baseline)", [python, "-c", "import numpy"]),
            Case("import sqlalchemy (the records' floor)", [python, "-c", "import sqlalchemy"]),
            Case("import sqlalchemy.orm", [python, "-c", "import sqlalchemy.orm"]),
            Case(
                "import app.records.db.models (ORM + the records' models)",
                [python, "-c", "import app.records.db.models"],
            ),
            Case(
                "import app.records.db.lab (all a records command imports)",
                [python, "-c", "import app.records.db.lab"],
            ),
        ]
        for root in (ROOT, *(other.resolve() for other in args.also)):
            label = "" if root == ROOT else f" ({root})"
            cases += [
                Case(f"`accelcal --help`{label}", [*accelcal, "--help"], root),
                Case(
                    f"`accelcal plan --preset piezo`{label}",
                    [*accelcal, "plan", "--preset", "piezo"],
                    root,
                ),
                Case(
                    f"`accelcal customers list`{label}",
                    [*accelcal, "customers", "list", "--db", records],
                    root,
                ),
            ]
            if not args.commands_only:
                cases.append(
                    Case(
                        f"warm LPM run, unpaced (all of it){label}",
                        [*accelcal, *RUN, "--json", "--out", str(runs)],
                        root,
                    )
                )
        if not args.commands_only:  # the same run with the records: gate, reference, index
            cases.append(
                Case(
                    "warm LPM run, unpaced, records in use (--db)",
                    [*accelcal, *RUN, "--json", "--db", records, "--out", str(runs)],
                )
            )
        paced = Case(
            "warm LPM run, paced", [*accelcal, *RUN, "--paced", "--json", "--out", str(runs)]
        )
        for case in cases:  # warm the file cache
            case.once(env)
        for case in cases:
            case.walls.clear()
            case.cpus.clear()
            case.reports.clear()
        for i in range(args.runs):
            log.info("round %d of %d", i + 1, args.runs)
            for case in cases:
                case.once(env)
        for _ in range(0 if args.commands_only else args.paced_runs):
            paced.once(env)
        load = os.getloadavg()
        on = [amplifier_on_s(runs / r["run_id"]) for r in paced.reports]
    base, base_cpu = cases[0].median, cases[0].cpu
    print(
        f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (1, 5, 15 min); "
        f"{os.cpu_count()} cores; python {sys.version.split()[0]}"
    )
    print()
    print(
        f"| command | wall, median of {args.runs} | ratio to import numpy | CPU (user + system) "
        "| CPU ratio |"
    )
    print("| --- | --- | --- | --- | --- |")
    for case in cases:
        print(
            f"| {case.name} | {case.median:.3f} s | {case.median / base:.2f} | {case.cpu:.3f} s "
            f"| {case.cpu / base_cpu:.2f} |"
        )
    print()
    for case in cases:  # SPEC s.12: a command that computes nothing numeric within 2x
        if case.root == ROOT and case.name.startswith(
            ("`accelcal --help`", "`accelcal plan", "`accelcal customers")
        ):
            ratio = case.median / base
            print(
                f"{case.name}: {ratio:.2f}x import numpy (target <= 2x on an idle machine): "
                f"{'pass' if ratio <= 2.0 else 'FAIL'}"
            )
    print()
    for run_case in (case for case in cases if case.reports):
        excitation = statistics.median(r["excitation_time_s"] for r in run_case.reports)
        print(
            f"{run_case.name}: {run_case.median:.3f} s wall (target <= 1.5 s idle), "
            f"simulated excitation {excitation:.3f} s"
        )
    if not paced.reports:
        return
    paced_excitation = [r["excitation_time_s"] for r in paced.reports]
    over_excitation = [w - e for w, e in zip(paced.walls, paced_excitation, strict=True)]
    over_on = [w - o for w, o in zip(paced.walls, on, strict=True)]
    print(
        f"paced LPM run (median of {len(paced.walls)}): wall {statistics.median(paced.walls):.3f} s"
        f", excitation {statistics.median(paced_excitation):.3f} s, amplifier on "
        f"{statistics.median(on):.3f} s; wall - excitation {statistics.median(over_excitation):.3f}"
        f" s (target <= 1.5 s); wall - amplifier on {statistics.median(over_on):.3f} s"
    )


if __name__ == "__main__":
    main()
