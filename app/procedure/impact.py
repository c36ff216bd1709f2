"""Impact of a reference standard found out of tolerance (ISO/IEC 17025 7.10): every indexed run
that used it in a window, re-analysed from its raw recording with the corrected calibration
table through the one analysis path (app.procedure.analysis.analyze), old and new DUT
sensitivity (mV/(m/s^2)), the change in units of the stated expanded uncertainty U and the
verdicts that change. Runs are verified (index hash, manifest) in worker processes.
"""

from __future__ import annotations

import ctypes
import dataclasses
import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from app.errors import Refusal
from app.io.hdf5 import Recording
from app.io.reference_table import ReferenceTableError, read_reference_table
from app.procedure.analysis import analyze_chains, read_for_analysis
from app.procedure.verdict import tolerances_for
from app.records.run_folder import MANIFEST_NAME, inspect_run, sha256_of
from app.records.run_record import RunRecord
from app.records.run_start import RunStart
from dsp.calibration import ReferenceChain, Results

log = logging.getLogger(__name__)


class ImpactError(Refusal):
    """An impact assessment that cannot be made; the message names the option or file."""


@dataclass(frozen=True)
class CorrectedTable:
    """A reference standard's corrected calibration table: frequencies in Hz (increasing),
    sensitivity in mV/(m/s^2), relative expanded uncertainty, phase in degrees (None: the
    stored phase is kept), and the SHA-256 of the file it came from."""

    frequencies_hz: tuple[float, ...]
    sensitivity_mv_per_ms2: tuple[float, ...]
    relative_expanded_uncertainty: tuple[float, ...]
    phase_deg: tuple[float, ...] | None
    sha256: str = ""

    def chain(self, stored: ReferenceChain) -> ReferenceChain:
        """The stored reference chain with this table (gains and skew as stored; the stored
        phase, interpolated at this table's frequencies, when the table has none)."""
        phase = self.phase_deg
        if phase is None:
            phase = tuple(float(p) for p in stored.sensitivity_at(np.array(self.frequencies_hz))[1])
        return dataclasses.replace(
            stored,
            frequencies_hz=self.frequencies_hz,
            sensitivity_mv_per_ms2=self.sensitivity_mv_per_ms2,
            phase_deg=phase,
        )


def read_table(path: Path) -> CorrectedTable:
    """The corrected table CSV, read as `refs add --table` reads it (app.io.reference_table:
    frequency_hz, sensitivity mV/(m/s^2), relative expanded uncertainty IN PERCENT[,
    phase_deg]; `#` comments and a header line allowed). ImpactError naming the file and the
    line of a bad row."""
    try:
        rows = read_reference_table(path, "--table")
    except ReferenceTableError as exc:
        raise ImpactError(str(exc)) from None
    phases = [r[3] for r in rows]
    if len({p is None for p in phases}) > 1:
        raise ImpactError(f"--table: {path}: phase given on some rows only")
    return CorrectedTable(
        tuple(r[0] for r in rows),
        tuple(r[1] for r in rows),
        tuple(r[2] for r in rows),
        None if phases[0] is None else tuple(float(p or 0.0) for p in phases),
        sha256_of(path),
    )


@dataclass(frozen=True)
class Task:
    """One indexed run to check: its folder, the manifest hash the index holds, and what the
    report needs about it from the records."""

    run_id: str
    folder: str
    manifest_sha256: str
    started_utc: datetime
    dut_id: str
    owner: str | None
    certificates: tuple[str, ...]


