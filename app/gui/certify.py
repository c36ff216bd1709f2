"""Certificates from the window: the run shown (verified again), the fields asked afresh, then
the certificate service (`app.certificate.service.issue_certificate`, the call `accelcal
certificate` makes) issues it: which register (the records when the window has them open, else
the runs root's JSON register), who prepared it, the two-person rule, staging, the number. A
refusal is shown and nothing is written.

An amendment or reissue (from the Register tab) is the same, with the certificate it replaces
and the reason. A run that already has a certificate in force gets no second one: the window
says so and offers its amendment (a reason asked) instead. Nothing here computes: it asks,
builds the request, calls and shows.
"""

from __future__ import annotations

import dataclasses
import functools
import html
import logging
from pathlib import Path
from typing import Any

from PySide6.QtCore import QUrl
from PySide6.QtGui import QDesktopServices
from PySide6.QtWidgets import QDialog, QInputDialog, QMessageBox

from app.certificate import CertificateError, CertificateInfo
from app.certificate.service import (
    IssueOutcome,
    IssueRequest,
    certificate_in_force,
    check_signatories,
    default_prepared_by,
    issue_certificate,
    records_in_use,
)
from app.gui.certificate_dialog import CertificateDialog, run_identity
from app.records.db.errors import RecordsInputError
from app.records.run_folder import RunIntegrityError, load_run
from app.records.run_record import RunRecord

log = logging.getLogger(__name__)


def request(
    window: Any,
    folder: Path,
    info: CertificateInfo,
    *,
    replaces: str | None = None,
    reason: str | None = None,
) -> IssueRequest:
    """The service's request for the run `folder` from the window: its records (the URL it
    opened, or none when they could not be opened), the next free certificate*.pdf."""
    return IssueRequest(
        run=Path(folder),
        info=info,
        replaces=replaces,
        reason=reason,
        db=window.records.url,
        records_available=window.records.lab is not None,
    )


def ask(
    window: Any,
    folder: Path,
    record: RunRecord,
    *,
    replaces: str | None = None,
    reason: str | None = None,
) -> Path | None:
    """Ask the certificate's fields for the run `folder`, name the run once, then issue it
    through the service; the PDF's path, None when cancelled or refused (shown)."""
    url = records_in_use(request(window, folder, CertificateInfo()))
    if replaces is None and url is not None:
        current = _current_certificate(url, record)
        if current is not None:  # one certificate per run: offer its amendment instead
            replaces, reason = _offer_amendment(window, record, current)
            if replaces is None:
                return None
    heading = f"Amendment of {replaces} ({reason})" if replaces else "Certificate"
    defaults = dict(window.records.certificate_defaults(record))
    template = chosen_template(window)
    offered = _offered(folder, url, defaults.get("dut_model"), template)
    if offered is not None:
        defaults["mounting"] = offered.mounting
    dialog = CertificateDialog(
        window,
        record,
        defaults,
        prepared_by=window.setup_tab.technician.text().strip() or _prepared_default(folder),
        check=functools.partial(check_signatories, url) if url is not None else None,
        heading=html.escape(heading),
        offered_from=offered.source if offered is not None else "",
        template=template,
    )
    window.certificate_dialog_open = dialog  # tests and screenshots reach the open dialog
    try:
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return None
    finally:
        window.certificate_dialog_open = None
    what = f"an amendment of {replaces}" if replaces else "the certificate"
    where = " and enter it in the register" if url is not None else ""
    answer = QMessageBox.question(
        window, "Issue the certificate?", f"Issue {what} of {run_identity(record)}{where}?"
    )
    if answer != QMessageBox.StandardButton.Yes:
        return None
    return issue(window, folder, dialog.info(), replaces=replaces, reason=reason)


def ask_batch(window: Any, batch_id: str, members: list[Any]) -> list[Path]:
    """Certificates for the complete DUTs `members` (app.gui.batch_view.MemberRow) of batch
    `batch_id` in one confirmation: the fields asked once (the first member's defaults; each
    certificate takes its own run's serial), then the certificate service once per member, as
    `accelcal certificate --batch` does (each its own number, the two-person rule each). The
    PDFs issued; a member refused is said and the others are still issued."""
    records = []
    for member in members:
        try:
            records.append((member, load_run(member.folder)))
        except (RunIntegrityError, ValueError) as exc:
            QMessageBox.warning(window, "Certificate refused", f"{member.position}: {exc}")
    if not records:
        return []
    first = records[0][1]
    url = records_in_use(request(window, records[0][0].folder, CertificateInfo()))
    dialog = CertificateDialog(
        window,
        first,
        dict(window.records.certificate_defaults(first)),
        prepared_by=window.setup_tab.technician.text().strip()
        or _prepared_default(records[0][0].folder),
        check=functools.partial(check_signatories, url) if url is not None else None,
        template=chosen_template(window),
    )
    named = ", ".join(f"{m.position} {m.serial}" for m, _ in records)
    dialog.setWindowTitle(f"Certificates of batch {batch_id}")
    dialog.title.setText(
        f"<b>Certificates of the {len(records)} DUTs of batch {html.escape(batch_id)}</b>: "
        f"{html.escape(named)}"
    )
    serial = dialog.edits["dut_serial"]
    serial.clear()
    serial.setEnabled(False)
    serial.setPlaceholderText("each DUT's own serial, from its run")
    window.certificate_dialog_open = dialog
    try:
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return []
    finally:
        window.certificate_dialog_open = None
    where = " and enter them in the register" if url is not None else ""
    answer = QMessageBox.question(
        window,
        "Issue the certificates?",
        f"Issue {len(records)} certificates, one per DUT ({named}){where}?",
    )
    if answer != QMessageBox.StandardButton.Yes:
        return []
    info = dataclasses.replace(dialog.info(), dut_serial=None)
    return issue_batch(window, [(m.position, m.folder) for m, _ in records], info)


