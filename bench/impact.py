"""Impact assessment speed (issue 27 point 1, issue 34 point 5): runs re-analysed per second with
a corrected reference table, through the real path (app.procedure.impact.assess: index hash and
manifest verified, the recording read, analysed once and its results computed with the stored
and the corrected table), in a pool of worker processes.

One short simulated run (piezo, 4 periods) is recorded once; every task points at its folder,
so N tasks are N full re-analyses of a real recording. The baseline, measured in the same run
on the same pool of workers: per task, every file of the run folder hashed (what verifying its
manifest reads) and the recording's channels read (h5py), the floor of any re-analysis. Prints
the time per run, the baseline's and their ratio, with the load average (wall times depend on
the machine's load; the ratio much less).

Run: python bench/impact.py [RUNS] [WORKERS]   (default 10000 runs, one worker per core)
Smoke (CI): python bench/impact.py 8 2   (or --smoke, the same)
Parts: python bench/impact.py --parts [REPS]   (CPU ms of each part of one task, in this
process, best of 3 rounds of REPS, default 20: what a run costs and what was repeated)
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from datetime import UTC, datetime
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import h5py

from app.io.hdf5 import read_recording
from app.procedure import impact
from app.procedure.analysis import analyze, analyze_chains, read_for_analysis
from app.procedure.run import RunRequest, execute
from app.records.run_folder import MANIFEST_NAME, inspect_run, sha256_of
from app.records.run_record import RunRecord

SMOKE_ARGS = ("8", "2")  # --smoke: 8 runs on 2 workers, to see that it still works


def read_and_hash(folder: str) -> int:
    """The baseline task: every file of the run folder hashed (SHA-256, as its manifest is
    verified) and the recording's channels read; the samples read."""
    samples = 0
    for path in sorted(Path(folder).iterdir()):
        if path.is_file():
            sha256_of(path)
    with h5py.File(Path(folder) / "recording.h5", "r") as f:
        for name in f["signals"]:
            samples += f["signals"][name][()].size
    return samples


def baseline(folder: str, runs: int, workers: int) -> float:
    """Seconds for `runs` baseline tasks on `workers` processes (one process: in this one)."""
    start = time.perf_counter()
    if workers <= 1:
        for _ in range(runs):
            read_and_hash(folder)
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for future in as_completed([pool.submit(read_and_hash, folder) for _ in range(runs)]):
                future.result()
    return time.perf_counter() - start


def load_average() -> str:
    return "load average " + " ".join(f"{v:.2f}" for v in os.getloadavg())


def cpu_ms(work: Callable[[], object], reps: int) -> float:
    """CPU milliseconds of one call of `work`: best of 3 rounds of `reps` calls."""
    work()
    best = math.inf
    for _ in range(3):
        start = time.process_time()
        for _ in range(reps):
            work()
        best = min(best, (time.process_time() - start) / reps)
    return 1000 * best


def parts(folder: Path, task: impact.Task, serial: str, table: impact.CorrectedTable, reps: int):
    """Print the CPU cost of each part of one task, and the task as it was before issue 34
    (the folder verified twice, the recording read whole, analysed once per table)."""
    check = inspect_run(folder)
    assert check.record is not None
    settings = check.record.analysis
    options = {"estimator": settings.estimator, "probability": settings.probability}
    stored = read_for_analysis(folder, check=check)
    whole = dataclasses.replace(read_recording(folder / "recording.h5"), status=stored.status)
    chains = [whole.chain, table.chain(whole.chain)]
    costs = {
        "verify the run folder (inspect_run)": cpu_ms(lambda: inspect_run(folder), reps),
        "read and check the recording, stored": cpu_ms(
            lambda: read_for_analysis(folder, check=check), reps
        ),
        "read and check the recording, whole": cpu_ms(
            lambda: read_recording(folder / "recording.h5"), reps
        ),
        "analyse with one table": cpu_ms(lambda: analyze(stored, **options), reps),
        "analyse with both tables (analyze_chains)": cpu_ms(
            lambda: analyze_chains(stored, chains, **options), reps
        ),
        "one task (impact.reanalyse)": cpu_ms(lambda: impact.reanalyse(task, serial, table), reps),
        "baseline task (folder hashed, channels read)": cpu_ms(
            lambda: read_and_hash(str(folder)), reps
        ),
    }
    for name, ms in costs.items():
        print(f"{name:46s} {ms:8.2f} ms CPU")
    before = (
        2 * costs["verify the run folder (inspect_run)"]
        + costs["read and check the recording, whole"]
        + 2 * costs["analyse with one table"]
    )
    print(f"{'the task as before (2 verify, whole, 2 analyse)':46s} {before:8.2f} ms CPU")
    print(load_average())


