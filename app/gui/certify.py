"""Certificates from the window through the lab's register: the run shown (verified again), the
fields asked afresh, the number allocated by the register
(`app.certificate.register_issue.issue_registered`, the PDF written inside the register's
transaction), or a refusal shown and nothing written.

An amendment or reissue (from the Register tab) is the same, with the certificate it replaces
and the reason. A run that already has a certificate in force gets no second one: the window
says so and offers its amendment (a reason asked) instead. Without the records the window issues
an unregistered certificate as before (`MainWindow.issue_certificate`). Nothing here computes:
it asks, calls and shows.
"""

from __future__ import annotations

import html
import logging
from pathlib import Path
from typing import Any

from PySide6.QtCore import QUrl
from PySide6.QtGui import QDesktopServices
from PySide6.QtWidgets import QDialog, QInputDialog, QMessageBox

from app.certificate import CertificateError, CertificateInfo
from app.gui.certificate_dialog import CertificateDialog, run_identity
from app.records.db.errors import RecordsInputError
from app.records.run_folder import RunIntegrityError, is_product_name
from app.records.run_record import RunRecord

log = logging.getLogger(__name__)

MAX_CERTIFICATES_PER_RUN = 100


def free_pdf(folder: Path) -> Path:
    """The first certificate file name not yet used in a run folder: certificate.pdf, then
    certificate-2.pdf, ... (a certificate is never overwritten; an amendment is a new file)."""
    for n in range(1, MAX_CERTIFICATES_PER_RUN + 1):
        path = folder / ("certificate.pdf" if n == 1 else f"certificate-{n}.pdf")
        assert is_product_name(path.name)
        if not path.exists() and not path.with_suffix(".xml").exists():
            return path
    raise CertificateError(f"{folder}: {MAX_CERTIFICATES_PER_RUN} certificates already")


def ask(
    window: Any,
    folder: Path,
    record: RunRecord,
    *,
    replaces: str | None = None,
    reason: str | None = None,
) -> Path | None:
    """Ask the certificate's fields for the run `folder`, name the run once, then issue it
    through the register; the PDF's path, None when cancelled or refused (shown)."""
    lab = window.records.lab
    if replaces is None:
        current = _current_certificate(window, record)
        if current is not None:  # one certificate per run: offer its amendment instead
            replaces, reason = _offer_amendment(window, record, current)
            if replaces is None:
                return None
    heading = f"Amendment of {replaces} ({reason})" if replaces else "Certificate"
    dialog = CertificateDialog(
        window,
        record,
        window.records.certificate_defaults(record),
        prepared_by=window.setup_tab.technician.text().strip(),
        check=lab.check_signatories,
        heading=html.escape(heading),
    )
    window.certificate_dialog_open = dialog  # tests and screenshots reach the open dialog
    try:
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return None
    finally:
        window.certificate_dialog_open = None
    what = f"an amendment of {replaces}" if replaces else "the certificate"
    answer = QMessageBox.question(
        window,
        "Issue the certificate?",
        f"Issue {what} of {run_identity(record)} and enter it in the register?",
    )
    if answer != QMessageBox.StandardButton.Yes:
        return None
    return issue(
        window, folder, dialog.info(), dialog.prepared_by(), replaces=replaces, reason=reason
    )


def _current_certificate(window: Any, record: RunRecord) -> str | None:
    """The number of the run's certificate in force in the register (None: none yet, or the
    register cannot say: the issue itself then decides)."""
    try:
        row = window.records.lab.issued_for_run(str(record.run_id))
    except RecordsInputError as exc:
        log.warning("register not read: %s", exc)
        return None
    return None if row is None else str(row.number)


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
    prepared_by: str,
    *,
    replaces: str | None = None,
    reason: str | None = None,
) -> Path | None:
    """Issue through the register (number, PDF in one transaction); errors shown, not raised."""
    from app.certificate.register_issue import issue_registered

    window.records.wait_jobs()  # the run's own indexing (records thread) first: no race
    try:
        out = free_pdf(folder)
        issued = issue_registered(
            folder,
            info,
            out,
            url=window.records.url,
            prepared_by=prepared_by,
            replaces=replaces,
            reason=reason,
        )
    except (RecordsInputError, CertificateError, RunIntegrityError, ValueError, OSError) as exc:
        QMessageBox.warning(window, "Certificate refused", str(exc))
        window.run_tab.messages.setText(html.escape(f"certificate refused: {exc}"))
        return None
    path = Path(issued.file)
    log.info("certificate %s of %s written: %s", issued.number, folder.name, path)
    window.last_certificate = issued.number
    window.run_tab.messages.setText(html.escape(f"certificate {issued.number} written: {path}"))
    if window.results_tab.folder == folder:
        window.results_tab.summary.setText(
            window.results_tab.summary.text()
            + f"<br/>Certificate {html.escape(issued.number)}: {html.escape(str(path))}"
        )
    window.register_tab.refresh()
    QDesktopServices.openUrl(QUrl.fromLocalFile(str(path.resolve())))
    return path