def issue_batch(window: Any, members: list[tuple[str, Path]], info: CertificateInfo) -> list[Path]:
    """Issue a certificate per member (position, run folder) through the certificate service
    with `info`; the PDFs issued. Each refusal is said (the others are issued)."""
    window.records.wait_jobs()  # the runs' own indexing (records thread) first: no race
    issued: list[Path] = []
    lines: list[str] = []
    refused: list[str] = []
    for position, folder in members:
        try:
            outcome = issue_certificate(request(window, folder, info))
        except (RecordsInputError, CertificateError, RunIntegrityError, ValueError, OSError) as exc:
            refused.append(f"position {position}: no certificate: {exc}")
            continue
        log.info("certificate %s of %s written: %s", outcome.number, folder.name, outcome.pdf)
        window.last_certificate = outcome.number
        issued.append(outcome.pdf)
        lines += [f"position {position}: certificate {outcome.number}: {outcome.pdf}"]
        lines += outcome.notes
    window.run_tab.messages.setText("<br/>".join(html.escape(t) for t in [*lines, *refused]))
    if refused:
        QMessageBox.warning(
            window,
            "Certificates refused",
            f"{len(refused)} of {len(members)} certificates refused:\n" + "\n".join(refused),
        )
    window.register_tab.refresh()
    return issued


def chosen_template(window: Any) -> str:
    """The run template chosen on the Setup tab ("" : none, the model's own settings)."""
    from app.gui.templates import NONE_CHOSEN

    picker = getattr(window.setup_tab, "templates", None)
    if picker is None or not picker.templates:
        return ""
    name = picker.combo.currentText()
    return "" if name == NONE_CHOSEN else name


def _offered(folder: Path, url: str | None, model: str | None, template: str) -> Any:
    """The mounting remembered for the run's sensor model (or its template), None."""
    from app.certificate.remembered import RememberedConditions, run_model

    try:
        return RememberedConditions().offered(model or run_model(folder, url), template)
    except (OSError, ValueError) as exc:  # an offer lost, never the dialog
        log.warning("remembered mounting not read: %s", exc)
        return None


def _prepared_default(folder: Path) -> str:
    """Who prepared it when the window's Technician field is empty: the service's default
    (the run's technician, else the stand file's); "" when it cannot say."""
    try:
        return default_prepared_by(folder)
    except (CertificateError, RunIntegrityError, ValueError, OSError) as exc:
        log.warning("prepared by not read: %s", exc)
        return ""


def _current_certificate(url: str, record: RunRecord) -> str | None:
    """The number of the run's certificate in force in the register (None: none yet, or the
    register cannot say: the issue itself then decides)."""
    try:
        return certificate_in_force(url, str(record.run_id))
    except RecordsInputError as exc:
        log.warning("register not read: %s", exc)
        return None


def _offer_amendment(window: Any, record: RunRecord, number: str) -> tuple[str | None, str | None]:
    """Say that the run has certificate `number` and offer to amend it; (number, reason) when
    accepted with a reason, (None, None) otherwise."""
    answer = QMessageBox.question(
        window,
        "The run already has a certificate",
        f"{run_identity(record)} already has certificate {number}; a run has one certificate. "
        f"Issue an amendment that replaces {number}?",
    )
    if answer != QMessageBox.StandardButton.Yes:
        return None, None
    text, ok = QInputDialog.getText(
        window, f"Amend {number}", f"Why is {number} amended? (required; kept in the register)"
    )
    if not ok:
        return None, None
    if not text.strip():
        QMessageBox.warning(window, f"Amend {number}", "reason: must not be blank")
        return None, None
    return number, text.strip()


def issue(
    window: Any,
    folder: Path,
    info: CertificateInfo,
    *,
    replaces: str | None = None,
    reason: str | None = None,
) -> Path | None:
    """Issue through the certificate service; the PDF's path, None when refused (shown, not
    raised)."""
    window.records.wait_jobs()  # the run's own indexing (records thread) first: no race
    try:
        outcome = issue_certificate(request(window, folder, info, replaces=replaces, reason=reason))
    except (RecordsInputError, CertificateError, RunIntegrityError, ValueError, OSError) as exc:
        QMessageBox.warning(window, "Certificate refused", str(exc))
        window.run_tab.messages.setText(html.escape(f"certificate refused: {exc}"))
        return None
    show(window, folder, outcome)
    return outcome.pdf


def show(window: Any, folder: Path, outcome: IssueOutcome) -> None:
    """Say where the certificate went and what the service noted (the two-person rule, the
    validation report named or why none: messages), the Results tab, the Register tab; open
    it."""
    path = outcome.pdf
    log.info("certificate %s of %s written: %s", outcome.number, folder.name, path)
    window.last_certificate = outcome.number
    lines = [f"certificate {outcome.number} written: {path}", *outcome.notes]
    window.run_tab.messages.setText("<br/>".join(html.escape(line) for line in lines))
    if window.results_tab.folder == folder:
        window.results_tab.summary.setText(
            window.results_tab.summary.text()
            + f"<br/>Certificate: {html.escape(outcome.number)}, {html.escape(str(path))}"
        )
    window.register_tab.refresh()
    QDesktopServices.openUrl(QUrl.fromLocalFile(str(path.resolve())))
