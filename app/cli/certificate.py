"""`accelcal certificate`: the PDF certificate (and DCC) of a stored complete run. The options
are parsed into an `app.certificate.service.IssueRequest` and issued by the certificate
service, the same call the GUI's certificate dialog makes (which register, who prepared it, the
two-person rule, staging, signing: all there); this prints what was issued."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from app.cli.exits import EXIT_BAD_INPUT, EXIT_OK, UsageError
from app.cli.options import writable_folder
from app.errors import Refusal


def cmd_certificate(args: argparse.Namespace) -> int:
    from app.certificate.info import CertificateError, Specification, SpecKind
    from app.certificate.service import issue_certificate
    from app.records.run_folder import is_run_folder

    if args.batch is not None:
        return certificates_of_batch(args)
    if args.triaxial is not None:
        return certificate_of_triaxial(args)
    if args.run is None:
        raise UsageError("certificate: give a run folder, or --batch BATCH")
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
    request = issue_request(args, args.run, specification)
    outcome = issue_certificate(request)
    _print_outcome(outcome)
    return EXIT_OK


def issue_request(args: argparse.Namespace, run: Path, specification: Any) -> Any:
    """The IssueRequest of the command line for the run folder `run`."""
    from app.certificate import CertificateInfo
    from app.certificate.service import IssueRequest

    return IssueRequest(
        run=run,
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


def _print_outcome(outcome: Any) -> None:
    print(f"certificate {outcome.number}: {outcome.pdf}")
    if outcome.conditions_note:
        print(outcome.conditions_note)
    for note in outcome.notes:
        print(note)
    if outcome.dcc is not None:
        print(f"digital calibration certificate (DCC 3.3.0, in the PDF too): {outcome.dcc}")
    else:
        print("no digital calibration certificate: the stand file names no laboratory.country")


def certificates_of_batch(args: argparse.Namespace) -> int:
    """`certificate --batch BATCH`: one certificate per member of the batch, each issued by
    the certificate service on its own run folder (its own number, the customer given, the
    two-person rule per certificate). Options that name one certificate are refused."""
    from app.certificate.info import CertificateError, Specification, SpecKind
    from app.certificate.service import issue_certificate
    from app.records.batch import BatchError, read_batch

    for flag, given in (
        ("run", args.run),
        ("--out", args.out),
        ("--certificate-number", args.certificate_number),
        ("--dut-serial", args.dut_serial),
        ("--replaces", args.replaces),
        ("--sweep", args.sweep),
    ):
        if given:
            raise UsageError(f"{flag}: names one certificate; --batch issues one per member")
    folder = batch_folder(args.batch)
    try:
        batch = read_batch(folder)
    except BatchError as exc:
        raise UsageError(f"--batch: {exc}") from None
    specification = None
    if args.spec_kind or args.spec_id or args.spec_tolerances:
        if not (args.spec_kind and args.spec_id):
            raise CertificateError(
                "specification (--spec-kind, --spec-id): give its kind and its document"
            )
        specification = Specification(
            SpecKind(args.spec_kind), " ".join(args.spec_id.split()), args.spec_tolerances or ""
        )
    refused = 0
    for member in batch.members:
        run = folder.parent / member.run_id
        print(f"position {member.position}: DUT {member.serial}, run {member.run_id}")
        try:
            _print_outcome(issue_certificate(issue_request(args, run, specification)))
        except Refusal as exc:  # the others are still issued; this one says why not
            refused += 1
            print(f"position {member.position}: no certificate: {exc}", file=sys.stderr)
    if refused:
        print(f"{refused} of {len(batch.members)} certificates refused", file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK


def certificate_of_triaxial(args: argparse.Namespace) -> int:
    """`certificate --triaxial BX BY BZ`: one certificate of a triaxial sensor from its three
    orientation batches (app.certificate.triaxial_issue), issued by the certificate service on
    the x orientation's x channel run with the triaxial section in the PDF and the DCC."""
    import dataclasses

    from app.certificate.triaxial_issue import triaxial_result_of, triaxial_runs

    for flag, given in (("run", args.run), ("--batch", args.batch), ("--sweep", args.sweep)):
        if given:
            raise UsageError(f"{flag}: --triaxial names its three batches only")
    runs = triaxial_runs([batch_folder(text, "--triaxial") for text in args.triaxial])
    result = triaxial_result_of(runs)
    request = issue_request(args, runs.main_run, specification_of(args))
    info = dataclasses.replace(
        request.info,
        triaxial=result,
        dut_type=request.info.dut_type or "triaxial accelerometer",
    )
    outcome = issue_certificate_of(dataclasses.replace(request, info=info))
    print(
        f"triaxial {runs.position}={runs.serial}: orientations "
        + ", ".join(f"{o} {b}" for o, b in sorted(runs.batches.items()))
    )
    _print_outcome(outcome)
    return EXIT_OK


def specification_of(args: argparse.Namespace) -> Any:
    """The specification the options name (--spec-kind, --spec-id, --spec-tolerances), or
    None; CertificateError when one is given without the other."""
    from app.certificate.info import CertificateError, Specification, SpecKind

    if not (args.spec_kind or args.spec_id or args.spec_tolerances):
        return None
    if not (args.spec_kind and args.spec_id):
        raise CertificateError(
            "specification (--spec-kind, --spec-id): give its kind and its document"
        )
    return Specification(
        SpecKind(args.spec_kind), " ".join(args.spec_id.split()), args.spec_tolerances or ""
    )


def issue_certificate_of(request: Any) -> Any:
    """The certificate service's issue of `request` (app.certificate.service)."""
    from app.certificate.service import issue_certificate

    return issue_certificate(request)


def batch_folder(text: str, flag: str = "--batch") -> Path:
    """A batch by folder, or by id under ./runs (UsageError naming `flag`)."""
    from app.records.batch import is_batch_folder

    for candidate in (Path(text), Path("runs") / text):
        if is_batch_folder(candidate):
            return candidate
    raise UsageError(f"{flag}: {text!r} is not a batch folder (nor ./runs/{text})")
