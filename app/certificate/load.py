"""Reading what a certificate is made from: a stored, verified, complete run folder (its
record, results, budget and config.json as a RunStart) and, optionally, its sweep summary.

Nothing is recomputed; a run that does not verify or did not complete is refused by
CertificateError saying why, and so is one whose stored budget does not state the ISO 16063-21
Annex A components or whose results carry a warning that blocks the certificate
(app.records.warnings; issue 25 points 1 and 2): checked from the sealed budget and results,
not from the stored verdict.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from app.certificate.info import CertificateError
from app.io.checks import MAX_TEXT_BYTES, InputFileError, check_input_file
from app.procedure.verdict import run_warnings
from app.records.run_folder import STATUS_COMPLETE, load_run
from app.records.run_record import RunRecord
from app.records.run_start import RunStart, RunStartError
from app.records.seal import named_seal
from app.records.sweep_summary import SweepSummary, SweepSummaryError
from app.records.warnings import blocking
from dsp.annex_a import implausible_components, missing_components
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


def load_stored_run(path: str | Path, *, certifiable: bool = True) -> StoredRun:
    """A complete run, or CertificateError saying why not; `certifiable=False` skips
    `check_certifiable` (a triaxial sensor's cross channel: app.certificate.triaxial)."""
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
    try:
        budget = Budget.from_list(list(record.budget))
        results = Results.from_dict(dict(record.results))
    except ValueError as exc:
        raise CertificateError(f"{path}: {exc}") from None
    run = StoredRun(path, record, start, results, budget)
    if certifiable:
        check_certifiable(run)
    return run


def check_certifiable(run: StoredRun) -> None:
    """CertificateError when the run's budget has an implausible component or lacks ISO
    16063-21 Annex A components (named), the run states no CMC (issue 32 point 1), or a warning
    of the run blocks the certificate (each named): results for review only; or the run is a
    triaxial sensor's cross channel (its sensitivity a transverse one: the triaxial
    certificate states it, issue 36 point 3)."""
    link = run.start.batch
    if link is not None and link.transverse:
        raise CertificateError(
            f"{run.path}: no certificate: channel {link.channel} is a cross channel of the "
            f"triaxial DUT's orientation {link.orientation} run (a transverse sensitivity, no "
            "verdict); its figures go on the triaxial certificate: accelcal certificate "
            "--triaxial BATCH_X BATCH_Y BATCH_Z"
        )
    refused = implausible_components(run.budget)
    if refused:
        raise CertificateError(
            f"{run.path}: no certificate: the run's budget has implausible component(s): "
            f"{'; '.join(refused)}; the run is results for review only"
        )
    missing = missing_components(run.budget)
    if missing:
        raise CertificateError(
            f"{run.path}: no certificate: the run's budget does not state the ISO 16063-21 "
            f"Annex A component(s) {'; '.join(missing)}; the run is results for review only "
            "(state them in the stand file's [[component]] entries with their kind)"
        )
    if not run.results.cmc:
        raise CertificateError(
            f"{run.path}: no certificate: the run states no CMC of the laboratory, so nothing "
            "bounds its uncertainty from below (ILAC P14); state the scope's [[cmc]] bands in "
            "the stand file and run again"
        )
    blocked = blocking(run_warnings(run.results))
    if blocked:
        reasons = "; ".join(f"{w.kind.value}: {w.text}" for w in blocked)
        raise CertificateError(
            f"{run.path}: no certificate: {reasons} (results for review only; the blocking "
            "warnings are listed in docs/validation.md)"
        )


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