def main(argv: list[str]) -> int:
    args = list(SMOKE_ARGS) if argv[1:] == ["--smoke"] else argv[1:]
    reps = 0
    try:
        if args[:1] == ["--parts"]:
            reps = int(args[1]) if len(args) > 1 else 20
            args = ["1", "1"]
        runs = int(args[0]) if args else 10_000
        workers = int(args[1]) if len(args) > 1 else (os.cpu_count() or 1)
    except ValueError:
        print(
            f"usage: {Path(argv[0]).name} [RUNS] [WORKERS] | --smoke | --parts [REPS]",
            file=sys.stderr,
        )
        return 2
    logging.basicConfig(level=logging.WARNING)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        finished = execute(RunRequest(dut="piezo", dut_id="SN-BENCH", periods=4, out=root))
        folder = root / str(finished.record.run_id)
        record = RunRecord.from_json((folder / "results.json").read_text())
        chain = record.reference_chain
        table = root / "corrected.csv"
        rows = [
            f"{f!r},{1.01 * s!r},0.005,{p!r}"
            for f, s, p in zip(
                chain["frequencies_hz"],
                chain["sensitivity_mv_per_ms2"],
                chain["phase_deg"],
                strict=True,
            )
        ]
        table.write_text("\n".join(rows) + "\n")
        corrected = impact.read_table(table)
        manifest = sha256_of(folder / MANIFEST_NAME)
        now = datetime.now(UTC)
        tasks = [
            impact.Task(f"run-{i}", str(folder), manifest, now, "SN-BENCH", None, ())
            for i in range(runs)
        ]
        serial = str(record.stand.reference.get("serial"))
        last = [0.0]

        def progress(done: int, total: int, elapsed: float) -> None:
            if elapsed - last[0] >= 10 or done == total:
                last[0] = elapsed
                print(impact.progress_line(done, total, elapsed), flush=True)

        if reps:
            parts(folder, tasks[0], serial, corrected, reps)
            return 0
        load_before = load_average()
        floor = baseline(str(folder), runs, workers)
        start = time.perf_counter()
        results = impact.assess(tasks, serial, corrected, workers=workers, progress=progress)
        total = time.perf_counter() - start
        load_after = load_average()
    problems = [r.problem for r in results if r.problem]
    if problems or not all(r.uses_reference for r in results):
        print(f"FAIL: {len(problems)} run(s) not checked: {problems[:1]}")
        return 1
    ratio = results[0].new_sensitivity / results[0].old_sensitivity  # type: ignore[operator]
    print(
        f"impact: {runs} runs re-analysed on {workers} worker(s) ({os.cpu_count()} cores): "
        f"total {total:.1f} s, {1000 * total / runs:.1f} ms per run "
        f"({1000 * total * workers / runs:.1f} ms of a worker per run); new/old at the "
        f"reference frequency {ratio:.9f} (table ratio 1.01)"
    )
    print(
        f"baseline (folder hashed, channels read), same runs and workers: total {floor:.1f} s, "
        f"{1000 * floor / runs:.2f} ms per run; impact / baseline = {total / floor:.1f}"
    )
    print(f"{load_before} before, {load_after} after")
    return 0 if abs(ratio - 1.01) < 1e-9 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
