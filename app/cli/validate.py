"""`accelcal validate [--out report.pdf] [--sign LAB.p12]`: the ISO/IEC 17025 7.11.2 software
validation report of the installed version (app.validation), signed with the lab's key. Without
--out it goes to the lab's validation folder (app.certificate.validated: $ACCELCAL_VALIDATION_DIR,
else the user's data directory), where a certificate looks for the report of its software; a
certificate names only a signed report. Exit 0 when every case passed, 1 when any failed, 2 for
a report path that cannot be written or a key that cannot be used."""

from __future__ import annotations

import argparse
from datetime import UTC, datetime
from pathlib import Path


def default_out() -> Path:
    """validation-<UTC time>.pdf in the lab's validation folder (created when missing)."""
    from app.certificate.validated import validation_folder

    folder = validation_folder()
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"validation-{datetime.now(UTC).strftime('%Y%m%dT%H%M%SZ')}.pdf"


def cmd_validate(args: argparse.Namespace) -> int:
    from app.validation import validate

    out = args.out or default_out()
    code = validate(out, args.sign)
    signed = (
        "signed" if args.sign is not None else "NOT signed (no --sign: no certificate names it)"
    )
    print(f"validation {'passed' if code == 0 else 'FAILED'}: report {out}, {signed}")
    return code