@dataclass(frozen=True)
class RunImpact:
    """A run's outcome. `uses_reference` False: another reference (not in the report);
    `problem` set: the run could not be checked (named why). Sensitivities and U at the
    reference frequency in mV/(m/s^2); `change_in_u` = (new - old) / U_old there;
    `worst_change_in_u` the largest |change| / U over every line, at `worst_frequency_hz`."""

    task: Task
    uses_reference: bool
    problem: str | None = None
    reference_frequency_hz: float | None = None
    stored_sensitivity: float | None = None
    old_sensitivity: float | None = None
    new_sensitivity: float | None = None
    expanded_uncertainty: float | None = None
    change_in_u: float | None = None
    worst_change_in_u: float | None = None
    worst_frequency_hz: float | None = None
    old_verdict: str | None = None
    new_verdict: str | None = None

    @property
    def verdict_changed(self) -> bool:
        return self.old_verdict != self.new_verdict and self.new_verdict is not None


def uses_reference(record: RunRecord, start: RunStart, serial: str) -> bool:
    """Whether the run used reference standard `serial` (its serial or its id): the run
    record's stand reference, else the stored config.json's stand [reference] table."""
    reference = dict(record.stand.reference) or start.reference
    wanted = serial.strip().casefold()
    return any(
        str(reference.get(key) or "").strip().casefold() == wanted for key in ("serial", "id")
    )


def reanalyse(task: Task, serial: str, table: CorrectedTable) -> RunImpact:
    """Verify one run (the manifest the index holds, then the folder), and when it used
    reference `serial`, re-analyse its recording with the stored and with the corrected table
    through the same path (app.procedure.analysis.analyze, same tolerances)."""
    folder = Path(task.folder)
    try:
        if sha256_of(folder / MANIFEST_NAME) != task.manifest_sha256:
            return RunImpact(task, True, f"{folder}: manifest differs from the one indexed")
        check = inspect_run(folder)
        if check.record is None:
            return RunImpact(task, True, "; ".join(check.problems) or f"{check.state}")
        record = check.record
        start = RunStart.read(folder)
        if not uses_reference(record, start, serial):
            return RunImpact(task, False)
        recording = read_for_analysis(folder, check=check)  # verified above: not again
        # a triaxial sensor's cross channel is analysed as its run was (no verdict: issue 36)
        transverse = start.batch is not None and start.batch.transverse
        return _compare(task, record, recording, table, transverse=transverse)
    except (OSError, ValueError) as exc:  # refusals included: named, never a traceback
        return RunImpact(task, True, f"{folder}: {exc}")


def _compare(
    task: Task,
    record: RunRecord,
    recording: Recording,
    table: CorrectedTable,
    *,
    transverse: bool = False,
) -> RunImpact:
    """Old (stored table) and new (corrected table) analyses of one verified recording."""
    settings = record.analysis
    catalogue = record.dut.catalogue if record.dut else None
    tolerances = tolerances_for(
        catalogue, recording.plan.reference_frequency_hz, settings.tolerance_percent
    )
    options: dict[str, Any] = dict(
        estimator=settings.estimator,
        probability=settings.probability,
        rule=settings.rule,
        tolerances=tolerances,
        transverse=transverse,
    )
    old, new = analyze_chains(  # read and estimated once: the chain enters the results only
        recording, [recording.chain, table.chain(recording.chain)], **options
    )
    return _impact(task, record, old.results, new.results)


def _impact(task: Task, record: RunRecord, old: Results, new: Results) -> RunImpact:
    stored = record.reference_result
    u_old = old.reference.expanded_uncertainty_mv_per_ms2
    s_old, s_new = old.reference.sensitivity_mv_per_ms2, new.reference.sensitivity_mv_per_ms2
    worst, worst_f = None, None
    for a, b in zip(old.lines, new.lines, strict=True):
        u = a.expanded_uncertainty_mv_per_ms2
        if u and math.isfinite(u) and u > 0 and b.stated:  # a line not stated: no change
            change = (b.sensitivity_mv_per_ms2 - a.sensitivity_mv_per_ms2) / u
            if worst is None or abs(change) > abs(worst):
                worst, worst_f = change, a.nominal_frequency_hz
    return RunImpact(
        task,
        True,
        reference_frequency_hz=old.reference.frequency_hz,
        stored_sensitivity=stored.sensitivity_mv_per_ms2 if stored is not None else None,
        old_sensitivity=s_old,
        new_sensitivity=s_new,
        expanded_uncertainty=u_old,
        change_in_u=(s_new - s_old) / u_old if u_old and u_old > 0 else None,
        worst_change_in_u=worst,
        worst_frequency_hz=worst_f,
        old_verdict=record.verdict or old.verdict,
        new_verdict=new.verdict,
    )


