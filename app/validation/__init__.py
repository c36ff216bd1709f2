"""Software validation (ISO/IEC 17025:2017 7.11.2; issue 27 point 2, issue 33 point 4):
`validate(out, sign)` runs the validation cases (app.validation.cases) on the installed code and
writes the report (app.validation.report): one PDF at `out` carrying its record and, with the
lab's key, the lab's signature (the only form a certificate names), a readable JSON copy beside
it. Exit status 0 only when every case passed, 1 otherwise.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from app.errors import Refusal
from app.files import FileExistsRefusal

log = logging.getLogger(__name__)


class ValidationInputError(Refusal):
    """A report path that cannot be written; the message names the option and the reason."""


def validate(out: Path, sign: Path | None = None) -> int:
    """Run every validation case and write the report to `out` (and its .json copy), signed
    with the PKCS#12 key `sign` (password from $ACCELCAL_SIGN_PASSWORD) when given: 0 when
    every case passed, 1 when any failed. ValidationInputError (nothing run) when `out` or its
    copy exists, is not a .pdf, its folder is missing, or the key cannot be used."""
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
    signer = None
    if sign is not None:
        from app.certificate.sign import Signer, SigningError

        try:
            signer = Signer.load(Path(sign))
        except SigningError as exc:
            raise ValidationInputError(str(exc)) from None
    else:
        log.warning(
            "the report is not signed (no --sign): no certificate will name it as the "
            "software's validation"
        )
    software = software_identity()
    log.info("validating accelcal %s (files SHA-256 %s)", software.version, software.sha256)
    cases = run_all()
    try:
        write_report(out, cases, software, environment(), now_utc(), signer)
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


def passed_report(folder: Path, software_sha256: str, trust: list[Any] | None) -> Path | None:
    """The newest validation report PDF in `folder` that proves itself for the software with
    SHA-256 `software_sha256` against the trust anchors `trust` (signed by the lab, every case
    passed, not dated in the future: app.certificate.validated_check.read_report), or None."""
    from app.certificate.validated_check import folder_claim

    claim = folder_claim(Path(folder), trust, software_sha256).claim
    return None if claim is None else Path(folder) / claim.report
