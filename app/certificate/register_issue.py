"""A certificate issued through the records: customer and sensor data from the sensor's
record, the number from the lab's register (its pattern, no gap), crash-safe: the PDF and DCC
written under staging names inside the register's transaction (their path and SHA-256 in the
row), the transaction committed, then the files renamed into place; leftovers of a killed
issue are cleared first (app.certificate.leftovers), and a number a file carries is skipped.

With records in use the database is the one register: the runs root's JSON register
(app.records.register) is not written (SPEC.md section 9: "every certificate through the
register"). Identity (serial, model, customer) is the run's and the records': a different one
given is refused by name.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from app.certificate.info import (
    Amendment,
    CertificateError,
    CertificateInfo,
    Specification,
    SpecKind,
)
from app.certificate.issuing import Issuance, Staged, _step, issuance
from app.certificate.leftovers import Leftover, Registered, find_issuance_leftovers
from app.records.db.certificates import IssuedFiles
from app.records.db.engine import open_engine
from app.records.db.lab import Lab, RecordsError
from app.records.db.store import text_field
from app.records.register import Issued, read_register
from app.records.run_folder import load_run


def _identity(
    info: CertificateInfo, sensor: Any, run_serial: str, prepared_by: str
) -> CertificateInfo:
    """`info` with the sensor's customer, address, model and serial (and the unit its model's
    sensitivity is given in) from the records, and who prepared it; a different serial,
    customer or model given is refused naming its option."""
    model = f"{sensor.model.maker} {sensor.model.model}"
    for given, actual, option in (
        (info.dut_serial, sensor.serial, "--dut-serial"),
        (info.customer, sensor.owner.name, "--customer"),
        (info.dut_model, model, "--dut-model"),
    ):
        if given not in (None, "") and " ".join(str(given).split()) != actual:
            raise RecordsError(
                f"{option}: {given!r} is not the run's {actual!r} (run DUT {run_serial}, from "
                "the records); a certificate states the sensor that was calibrated"
            )
    address = info.customer_address or sensor.owner.address or ""
    if not address.strip() and not info.address_not_stated.strip():
        raise CertificateError(
            f"customer_address (--customer-address): the records hold no address for customer "
            f"{sensor.owner.name!r}; give it, or state why it is not given "
            '(--address-not-stated "REASON")'
        )
    specification = info.specification or Specification(  # whose tolerances (issue 35)
        SpecKind.DATASHEET, f"{model} data sheet, as entered in the records' sensor model", ""
    )
    return dataclasses.replace(
        info,
        specification=specification,
        customer=sensor.owner.name,
        customer_address=info.customer_address or sensor.owner.address or "",
        dut_model=model,
        dut_serial=sensor.serial,
        prepared_by=prepared_by,
        sensitivity_unit=sensor.model.unit,
    )


def registered_files(lab: Lab, runs_root: Path | None = None) -> tuple[dict, list[str]]:
    """The register's files (absolute PDF path -> Registered) and every number the registers
    hold (the database's, and the runs root's JSON register from before records were used)."""
    files: dict[str, Registered] = {}
    numbers: list[str] = []
    for row in lab.register():
        numbers.append(row.number)
        if row.file:
            files[row.file] = Registered(row.number, row.sha256, row.dcc_sha256)
    if runs_root is not None:
        numbers += [e.number for e in read_register(runs_root)]
    return files, numbers


def leftovers_in_records(lab: Lab) -> list[Leftover]:
    """The issuance leftovers the records can point to (for `accelcal db verify`): in the
    folders of every registered certificate file and of every run that has a certificate;
    clear them with `app.certificate.leftovers.clear_leftovers`."""
    files, numbers = registered_files(lab)
    run_folders = {Path(c.run.folder) for c in lab.register()}
    for run_folder in run_folders:  # a run's JSON register from before the records
        numbers += [e.number for e in read_register(run_folder.parent)]
    folders = {Path(file).parent for file in files}
    return find_issuance_leftovers(folders, files, numbers, run_folders=run_folders)


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
    as_found: str | None = None,
    signer: Any = None,
) -> Issued:
    """Issue the certificate of a stored run with its number from the records' register at
    `url` (app.records.db.engine.records_url); the run is indexed first when it is not yet.
    RecordsError / CertificateError name the field."""
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
    info = _identity(info, sensor, dut_id, prepared_by)
    run_id = str(record.run_id)
    if replaces is not None:  # what the amendment states of the one it replaces (page 1, DCC)
        reason = text_field(reason, "reason")
        info = dataclasses.replace(info, amendment=_amendment(lab, replaces, reason))
    if replaces is None:  # before anything is written: one certificate per run
        current = lab.issued_for_run(run_id)
        if current is not None:
            raise RecordsError(
                f"run: {run_id} already has certificate {current.number}; a run has one "
                f"certificate: amend it (--replaces {current.number} --reason ...)"
            )
    with issuance(run_path, info, out, sweep_path, signer) as job:
        files, numbers = registered_files(lab, Path(run_path).resolve().parent)
        taken = {n.casefold() for n in job.clear(files, numbers)}
        staged: list[Staged] = []

        def produce(number: str) -> IssuedFiles:
            _step("numbered")
            done = job.stage(dataclasses.replace(job.info, certificate_number=number))
            staged.append(done)
            _step("staged")
            return IssuedFiles(str(done.pdf.resolve()), done.sha256, done.dcc_sha256)

        try:
            row = lab.issue_certificate(
                run_id=run_id,
                prepared_by=prepared_by,
                approved_by=str(info.authorised_by or ""),
                replaces=replaces,
                reason=reason,
                as_found_run_id=as_found,
                produce=produce,
                taken=lambda number: number.casefold() in taken,
                customer_id=sensor.owner_id,  # the customer the PDF names (info.customer)
            )
        except BaseException:
            job.discard(staged[0] if staged else None)
            raise
        if not staged:
            raise CertificateError("the certificate was not written")
        _step("committed")
        job.publish(staged[0])
        return _issued(job, row)


def _amendment(lab: Lab, replaces: str, reason: str) -> Amendment:
    """The replaced certificate as the register holds it: refused by name when there is none
    or it is no longer in force (the issuing transaction checks it again, locked)."""
    old = lab.certificate(replaces)
    if old is None:
        raise RecordsError(f"replaces: no certificate {replaces!r}")
    if old.state != "issued":
        raise RecordsError(f"replaces: {replaces} is already {old.state}")
    return Amendment(
        replaces=old.number,
        reason=reason,
        sha256=old.dcc_sha256 or old.sha256 or "",
        of_dcc=bool(old.dcc_sha256),
    )


def _issued(job: Issuance, row: Any) -> Issued:
    return Issued(
        row.number,
        str(job.p.run.record.run_id or job.p.run.path.name),
        str(job.out.resolve()),
        row.issued_utc.isoformat(timespec="seconds"),
        row.sha256 or "",
    )
