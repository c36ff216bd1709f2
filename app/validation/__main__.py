"""`python -m app.validation --out REPORT.pdf [--sign LAB.p12]`: run the validation cases and
write the report (the same as `accelcal validate`). Exit 0 when every case passed, 1 when any
failed, 2 (one line on stderr) for a report path that cannot be written."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from app.validation import ValidationInputError, validate


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m app.validation", description=__doc__)
    parser.add_argument("--out", type=Path, required=True, help="the report PDF to write")
    parser.add_argument(
        "--sign", type=Path, metavar="P12", help="sign the report with the lab's key (PKCS#12)"
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        return validate(args.out, args.sign)
    except ValidationInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