Progress = Callable[[int, int, float], None]  # done, total, seconds elapsed

PR_SET_PDEATHSIG = 1  # linux/prctl.h
PARENT_POLL_S = 0.5


def end_with_parent(parent_pid: int) -> None:
    """A worker's initializer: the worker ends when its parent does, also when the parent is
    killed (SIGKILL leaves it no way to stop its pool; issue 33 point 6 found 6 workers of
    130 MB each left): the kernel's parent-death signal on Linux (prctl PR_SET_PDEATHSIG), and
    everywhere a thread that ends the worker once its parent is no longer `parent_pid`."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError) as exc:  # the watch below still ends it
            log.debug("prctl(PR_SET_PDEATHSIG) not available: %s", exc)
    if os.getppid() != parent_pid:  # the parent died before the signal was asked for
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def assess(
    tasks: Sequence[Task],
    serial: str,
    table: CorrectedTable,
    *,
    workers: int = 1,
    progress: Progress | None = None,
) -> list[RunImpact]:
    """Every task checked (in a pool of `workers` processes when more than one), in the
    tasks' order; `progress(done, total, elapsed_s)` after each."""
    start = time.monotonic()
    results: dict[int, RunImpact] = {}
    if workers <= 1 or len(tasks) <= 1:
        for i, task in enumerate(tasks):
            results[i] = reanalyse(task, serial, table)
            if progress:
                progress(i + 1, len(tasks), time.monotonic() - start)
    else:
        with ProcessPoolExecutor(
            max_workers=workers, initializer=end_with_parent, initargs=(os.getpid(),)
        ) as pool:
            futures = {pool.submit(reanalyse, t, serial, table): i for i, t in enumerate(tasks)}
            for done, future in enumerate(as_completed(futures), 1):
                results[futures[future]] = future.result()
                if progress:
                    progress(done, len(tasks), time.monotonic() - start)
    return [results[i] for i in range(len(tasks))]


def progress_line(done: int, total: int, elapsed_s: float) -> str:
    """ "impact: 12/40 runs, 3 s, about 7 s left" (time left from the mean so far)."""
    left = elapsed_s / done * (total - done) if done else float("nan")
    tail = f", about {left:.0f} s left" if done < total and math.isfinite(left) else ""
    return f"impact: {done}/{total} runs, {elapsed_s:.0f} s{tail}"


def review_reason(serial: str, impact: RunImpact, table: CorrectedTable) -> str:
    """The register's reason for flagging a certificate of `impact`'s run."""
    if impact.problem:
        return (
            f"under review: impact of reference {serial} (corrected table sha256 "
            f"{table.sha256[:16]}): run {impact.task.run_id} could not be re-analysed "
            f"({impact.problem}); to amend or confirm"
        )
    verdict = (
        f"; verdict {impact.old_verdict} -> {impact.new_verdict}" if impact.verdict_changed else ""
    )
    change = "n/a" if impact.change_in_u is None else f"{impact.change_in_u:+.2f} U"
    return (
        f"under review: impact of reference {serial} (corrected table sha256 "
        f"{table.sha256[:16]}): sensitivity {impact.old_sensitivity:.6g} -> "
        f"{impact.new_sensitivity:.6g} mV/(m/s^2) at {impact.reference_frequency_hz:g} Hz "
        f"({change}){verdict}; to amend or confirm"
    )


def review_subject(serial: str) -> str:
    """The register's subject of the reviews the impact of reference `serial` opens (the
    records' wording; imported here so the worker processes need no SQLAlchemy)."""
    from app.records.db.reviews import impact_subject

    return impact_subject(serial)
