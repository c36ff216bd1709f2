"""A certificate issued through the records: customer and sensor data from the sensor's
record, the number from the lab's register (its pattern, no gap), the PDF written inside the
register's transaction so a number never exists without its certificate, or the reverse."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from app.certificate import CertificateError, CertificateInfo, Issued, issue
from app.records.db.engine import open_engine
from app.records.db.lab import Lab, RecordsError
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
        }
    )
    if info.dut_serial != sensor.serial:
        raise RecordsError(f"--dut-serial: {info.dut_serial!r} is not the run's {sensor.serial!r}")
    issued: list[Issued] = []

    def produce(number: str) -> None:
        issued.append(
            issue(
                run_path,
                dataclasses.replace(info, certificate_number=number),
                out,
                sweep_path,
                signer,
            )
        )

    try:
        lab.issue_certificate(
            run_id=str(record.run_id),
            prepared_by=prepared_by,
            approved_by=str(info.authorised_by or ""),
            replaces=replaces,
            reason=reason,
            produce=produce,
        )
    except BaseException:
        if issued:  # written, but the register did not take it: no certificate without entry
            Path(issued[0].file).unlink(missing_ok=True)
        raise
    if not issued:
        raise CertificateError("the certificate was not written")
    return issued[0]
