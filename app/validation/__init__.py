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
    from app.validation.cases import run_all
    from app.validation.report import environment, now_utc, software_identity, write_report

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
    the software with SHA-256 `software_sha256` (app.validation.report.software_identity), or
    None. For the certificate to name the validation report of its software version. The
    twin is not signed: whoever can write `folder` can claim a validation, so keep it with the
    lab's records."""
    import json

    found: list[tuple[str, Path]] = []
    for twin in sorted(Path(folder).glob("*.json")):
        try:
            record = json.loads(twin.read_text(encoding="utf-8"))
            ok = (
                record.get("passed") is True
                and record["software"]["sha256"] == software_sha256
                and all(case["passed"] is True for case in record["cases"])
                and bool(record["cases"])
            )
            when = str(record["date_utc"])
        except (OSError, ValueError, KeyError, TypeError):
            continue  # not a validation report
        pdf = twin.with_suffix(".pdf")
        if ok and pdf.is_file():
            found.append((when, pdf))
    return max(found)[1] if found else None
