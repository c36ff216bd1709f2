"""`accelcal verify`: check a certificate PDF (signature, DCC, the run it certifies)."""

from __future__ import annotations

import argparse
import sys

from app.cli.exits import EXIT_BAD_INPUT, EXIT_OK, UsageError


def cmd_verify(args: argparse.Namespace) -> int:
    """accelcal verify: exit 0 when every check holds, 2 when one fails or the input is bad."""
    from app.certificate.verify import verify

    if args.run is not None and not args.run.is_dir():
        raise UsageError(f"--run: no such run folder {args.run}")
    from app.records.db.engine import records_url

    records = records_url(args.db)
    report = verify(args.pdf, args.run, args.trust, records)
    for note in report.notes:  # beside the report, not one of its checks
        print(note, file=sys.stderr)
    print("\n".join(report.lines()))
    code = EXIT_OK if report.ok else EXIT_BAD_INPUT
    if args.triaxial is not None:
        code = max(code, _triaxial(args))
    if args.validation_report is not None:
        code = max(code, _validation_report(args))
    return code


def _triaxial(args: argparse.Namespace) -> int:
    """--triaxial BX BY BZ: the certificate's triaxial section (its DCC) recomputed from the
    three orientation batches (each batch's seal, each of the nine runs' manifest and seal
    checked as a certificate loads them) and compared value by value; a FAIL line naming
    each difference, exit 2."""
    from app.certificate.info import CertificateError
    from app.certificate.triaxial_issue import (
        dcc_of,
        section_differences,
        triaxial_result_of,
        triaxial_runs,
    )
    from app.cli.certificate import batch_folder

    try:
        runs = triaxial_runs([batch_folder(text, "--triaxial") for text in args.triaxial])
        result = triaxial_result_of(runs)
        differences = section_differences(dcc_of(args.pdf), result)
    except CertificateError as exc:
        print(f"FAIL triaxial section: {exc}")
        return EXIT_BAD_INPUT
    if args.run is not None and args.run.resolve() != runs.main_run.resolve():
        differences.append(f"--run {args.run} is not the x orientation's x run {runs.main_run}")
    if differences:
        for text in differences:
            print(f"FAIL triaxial section: {text}")
        return EXIT_BAD_INPUT
    print(
        "ok   triaxial section: equal to the nine runs of batches "
        + ", ".join(f"{o} {b}" for o, b in sorted(runs.batches.items()))
    )
    return EXIT_OK


def _validation_report(args: argparse.Namespace) -> int:
    """--validation-report: the report's SHA-256 recomputed against the one the certificate
    names, then the report itself proved (app.certificate.validated.read_report): the lab's
    signature checked against --trust, the software it validated equal to the one the
    certificate states, every case passed, not dated in the future. A report that does not
    prove itself: a FAIL line naming what was found, exit 2."""
    from app.certificate.validated import ValidationClaimError, software_identity
    from app.certificate.validated_check import stated_validation, trust_from_ca, verify_report

    stated = stated_validation(args.pdf)
    if stated is None:
        print("validation report: FAIL: the certificate names no validation report")
        return EXIT_BAD_INPUT
    if stated.software_sha256 is None:
        print(
            "validation report: FAIL: the certificate names the report by its hash only (made "
            "before reports were signed): nothing proves it"
        )
        return EXIT_BAD_INPUT
    trust = trust_from_ca(args.trust) if args.trust is not None else None
    try:
        claim = verify_report(
            stated.report_sha256, args.validation_report, trust, stated.software_sha256
        )
    except ValidationClaimError as exc:
        print(f"validation report: FAIL: {exc}")
        return EXIT_BAD_INPUT
    assert claim is not None
    print(
        f"validation report: ok: {args.validation_report} is the one named (SHA-256 "
        f"{stated.report_sha256}), signed by {claim.signer}, {claim.cases} cases passed for "
        f"software {claim.software_sha256} on {claim.date_utc[:10]}"
    )
    if software_identity().sha256 != claim.software_sha256:
        print(
            "validation report: note: the software running this check is not the validated "
            "one (another installation or version); the certificate's claim is checked as stated"
        )
    return EXIT_OK
