"""`accelcal verify`: check a certificate PDF (signature, DCC, the run it certifies)."""

from __future__ import annotations

import argparse

from app.cli.exits import EXIT_BAD_INPUT, EXIT_OK, UsageError


def cmd_verify(args: argparse.Namespace) -> int:
    """accelcal verify: exit 0 when every check holds, 2 when one fails or the input is bad."""
    from app.certificate.sign import verify

    for option, path in (("pdf", args.pdf), ("--trust", args.trust)):
        if path is not None and not path.is_file():
            raise UsageError(f"{option}: no such file {path}")
    if args.run is not None and not args.run.is_dir():
        raise UsageError(f"--run: no such run folder {args.run}")
    report = verify(args.pdf, args.run, args.trust)
    for name, ok, detail in report.checks:
        print(f"{'ok  ' if ok else 'FAIL'} {name}" + (f": {detail}" if detail else ""))
    print("certificate verified" if report.ok else "certificate NOT verified")
    return EXIT_OK if report.ok else EXIT_BAD_INPUT
