"""`accelcal validate [--out report.pdf]`: the ISO/IEC 17025 7.11.2 software validation report
of the installed version (app.validation). Exit 0 when every case passed, 1 when any failed,
2 for a report path that cannot be written."""

from __future__ import annotations

import argparse
from datetime import UTC, datetime
from pathlib import Path


def cmd_validate(args: argparse.Namespace) -> int:
    from app.validation import validate

    out = args.out or Path(f"validation-{datetime.now(UTC).strftime('%Y%m%dT%H%M%SZ')}.pdf")
    code = validate(out)
    print(f"validation {'passed' if code == 0 else 'FAILED'}: report {out}")
    return code
