"""`accelcal certificate`: the PDF certificate (and DCC) of a stored complete run. The options
are parsed into an `app.certificate.service.IssueRequest` and issued by the certificate
service, the same call the GUI's certificate dialog makes (which register, who prepared it, the
two-person rule, staging, signing: all there); this prints what was issued."""

from __future__ import annotations

import argparse

from app.cli.exits import EXIT_OK
from app.cli.options import writable_folder


def cmd_certificate(args: argparse.Namespace) -> int:
    from app.certificate import CertificateInfo
    from app.certificate.info import CertificateError, Specification, SpecKind
    from app.certificate.service import IssueRequest, issue_certificate
    from app.records.run_folder import is_run_folder

    if args.out is not None and not is_run_folder(args.out.parent):  # a run's own: see issue()
        writable_folder(args.out.parent, "--out")
    specification = None
    if args.spec_kind or args.spec_id or args.spec_tolerances:
        if not (args.spec_kind and args.spec_id):
            raise CertificateError(
                "specification (--spec-kind, --spec-id): give its kind and its document"
            )
        specification = Specification(
            SpecKind(args.spec_kind), " ".join(args.spec_id.split()), args.spec_tolerances or ""
        )
    request = IssueRequest(
        run=args.run,
        info=CertificateInfo(
            customer=args.customer,
            customer_address=args.customer_address,
            address_not_stated=args.address_not_stated,
            humidity_percent=args.humidity,
            specification=specification,
            authorised_by=args.authorised_by,
            dut_model=args.dut_model,
            dut_serial=args.dut_serial,
            dut_type=args.dut_type,
            temperature_c=args.temperature,
            mounting=args.mounting,
            certificate_number=args.certificate_number,
            issue_date=args.issue_date,
            notes=args.notes,
            prepared_by=args.prepared_by or "",
            authorised_function=args.authorised_function or "",
        ),
        out=args.out,
        sweep=args.sweep,
        replaces=args.replaces,
        reason=args.reason,
        as_found=args.as_found,
        sign=args.sign,
        trust=args.trust,
        db=args.db,
    )
    outcome = issue_certificate(request)
    print(f"certificate {outcome.number}: {outcome.pdf}")
    if outcome.conditions_note:
        print(outcome.conditions_note)
    for note in outcome.notes:
        print(note)
    if outcome.dcc is not None:
        print(f"digital calibration certificate (DCC 3.3.0, in the PDF too): {outcome.dcc}")
    else:
        print("no digital calibration certificate: the stand file names no laboratory.country")
    return EXIT_OK
