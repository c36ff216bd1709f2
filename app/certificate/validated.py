"""Which software validation report (ISO/IEC 17025 7.11.2) a certificate names: the software's
identity (version and the SHA-256 over its installed files), the folder where the lab keeps its
validation reports, and the newest report there that passed for this very software.

A report's JSON twin carries the SHA-256 of its PDF; a report counts only while its PDF still
has that hash, and the certificate states the hash, so whoever holds the report can check the
claim (`verify_report`) rather than trust the folder.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

from app.errors import Refusal

PACKAGES = ("dsp", "hardware", "sim", "app")  # what the software hash covers
FOLDER_ENV = "ACCELCAL_VALIDATION_DIR"
MAX_TWIN_BYTES = 4 << 20


class ValidationClaimError(Refusal):
    """A validation report that is not the one a certificate names; the message says why."""


@dataclass(frozen=True)
class Software:
    """The validated software: version, SHA-256 over its installed files, their number."""

    version: str
    sha256: str
    files: int


def software_identity() -> Software:
    """Version (app.version) and the SHA-256 of every installed file of PACKAGES (no bytecode):
    over the sorted lines 'package/relative/path <sha256 of the file>'."""
    from app.version import software_version

    lines = []
    for package in PACKAGES:
        root = Path(str(importlib.import_module(package).__file__)).parent
        for path in sorted(root.rglob("*")):
            if not path.is_file() or "__pycache__" in path.parts or path.suffix == ".pyc":
                continue
            digest = hashlib.sha256(path.read_bytes()).hexdigest()
            lines.append(f"{package}/{path.relative_to(root).as_posix()} {digest}")
    total = hashlib.sha256("\n".join(lines).encode("utf-8")).hexdigest()
    return Software(software_version(), total, len(lines))


def validation_folder() -> Path:
    """Where the lab keeps its validation reports: $ACCELCAL_VALIDATION_DIR, else
    `validation` in the user's data directory (what `accelcal validate` writes by default)."""
    explicit = os.environ.get(FOLDER_ENV)
    if explicit:
        return Path(explicit)
    from platformdirs import user_data_dir

    return Path(user_data_dir("accelcal", appauthor=False)) / "validation"


@dataclass(frozen=True)
class ValidationClaim:
    """The validation report a certificate names: its file name, date (UTC, ISO), the SHA-256
    of its PDF, and the software it validated."""

    report: str
    date_utc: str
    report_sha256: str
    software_version: str
    software_sha256: str

    def line(self) -> str:
        """The certificate's sentence."""
        return (
            f"The software (accelcal {self.software_version}, files SHA-256 "
            f"{self.software_sha256}) was validated per ISO/IEC 17025:2017 7.11.2: report "
            f"{self.report} of {self.date_utc[:10]}, all cases passed; the report PDF's "
            f"SHA-256 is {self.report_sha256}."
        )


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _claim(twin: Path, software_sha256: str) -> ValidationClaim | None:
    """The claim of one JSON twin when it passed for `software_sha256` and its PDF still has
    the hash the twin records; else None."""
    try:
        if twin.is_symlink() or not twin.is_file() or twin.stat().st_size > MAX_TWIN_BYTES:
            return None
        record = json.loads(twin.read_text(encoding="utf-8"))
        ok = (
            record.get("passed") is True
            and record["software"]["sha256"] == software_sha256
            and bool(record["cases"])
            and all(case["passed"] is True for case in record["cases"])
        )
        pdf = twin.with_suffix(".pdf")
        if not ok or pdf.is_symlink() or not pdf.is_file():
            return None
        pdf_sha = str(record["report_pdf_sha256"])
        if _sha256(pdf) != pdf_sha:
            return None  # the PDF is not the one the twin was written with
        return ValidationClaim(
            pdf.name,
            str(record["date_utc"]),
            pdf_sha,
            str(record["software"].get("version") or ""),
            software_sha256,
        )
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None  # not a validation report


def passed_claim(folder: Path, software_sha256: str) -> ValidationClaim | None:
    """The newest report in `folder` that passed for the software `software_sha256` and whose
    PDF still has the SHA-256 its twin records, or None."""
    found = [
        (claim.date_utc, claim)
        for twin in sorted(Path(folder).glob("*.json"))
        if (claim := _claim(twin, software_sha256)) is not None
    ]
    return max(found, key=lambda item: item[0])[1] if found else None


def current_claim() -> ValidationClaim | None:
    """The claim for the installed software from the lab's validation folder, or None (no
    folder, or no passed report of this software)."""
    folder = validation_folder()
    if not folder.is_dir():
        return None
    return passed_claim(folder, software_identity().sha256)


def verify_report(stated_sha256: str, report: Path) -> None:
    """ValidationClaimError unless `report`'s SHA-256 is the one a certificate states."""
    if not report.is_file():
        raise ValidationClaimError(f"--validation-report: no such file {report}")
    actual = _sha256(report)
    if actual != stated_sha256.strip().lower():
        raise ValidationClaimError(
            f"--validation-report: {report} has SHA-256 {actual}, the certificate names "
            f"{stated_sha256}"
        )


STATEMENT_NAME = "Software validation"  # the DCC statement and the PDF heading
