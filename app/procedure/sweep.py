"""Amplitude sweep (SPEC.md section 5, seed Fig. 4): the procedure at several levels on the same
stand; sensitivity against frequency and level, and a linearity figure.

Linearity per line: the largest relative deviation of the sensitivity at any level from its
mean over the levels, in %. The sweep summary (app.records.sweep_summary.SweepSummary) is
written beside the run folders as sweep-<id>.json (atomically, never replacing a file,
read-only); each level is a run folder of its own.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app.files import write_with
from app.io.vocabulary import RunStatus
from app.procedure import Finished, Listener, PreflightError
from app.procedure.run import RunRequest, execute, prepare
from app.records.run_folder import new_run_id
from app.records.sweep_summary import SweepSummary, SweepTable
from app.stand.config import StandConfig


@dataclass(frozen=True)
class Sweep:
    """The runs of a sweep (in level order), its summary and the file it is written to."""

    runs: tuple[Finished, ...]
    result: SweepSummary
    path: Path

    @property
    def complete(self) -> bool:
        return self.result.complete

    @property
    def summary(self) -> dict[str, Any]:
        """The summary as its JSON object plus "path", for the CLI's printer (which is to read
        `result` instead)."""
        return {**self.result.to_dict(), "path": str(self.path)}


def linearity(sensitivity: np.ndarray) -> np.ndarray:
    """Per line (columns), max |S(level) / mean(S) - 1| over levels (rows), as a fraction."""
    mean = sensitivity.mean(axis=0)
    return np.max(np.abs(sensitivity / mean - 1.0), axis=0)


def run_sweep(
    request: RunRequest,
    levels: list[float],
    listener: Listener | None = None,
    *,
    config: StandConfig | None = None,
) -> Sweep:
    """Run `request` at each level (ascending); stop at the first run that does not complete.
    `config`: the stand file as the run service loaded it (None: loaded per run)."""
    if len(levels) < 2:
        raise ValueError("--levels: a sweep needs at least two levels")
    if any(not level > 0 for level in levels):
        raise ValueError("--levels: every level must be > 0 m/s^2")
    for level in sorted(levels):  # every level is checked before anything moves
        try:
            _, stand = prepare(dataclasses.replace(request, level_ms2=level), config=config)
        except PreflightError as exc:
            raise PreflightError(f"level {level:g} m/s^2: {exc}") from None
        stand.close()
    runs = []
    for level in sorted(levels):
        finished = execute(dataclasses.replace(request, level_ms2=level), listener, config=config)
        runs.append(finished)
        if finished.status != RunStatus.COMPLETE:
            break
    summary = summarise(runs, sorted(levels))
    sweep_id = new_run_id(f"sweep-{request.dut_id or request.dut}")
    path = Path(request.out) / f"{sweep_id}.json"
    write_with(path, summary.write)
    return Sweep(tuple(runs), summary, path)


def summarise(runs: list[Finished], levels: list[float]) -> SweepSummary:
    """Sensitivity against frequency and level, linearity per line and at the reference."""
    complete = [r for r in runs if r.status == RunStatus.COMPLETE and r.results is not None]
    summary = SweepSummary(
        status=RunStatus.COMPLETE if len(complete) == len(levels) else RunStatus.ABORTED,
        levels_ms2=tuple(levels),
        run_ids=tuple(str(r.record.run_id) for r in runs),
        abort_reason=next((r.abort_reason for r in runs if r.status != RunStatus.COMPLETE), None),
    )
    if len(complete) < 2:
        return summary
    results = [r.results for r in complete if r.results is not None]
    first = results[0]
    # the lines stated at every level (a line outside the reference's range is never stated)
    stated = [k for k in range(len(first.lines)) if all(r.lines[k].stated for r in results)]
    frequencies = [first.lines[k].nominal_frequency_hz for k in stated]
    table = np.array([[r.lines[k].sensitivity_mv_per_ms2 for k in stated] for r in results])
    lin = linearity(table)
    ref = frequencies.index(first.reference.frequency_hz)
    return dataclasses.replace(
        summary,
        table=SweepTable(
            frequencies_hz=tuple(frequencies),
            sensitivity_mv_per_ms2=tuple(tuple(row) for row in table.tolist()),
            linearity_percent=tuple((100 * lin).tolist()),
            reference_frequency_hz=first.reference.frequency_hz,
            reference_linearity_percent=float(100 * lin[ref]),
            worst_linearity_percent=float(100 * lin.max()),
            worst_linearity_frequency_hz=float(frequencies[int(np.argmax(lin))]),
        ),
    )
