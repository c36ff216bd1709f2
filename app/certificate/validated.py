"""Which software validation report (ISO/IEC 17025 7.11.2) a certificate names: the software's
identity (version and the SHA-256 over its installed files), the folder where the lab keeps its
validation reports, and the claim a certificate states (`ValidationClaim`).

A report proves itself only as one signed PDF made by `accelcal validate --sign` (its record
embedded as REPORT_ATTACHMENT under the lab's signature); reading and proving it is
app.certificate.validated_check (`read_report`, `folder_claim`, `verify_report`), which uses
the signature checks of app.certificate.verify.
"""

from __future__ import annotations

import hashlib
import importlib
import os
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path

from app.errors import Refusal

PACKAGES = ("dsp", "hardware", "sim", "app")  # what the software hash covers
FOLDER_ENV = "ACCELCAL_VALIDATION_DIR"
REPORT_ATTACHMENT = "validation.json"  # the signed record inside the report PDF
MAX_REPORT_BYTES = 20 << 20
MAX_REPORTS = 200  # the newest report files of a folder that are examined
CLOCK_SKEW = timedelta(minutes=5)  # a report dated later than now + this is refused


class ValidationClaimError(Refusal):
    """A validation report that is not the one a certificate names, or that does not prove
    itself; the message names the report and what was found."""


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
    of its PDF, the software it validated, its number of cases and who signed it."""

    report: str
    date_utc: str
    report_sha256: str
    software_version: str
    software_sha256: str
    cases: int = 0
    signer: str = ""

    def line(self) -> str:
        """The certificate's sentence."""
        return (
            f"The software (accelcal {self.software_version}, files SHA-256 "
            f"{self.software_sha256}) was validated per ISO/IEC 17025:2017 7.11.2: report "
            f"{self.report} of {self.date_utc[:10]}, all {self.cases} cases passed, signed by "
            f"{self.signer}; the report PDF's SHA-256 is {self.report_sha256}."
        )


STATEMENT_NAME = "Software validation"  # the DCC statement and the PDF heading
