"""What a run ends with, as every face receives it from the run service: the run record, its
results, its folder, the records' indexing note and the exit status a script sees.

Exit statuses (`accelcal run`; the GUI's headless `--autorun` alike): 0 the run completed (any
verdict, unless asked otherwise), 1 a failure of the program or the hardware, 2 refused before
anything moved (bad input, a preflight refusal), 3 aborted, 4 completed with the verdict FAIL
when the run was asked to say so (`run --fail-exit`; without it a FAIL run exits 0, as before).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import TYPE_CHECKING

from app.procedure.errors import refused
from dsp.conformity import Verdict

if TYPE_CHECKING:
    from app.records.run_record import RunRecord
    from dsp.calibration import Results


class ExitStatus(IntEnum):
    """The process exit status of a command (module docstring)."""

    OK = 0
    FAILURE = 1
    BAD_INPUT = 2
    ABORTED = 3
    FAIL_VERDICT = 4


def exit_status(record: RunRecord, *, fail_exit: bool = False) -> ExitStatus:
    """The exit status of a finished run: complete 0 (4 with `fail_exit` when its verdict is
    FAIL), refused before anything moved 2, otherwise aborted 3."""
    if record.complete:
        if fail_exit and record.verdict == Verdict.FAIL:
            return ExitStatus.FAIL_VERDICT
        return ExitStatus.OK
    return ExitStatus.BAD_INPUT if refused(record.abort_reason) else ExitStatus.ABORTED


@dataclass(frozen=True)
class RunOutcome:
    """A finished run as the faces show it: `folder` None when the run made none (refused
    before it started), `index_note` the records' report (None: no records in use)."""

    record: RunRecord
    results: Results | None
    folder: Path | None
    index_note: str | None
    exit_status: ExitStatus
    notes: tuple[str, ...] = ()
