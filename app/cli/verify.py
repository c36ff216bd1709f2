"""`accelcal verify`: check a certificate PDF (signature, DCC, the run it certifies)."""

from __future__ import annotations

import argparse

from app.cli.exits import EXIT_BAD_INPUT, EXIT_OK, UsageError


def cmd_verify(args: argparse.Namespace) -> int:
    """accelcal verify: exit 0 when every check holds, 2 when one fails or the input is bad."""
    from app.certificate.verify import verify

    if args.run is not None and not args.run.is_dir():
        raise UsageError(f"--run: no such run folder {args.run}")
    report = verify(args.pdf, args.run, args.trust)
    print("\n".join(report.lines()))
    return EXIT_OK if report.ok else EXIT_BAD_INPUT
