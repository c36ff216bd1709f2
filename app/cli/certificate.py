"""`accelcal certificate`: the PDF certificate (and DCC) of a stored complete run, through the
records' register when records are in use (app.records.db.engine.records_url: the same answer
`run` uses), else numbered by the run folder's register (and saying so on the certificate).
"Prepared by" is --prepared-by, else the technician the run records (run --technician, the
GUI's Technician field), else the stand file's [certificate] prepared_by; never a login name."""

from __future__ import annotations

import argparse

from app.cli.exits import EXIT_OK, UsageError
from app.cli.options import writable_folder


def _prepared_by(args: argparse.Namespace) -> str:
    """Who prepared the certificate: --prepared-by, else the run's technician or the stand
    file's [certificate] prepared_by (app.certificate.info.default_info); UsageError naming
    --prepared-by when the run records none."""
    given = (args.prepared_by or "").strip()
    if given:
        return given
    from app.certificate.info import default_info
    from app.certificate.load import load_stored_run

    run = load_stored_run(args.run)
    found = str(default_info(run.record, run.start).get("prepared_by") or "").strip()
    if not found:
        raise UsageError(
            "--prepared-by: the run records no technician (accelcal run --technician NAME); "
            "name who prepared the certificate"
        )
    return found


def cmd_certificate(args: argparse.Namespace) -> int:
    from app.certificate import CertificateInfo, issue
    from app.records.run_folder import is_run_folder

    info = CertificateInfo(
        customer=args.customer,
        customer_address=args.customer_address,
        authorised_by=args.authorised_by,
        dut_model=args.dut_model,
        dut_serial=args.dut_serial,
        dut_type=args.dut_type,
        temperature_c=args.temperature,
        mounting=args.mounting,
        certificate_number=args.certificate_number,
        issue_date=args.issue_date,
        notes=args.notes,
        prepared_by=_prepared_by(args),
    )
    out = args.out or (args.run / "certificate.pdf")
    signer = None
    if args.sign is not None:
        from app.certificate.sign import Signer, SigningError

        try:
            signer = Signer.load(args.sign)
        except SigningError as exc:
            raise UsageError(str(exc)) from None
    if args.out is not None and not is_run_folder(args.out.parent):  # a run's own: see issue()
        writable_folder(args.out.parent, "--out")
    from app.records.db.engine import records_url

    url = records_url(args.db)  # the records `run` used: --db, $ACCELCAL_DB, the default file
    if url is not None:
        from app.certificate.register_issue import issue_registered
        from app.records.db.gate import records_quick_check

        records_quick_check(args.db)
        issued = issue_registered(
            args.run,
            info,
            out,
            url=url,
            prepared_by=info.prepared_by,
            sweep_path=args.sweep,
            replaces=args.replaces,
            reason=args.reason,
            as_found=args.as_found,
            signer=signer,
        )
    elif args.replaces or args.reason or args.as_found:
        raise UsageError("--replaces, --reason, --as-found: need the records (--db URL)")
    else:
        issued = issue(args.run, info, out, args.sweep, signer)
    print(f"certificate {issued.number}: {out}")
    from app.certificate import dcc_path

    if dcc_path(out).exists():
        print(f"digital calibration certificate (DCC 3.3.0, in the PDF too): {dcc_path(out)}")
    else:
        print("no digital calibration certificate: the stand file names no laboratory.country")
    return EXIT_OK
