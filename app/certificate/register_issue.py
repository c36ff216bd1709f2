"""A certificate issued through the records: customer and sensor data from the sensor's
record, the number from the lab's register (its pattern, no gap), the PDF written inside the
register's transaction so a number never exists without its certificate, or the reverse.

With records in use the database is the one register: the runs root's JSON register
(app.records.register) is not written (SPEC.md section 9: "every certificate through the
register")."""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path
from typing import Any

from app.certificate.info import CertificateError, CertificateInfo
from app.certificate.issuing import issue_numbered
from app.records.db.engine import open_engine
from app.records.db.lab import Lab, RecordsError
from app.records.register import Issued
from app.records.run_folder import load_run


def issue_registered(
    run_path: Path,
    info: CertificateInfo,
    out: Path,
    *,
    url: str | None,
    prepared_by: str,
    sweep_path: Path | None = None,
    replaces: str | None = None,
    reason: str | None = None,
    signer: Any = None,
) -> Issued:
    """Issue the certificate of a stored run with its number from the records' register; the
    run is indexed first when it is not yet. RecordsError / CertificateError name the field."""
    if info.certificate_number:
        raise RecordsError(
            "--certificate-number: the records' register numbers certificates (its pattern)"
        )
    record = load_run(run_path)
    lab = Lab(open_engine(url))
    report = lab.import_runs(run_path)
    if report.refused:
        raise RecordsError(f"run: {report.refused[0][1]}")
    dut_id = str((record.dut.id if record.dut else None) or "")
    if not dut_id:
        raise RecordsError("run: the run names no DUT (--dut-id); the register needs its sensor")
    sensor = lab.sensor(dut_id)
    info = info.merged(
        {
            "customer": sensor.owner.name,
            "customer_address": sensor.owner.address,
            "dut_model": f"{sensor.model.maker} {sensor.model.model}",
            "dut_serial": sensor.serial,
            "prepared_by": prepared_by,
            "sensitivity_unit": sensor.model.unit,
        }
    )
    if info.dut_serial != sensor.serial:
        raise RecordsError(f"--dut-serial: {info.dut_serial!r} is not the run's {sensor.serial!r}")
    issued: list[Issued] = []
    with contextlib.ExitStack() as written:  # an exception out of it removes the files

        def produce(number: str) -> None:
            numbered = dataclasses.replace(info, certificate_number=number)
            issued.append(
                written.enter_context(issue_numbered(run_path, numbered, out, sweep_path, signer))
            )

        lab.issue_certificate(
            run_id=str(record.run_id),
            prepared_by=prepared_by,
            approved_by=str(info.authorised_by or ""),
            replaces=replaces,
            reason=reason,
            produce=produce,
        )
    if not issued:
        raise CertificateError("the certificate was not written")
    return issued[0]
