"""Issuing a certificate: the one call every face makes (`accelcal certificate`, the GUI's
certificate dialog), so that the same inputs give the same certificate whichever face asked.

`issue_certificate(request)` decides the register (the records database when records are in
use: `--db`, $ACCELCAL_DB, else the default file when it exists, app.records.db.engine
.records_url; else the runs root's JSON register, the certificate then saying so), checks the
records (quick check of their chain), names who prepared it (given, else the run's technician,
else the stand file's [certificate] prepared_by; refused when none), applies the lab's
two-person rule before anything is written, loads the signing key, chooses the file (given,
else the run folder's certificate.pdf, for an amendment its first free certificate-N.pdf) and
issues through the register's
transaction (app.certificate.register_issue / app.certificate.issuing: staged, entered,
published). The faces parse their input into an `IssueRequest`, call, and show the
`IssueOutcome` or the refusal (CertificateError / RecordsError naming the field and option).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

from app.certificate.info import CertificateError, CertificateInfo
from app.files import disk_full_reason, is_disk_full
from app.records.register import Issued
from app.records.run_folder import is_product_name

log = logging.getLogger(__name__)

MAX_CERTIFICATES_PER_RUN = 100


class RegisterKind(StrEnum):
    """Which register numbers a certificate."""

    RECORDS = "records"  # the records database's register (its pattern, no gap)
    RUN_FOLDER = "run folder"  # the runs root's JSON register (no records in use)


@dataclass(frozen=True)
class IssueRequest:
    """What a face asks for: the run folder, the certificate's items as given (empty ones
    take their defaults), and how it is issued."""

    run: Path
    info: CertificateInfo
    out: Path | None = None  # None: <run>/certificate.pdf (an amendment: the next free name)
    sweep: Path | None = None  # the sweep summary the run belongs to
    replaces: str | None = None  # an amendment: the number it replaces (records only)
    reason: str | None = None  # why (records only; required with replaces)
    as_found: str | None = None  # the as-found run id of an adjusted sensor (records only)
    sign: Path | None = None  # PKCS#12 signing key (password from $ACCELCAL_SIGN_PASSWORD)
    trust: Path | None = None  # the lab's CA certificate: checks the validation report's signer
    db: str | None = None  # --db URL; None: $ACCELCAL_DB, else the default file if it exists
    records_available: bool = True  # False: the face could not open the records (GUI)


@dataclass(frozen=True)
class IssueOutcome:
    """A certificate issued: its register entry, its files and the register that numbered it."""

    issued: Issued
    pdf: Path
    dcc: Path | None  # None: the stand file names no laboratory country (no DCC)
    register: RegisterKind
    prepared_by: str
    notes: tuple[str, ...] = ()  # what the faces show beside it: the two-person rule, validation
    conditions_note: str = ""  # "mounting: 'X' (from model M)" when offered, not typed

    @property
    def number(self) -> str:
        return self.issued.number


def records_in_use(request: IssueRequest) -> str | None:
    """The URL of the records that number the certificate, None for the runs root's JSON
    register: the same answer `run` uses (app.records.db.engine.records_url)."""
    if not request.records_available:
        return None
    from app.records.db.engine import records_url

    return records_url(request.db)


def default_prepared_by(run: Path) -> str:
    """Who prepared a certificate of `run` when nobody is named: the technician the run
    records (run --technician, the GUI's Technician field), else the stand file's
    [certificate] prepared_by; "" when neither (never a login name)."""
    from app.certificate.info import default_info
    from app.certificate.load import load_stored_run

    stored = load_stored_run(run)
    return str(default_info(stored.record, stored.start).get("prepared_by") or "").strip()


def prepared_by(run: Path, given: str) -> str:
    """`given`, else `default_prepared_by(run)`; CertificateError naming --prepared-by when
    neither names anyone."""
    name = " ".join(given.split()) or default_prepared_by(run)
    if not name:
        raise CertificateError(
            "--prepared-by: the run records no technician (accelcal run --technician NAME); "
            "name who prepared the certificate"
        )
    return name


def check_signatories(url: str | None, prepared: str, approved: str) -> Signatories:
    """The two signatories as the certificate prints them. With records (`url`): the records'
    rule (app.records.db.certificates.check_signatories: neither blank nor in confusable
    scripts; under the lab's two-person rule each a person on record, resolved to a user, and
    not the same user); RecordsError naming the field. Without records nobody is identified:
    the names are printed as typed and the note says what could not be checked."""
    if url is None:
        return Signatories(
            " ".join(prepared.split()),
            " ".join(approved.split()),
            "two-person rule: NOT checked: without records the signatories are names as typed, "
            "no person is identified, so nothing proves that prepared by and authorised by are "
            "two people (use the records: accelcal db upgrade, records user add, register set "
            "two_person_rule on)",
        )
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab

    engine = open_engine(url)
    try:
        lab = Lab(engine)
        checked = lab.check_signatories(prepared, approved)
        rule = lab.two_person_rule()
    finally:
        engine.dispose()
    note = (
        f"two-person rule: prepared by {checked.prepared_by} and authorised by "
        f"{checked.approved_by}: two users of the records"
        if rule
        else "two-person rule: off in the records (names as typed; accelcal register set "
        "two_person_rule on makes each signatory a user and compares the users)"
    )
    return Signatories(checked.prepared_by, checked.approved_by, note)


@dataclass(frozen=True)
class Signatories:
    """Prepared by and authorised by as printed and registered, and what the rule checked."""

    prepared_by: str
    approved_by: str
    note: str


def validation_claim(request: IssueRequest, signer: Any) -> Any:
    """The software validation report the certificate names (app.certificate.validated_check
    .FolderClaim): the newest report in the lab's validation folder signed by the lab for this
    software, checked against `request.trust` (the lab's CA) or else the signing key's own
    certificates; with neither, none (the summary says why)."""
    from app.certificate.validated_check import current_claim, trust_from_ca, trust_from_signer

    if request.trust is not None:
        trust = trust_from_ca(Path(request.trust))
    elif signer is not None:
        trust = trust_from_signer(signer)
    else:
        trust = None
    found = current_claim(trust)
    for refused in found.refused:
        log.warning("software validation report not named: %s", refused)
    return found


def certificate_in_force(url: str | None, run_id: str) -> str | None:
    """The number of the run's certificate in force in the records' register (None: none, or
    no records)."""
    if url is None:
        return None
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab

    engine = open_engine(url)
    try:
        row = Lab(engine).issued_for_run(run_id)
    finally:
        engine.dispose()
    return None if row is None else str(row.number)


def free_pdf(folder: Path) -> Path:
    """The first certificate file name not yet used in a run folder: certificate.pdf, then
    certificate-2.pdf, ... (a certificate is never overwritten; an amendment is a new file)."""
    for n in range(1, MAX_CERTIFICATES_PER_RUN + 1):
        path = folder / ("certificate.pdf" if n == 1 else f"certificate-{n}.pdf")
        assert is_product_name(path.name)
        if not path.exists() and not path.with_suffix(".xml").exists():
            return path
    raise CertificateError(f"{folder}: {MAX_CERTIFICATES_PER_RUN} certificates already")


def default_out(run: Path, replaces: str | None) -> Path:
    """Where a certificate of `run` goes when no file is named: certificate.pdf in the run
    folder (refused when taken: a second certificate is named on purpose), an amendment the
    first free certificate-N.pdf there."""
    return free_pdf(run) if replaces else run / "certificate.pdf"


def _signer(key: Path | None) -> Any:
    if key is None:
        return None
    from app.certificate.sign import Signer, SigningError

    try:
        return Signer.load(key)
    except SigningError as exc:
        raise CertificateError(str(exc)) from None


def issue_certificate(request: IssueRequest) -> IssueOutcome:
    """Issue the certificate `request` asks for (see the module's docstring); nothing is
    written when it is refused."""
    from app.certificate.issuing import dcc_path

    url = records_in_use(request)
    run = Path(request.run)
    info = dataclasses.replace(request.info, prepared_by=prepared_by(run, request.info.prepared_by))
    signer = _signer(request.sign)
    out = Path(request.out) if request.out is not None else default_out(run, request.replaces)
    if url is not None:
        from app.records.db.gate import records_quick_check

        records_quick_check(url)
    people = check_signatories(url, info.prepared_by, str(info.authorised_by or ""))
    validation = validation_claim(request, signer)
    info, offered = _offered_mounting(info, run, url)
    info = dataclasses.replace(
        info,
        prepared_by=people.prepared_by,
        authorised_by=people.approved_by or info.authorised_by,
        authorised_function=" ".join(info.authorised_function.split()),
        validation=validation.claim,
    )
    try:
        issued, register = _issue(request, run, info, out, url, signer)
    except Exception as exc:
        if not is_disk_full(exc):
            raise
        raise CertificateError(_disk_full(out, url, exc)) from None
    dcc = dcc_path(out)
    log.info("certificate %s of %s issued (%s register): %s", issued.number, run.name,
             register, out)  # fmt: skip
    notes = (people.note, validation.summary())
    _remember(info, run, url)
    return IssueOutcome(
        issued,
        out,
        dcc if dcc.exists() else None,
        register,
        info.prepared_by,
        notes,
        offered.note() if offered is not None else "",
    )


def _offered_mounting(
    info: CertificateInfo, run: Path, url: str | None
) -> tuple[CertificateInfo, Any]:
    """`info` with the mounting remembered for its model (or template) when none is typed
    (app.certificate.remembered), and the offer (None: typed, or nothing remembered)."""
    if info.mounting and info.mounting.strip():
        return info, None
    from app.certificate.remembered import RememberedConditions, run_model

    offered = RememberedConditions().offered(info.dut_model or run_model(run, url), info.template)
    if offered is None:
        return info, None
    info = dataclasses.replace(info, mounting=offered.mounting, conditions_from=offered.source)
    return info, offered


def _remember(info: CertificateInfo, run: Path, url: str | None) -> None:
    """Keep the certificate's mounting for its model and template (the next one is offered it)."""
    from app.certificate.remembered import RememberedConditions, run_model

    RememberedConditions().remember(
        info.dut_model or run_model(run, url), info.mounting, info.template
    )


def _disk_full(out: Path, url: str | None, exc: BaseException) -> str:
    """What a full disk left of an issue (issue 33 point 6): the path that could not be
    written and what was kept, from the files themselves (the transaction's steps:
    app.certificate.issuing)."""
    from app.certificate.issuing import dcc_path
    from app.certificate.leftovers import staging_path

    register = "records database" if url is not None else "run folder's register"
    staged = [p for p in (staging_path(out), staging_path(dcc_path(out))) if p.exists()]
    outcome = "not issued"
    if staged:
        outcome = "numbered and entered, not yet in place"
        kept = (
            f"the certificate is entered in the {register} and its files are staged "
            f"({', '.join(p.name for p in staged)}); the next issue or `accelcal db verify` "
            "puts them in place"
        )
    else:
        kept = (
            f"nothing of it was written ({out.name} and its staged files absent), the "
            f"{register} and the run folder are as they were"
        )
    return (
        f"disk full: {disk_full_reason(exc)}: certificate {out} {outcome}; kept: {kept}; "
        "free some space, then issue it again"
    )


def _issue(
    request: IssueRequest,
    run: Path,
    info: CertificateInfo,
    out: Path,
    url: str | None,
    signer: Any,
) -> tuple[Issued, RegisterKind]:
    """The issue through the run folder's register or the records (`issue_certificate`)."""
    from app.certificate.issuing import issue
    from app.certificate.register_issue import issue_registered

    if url is None:
        if request.replaces or request.reason or request.as_found:
            raise CertificateError(
                "--replaces, --reason, --as-found: need the records (--db URL); without them "
                "a certificate is numbered by the run folder's register"
            )
        issued = issue(run, info, out, request.sweep, signer)
        register = RegisterKind.RUN_FOLDER
    else:
        issued = issue_registered(
            run,
            info,
            out,
            url=url,
            prepared_by=info.prepared_by,
            sweep_path=request.sweep,
            replaces=request.replaces,
            reason=request.reason,
            as_found=request.as_found,
            signer=signer,
        )
        register = RegisterKind.RECORDS
    return issued, register
