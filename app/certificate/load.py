"""Reading what a certificate is made from: a stored, verified, complete run folder (its
record, results, budget and config.json as a RunStart) and, optionally, its sweep summary.

Nothing is recomputed; a run that does not verify or did not complete is refused by
CertificateError saying why.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from app.certificate.info import CertificateError
from app.io.checks import MAX_TEXT_BYTES, InputFileError, check_input_file
from app.records.run_folder import STATUS_COMPLETE, load_run
from app.records.run_record import RunRecord
from app.records.run_start import RunStart, RunStartError
from app.records.seal import named_seal
from app.records.sweep_summary import SweepSummary, SweepSummaryError
from dsp.calibration import Results
from dsp.uncertainty import Budget


@dataclass(frozen=True)
class StoredRun:
    """What the certificate reads from a run folder."""

    path: Path
    record: RunRecord
    start: RunStart
    results: Results
    budget: Budget = field(default_factory=Budget)


def load_stored_run(path: str | Path) -> StoredRun:
    """A complete run, or CertificateError saying why not."""
    path = Path(path)
    try:
        record = load_run(path)
        named_seal(path)  # a seal that does not match: results and manifest were remade
    except ValueError as exc:
        raise CertificateError(str(exc)) from None
    if record.status != STATUS_COMPLETE or not record.results:
        reason = record.abort_reason or "no results"
        raise CertificateError(
            f"{path}: the run is {record.status} ({reason}); no certificate is issued for "
            "an incomplete run"
        )
    try:
        start = RunStart.read(path)
    except RunStartError as exc:
        raise CertificateError(str(exc)) from None
    budget = Budget.from_list(list(record.budget))
    return StoredRun(path, record, start, Results.from_dict(dict(record.results)), budget)


def load_sweep(path: str | Path, run: StoredRun) -> SweepSummary:
    """A complete sweep summary that includes `run`; CertificateError otherwise."""
    path = Path(path)
    try:
        check_input_file(path, MAX_TEXT_BYTES, "sweep summary")
    except InputFileError as exc:
        raise CertificateError(f"--sweep {exc}") from None
    try:
        head = SweepSummary.read(path, with_table=False)
        if not head.complete:
            raise CertificateError(f"--sweep {path}: the sweep is not complete")
        if run.record.run_id not in head.run_ids:
            raise CertificateError(f"--sweep {path}: does not include run {run.record.run_id}")
        return SweepSummary.read(path)
    except SweepSummaryError as exc:
        raise CertificateError(f"--sweep {exc}") from None
