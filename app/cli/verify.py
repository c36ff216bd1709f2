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
    code = EXIT_OK if report.ok else EXIT_BAD_INPUT
    if args.validation_report is not None:
        code = max(code, _validation_report(args))
    return code


def _validation_report(args: argparse.Namespace) -> int:
    """--validation-report: the report's SHA-256 recomputed against the one the (verified)
    certificate names."""
    from app.certificate.validated import verify_report
    from app.certificate.validated_check import stated_report_sha256

    stated = stated_report_sha256(args.pdf)
    if stated is None:
        print("validation report: FAIL: the certificate names no validation report")
        return EXIT_BAD_INPUT
    verify_report(stated, args.validation_report)
    print(f"validation report: ok: {args.validation_report} is the one named (SHA-256 {stated})")
    return EXIT_OK
