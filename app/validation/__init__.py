"""Software validation (ISO/IEC 17025:2017 7.11.2; issue 27 point 2): `validate(out)` runs the
validation cases (app.validation.cases) on the installed code and writes the report
(app.validation.report): PDF at `out`, its JSON twin beside it. Exit status 0 only when every
case passed, 1 otherwise.
"""

from __future__ import annotations

import logging
from pathlib import Path

from app.errors import Refusal
from app.files import FileExistsRefusal

log = logging.getLogger(__name__)


class ValidationInputError(Refusal):
    """A report path that cannot be written; the message names the option and the reason."""


def validate(out: Path) -> int:
    """Run every validation case and write the report to `out` (and its .json twin): 0 when
    every case passed, 1 when any failed. ValidationInputError (nothing run) when `out` or its
    twin exists, is not a .pdf, or its folder is missing."""
    from app.certificate.validated import software_identity
    from app.validation.cases import run_all
    from app.validation.report import environment, now_utc, write_report

    out = Path(out)
    if out.suffix.lower() != ".pdf":
        raise ValidationInputError(f"--out: {out}: the report is a PDF (name it .pdf)")
    for path in (out, out.with_suffix(".json")):
        if path.exists():
            raise ValidationInputError(f"--out: {path}: exists; a report is never overwritten")
    if not out.parent.is_dir():
        raise ValidationInputError(f"--out: {out.parent}: no such folder")
    software = software_identity()
    log.info("validating accelcal %s (files SHA-256 %s)", software.version, software.sha256)
    cases = run_all()
    try:
        write_report(out, cases, software, environment(), now_utc())
    except FileExistsRefusal as exc:  # appeared while the cases ran
        raise ValidationInputError(f"--out: {exc}") from None
    failed = [case for case in cases if not case.passed]
    for case in failed:
        log.error(
            "validation case failed: %s: expected %s, obtained %s (tolerance %s)",
            case.name,
            case.expected,
            case.obtained,
            case.tolerance,
        )
    log.info(
        "validation: %d of %d cases passed; report %s", len(cases) - len(failed), len(cases), out
    )
    return 0 if not failed else 1


def passed_report(folder: Path, software_sha256: str) -> Path | None:
    """The newest validation report PDF in `folder` whose JSON twin says every case passed for
    the software with SHA-256 `software_sha256` and whose PDF still has the SHA-256 the twin
    records (app.certificate.validated, where the certificate's claim is made), or None."""
    from app.certificate.validated import passed_claim

    claim = passed_claim(Path(folder), software_sha256)
    return None if claim is None else Path(folder) / claim.report
