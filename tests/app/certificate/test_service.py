"""The certificate service (app.certificate.service) is the one way to issue: `accelcal
certificate` and the GUI's certificate dialog both build an IssueRequest and call
`issue_certificate`, and for the same inputs they ask the same and issue the same certificate.
The service decides the register, who prepared it and the two-person rule."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.certificate import CertificateError, CertificateInfo, service
from app.certificate.pdf_marks import read_marks
from app.certificate.readback import items_from_pdf
from app.cli import main
from app.records.db.errors import RecordsInputError
from tests.app.certificate.conftest import Lab, copy_run
from tests.app.certificate.test_issue_matrix import GUI_FIELDS, Person, _window
from tests.records_db import add_staff

pytestmark = pytest.mark.integration

CUSTOMER = "ACME Ltd"


@pytest.fixture()
def requests(monkeypatch: pytest.MonkeyPatch) -> list[tuple[service.IssueRequest, str | None]]:
    """Every request a face hands the service, with the records it resolved to, as it goes
    through (the real service then issues it)."""
    from app.gui import certify

    seen: list[tuple[service.IssueRequest, str | None]] = []
    real = service.issue_certificate

    def spy(request: service.IssueRequest) -> service.IssueOutcome:
        seen.append((request, service.records_in_use(request)))
        return real(request)

    monkeypatch.setattr(service, "issue_certificate", spy)
    monkeypatch.setattr(certify, "issue_certificate", spy)
    return seen


def test_the_gui_dialog_and_the_cli_ask_the_same_and_issue_the_same_certificate(
    complete_run: Path, tmp_path: Path, qtbot, monkeypatch, requests
) -> None:
    gui_run = copy_run(complete_run, tmp_path / "gui")
    cli_run = copy_run(complete_run, tmp_path / "cli")
    monkeypatch.setenv("ACCELCAL_DB", f"sqlite:///{tmp_path / 'none.sqlite'}")  # no schema
    window = _window(qtbot, gui_run.parent, None)
    assert window.open_run(gui_run)
    Person(monkeypatch, {**GUI_FIELDS, "customer": CUSTOMER})
    assert window.certificate_action() == gui_run / "certificate.pdf"
    monkeypatch.delenv("ACCELCAL_DB")  # the CLI: no records either (no default file)
    f = GUI_FIELDS
    argv = ["certificate", str(cli_run), "--customer", CUSTOMER,
            "--customer-address", "1 Test Street, 00-001 Testtown", "--authorised-by",
            f["authorised_by"], "--prepared-by", f["prepared_by"], "--temperature",
            f["temperature"], "--mounting", f["mounting"]]  # fmt: skip
    assert main(argv) == 0
    (gui, gui_records), (cli, cli_records) = requests
    assert gui_records is None and cli_records is None  # both: the run folder's register
    same = {"run": Path("run"), "records_available": True}
    assert dataclasses.replace(gui, **same) == dataclasses.replace(cli, **same)
    assert gui.info == CertificateInfo(
        customer=CUSTOMER, authorised_by="J. Smith", temperature_c=23.0, mounting="stud, 2 N m",
        customer_address="1 Test Street, 00-001 Testtown",
        prepared_by="A. Tech")  # fmt: skip
    # and the same certificate: the DCC byte for byte, the printed items value for value
    gui_pdf, cli_pdf = gui_run / "certificate.pdf", cli_run / "certificate.pdf"
    assert (gui_run / "certificate.xml").read_bytes() == (cli_run / "certificate.xml").read_bytes()
    assert items_from_pdf(read_marks(gui_pdf.read_bytes())) == items_from_pdf(
        read_marks(cli_pdf.read_bytes())
    )
    assert [p.extract_text() for p in PdfReader(gui_pdf).pages] == [
        p.extract_text() for p in PdfReader(cli_pdf).pages
    ]


def test_the_register_is_the_records_when_in_use_else_the_run_folders(
    lab: Lab, tmp_path: Path, monkeypatch
) -> None:
    run = tmp_path / "run"
    request = service.IssueRequest(run=run, info=CertificateInfo())
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    assert service.records_in_use(request) is None  # no --db, no $ACCELCAL_DB, no file
    assert service.records_in_use(dataclasses.replace(request, db=lab.url)) == lab.url
    monkeypatch.setenv("ACCELCAL_DB", lab.url)
    assert service.records_in_use(request) == lab.url
    unavailable = dataclasses.replace(request, records_available=False)  # the GUI's link failed
    assert service.records_in_use(unavailable) is None


def test_an_amendment_without_records_is_refused_naming_the_options(
    complete_run: Path, tmp_path: Path, monkeypatch
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    request = service.IssueRequest(run=run, info=CertificateInfo(), replaces="AC-1", reason="x")
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    with pytest.raises(CertificateError, match=r"--replaces, --reason, --as-found: need the"):
        service.issue_certificate(request)
    assert not list(run.glob("certificate*"))


def test_nobody_named_as_preparer_is_refused_by_both_faces(
    run_100: Path, tmp_path: Path, qtbot, monkeypatch, capsys
) -> None:
    """run_100 records no technician: the CLI without --prepared-by and the GUI with its
    Prepared by field left empty are refused alike, naming --prepared-by; nothing written."""
    run = copy_run(run_100, tmp_path / "runs")
    argv = ["certificate", str(run), "--customer", CUSTOMER,
            "--customer-address", "1 Test Street, 00-001 Testtown", "--authorised-by", "J. Smith",
            "--temperature", "23", "--mounting", "stud"]  # fmt: skip
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--prepared-by: the run records no technician" in err and "Traceback" not in err
    monkeypatch.setenv("ACCELCAL_DB", f"sqlite:///{tmp_path / 'none.sqlite'}")
    window = _window(qtbot, run.parent, None)
    assert window.open_run(run)
    fields = {**GUI_FIELDS, "customer": CUSTOMER, "prepared_by": ""}
    person = Person(monkeypatch, fields)
    assert window.certificate_action() is None
    assert len(person.refusals) == 1 and "--prepared-by: the run records" in person.refusals[0]
    assert not list(run.glob("certificate*"))


def test_the_two_person_rule_is_the_services_for_both_faces(
    lab: Lab, records_runs: tuple[Path, Path], tmp_path: Path, qtbot, monkeypatch, capsys
) -> None:
    """Under the lab's two-person rule the preparer cannot approve: the CLI is refused before
    anything is written, and the GUI dialog's OK refuses it at the field (the service's
    check), leaving the dialog open."""
    from app.gui.certificate_dialog import CertificateDialog

    lab = Lab(own_records(lab, tmp_path), lab.runs)  # persons added: a copy of the records
    add_staff(lab.url, ("atech", "A. Tech"))
    assert main(["register", "set", "two_person_rule", "on", "--db", lab.url]) == 0
    try:
        run = records_runs[1]
        before = sorted(run.glob("certificate*"))
        argv = ["certificate", str(run), "--db", lab.url, "--prepared-by", "A. Tech",
                "--authorised-by", "a. tech", "--temperature", "23", "--mounting", "stud",
                "--out", str(tmp_path / "c.pdf")]  # fmt: skip
        capsys.readouterr()
        assert main(argv) == 2
        assert (
            "approved by: the lab's two-person rule needs another person: 'A. Tech' is user "
            "atech, who prepared it" in capsys.readouterr().err
        )
        assert sorted(run.glob("certificate*")) == before and not (tmp_path / "c.pdf").exists()
        with pytest.raises(RecordsInputError, match="two-person rule"):
            service.check_signatories(lab.url, "A. Tech", "A.  TECH")
        service.check_signatories(None, "A. Tech", "A. Tech")  # no records: no rule
        from app.records.run_folder import load_run

        window = _window(qtbot, run.parent, lab.url)
        dialog = CertificateDialog(
            window, load_run(run), prepared_by="A. Tech",
            check=lambda p, a: service.check_signatories(lab.url, p, a))  # fmt: skip
        qtbot.addWidget(dialog)
        dialog.edits["authorised_by"].setText("A. Tech")
        dialog.accept()
        assert dialog.result() != dialog.DialogCode.Accepted
        assert "two-person rule" in dialog.marks.reason(dialog.edits["authorised_by"])
    finally:
        assert main(["register", "set", "two_person_rule", "off", "--db", lab.url]) == 0


# --- signatories as persons (issue 33 point 3) -------------------------------------------------


def own_records(lab: Lab, tmp_path: Path) -> str:
    """A copy of the session's records (its runs indexed, its chain) this test may change."""
    import sqlite3

    copy = tmp_path / "records.sqlite"
    source = sqlite3.connect(lab.url.removeprefix("sqlite:///"))
    target = sqlite3.connect(copy)
    with target:
        source.backup(target)  # the live database, its write-ahead log included
    source.close()
    target.close()
    return f"sqlite:///{copy}"


def _issue(url: str, run: Path, out: Path, *people: str) -> int:
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab as Records
    from app.records.run_folder import load_run

    current = Records(open_engine(url)).issued_for_run(str(load_run(run).run_id))
    amend = [] if current is None else ["--replaces", current.number, "--reason", "test"]
    return main(["certificate", str(run), "--db", url, "--temperature", "23", "--mounting",
                 "stud", "--out", str(out), *amend, *people])  # fmt: skip


@pytest.mark.slow  # five refused issues through the CLI with records, then one issued (~6 s idle)
def test_the_suffix_signatory_is_refused_by_certificate_naming_the_person(
    lab: Lab, records_runs: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    """The issue's attack through `accelcal certificate`: prepared by "A. Tech", authorised by
    "A. Tech, head of laboratory" (and variants); refused, nothing written. Two persons on
    record pass, and the certificate prints the names recorded for them and the function."""
    url = own_records(lab, tmp_path)
    # user names of their own: other tests of the session add users (a "qm") to the records
    # this copy is made from
    add_staff(url, ("atech", "A. Tech"), ("quality-manager", "Quality Manager"))
    assert main(["register", "set", "two_person_rule", "on", "--db", url]) == 0
    run, out = records_runs[1], tmp_path / "c.pdf"
    attacks = {
        "A. Tech, head of laboratory": "approved by: 'A. Tech, head of laboratory' is no person "
        "on record: the lab's two-person rule takes signatories who are users of the records; "
        "'A. Tech' is user atech: give the name alone and the function with its own option "
        "(--authorised-function)",
        "a.  TECH": "approved by: the lab's two-person rule needs another person: 'A. Tech' is "
        "user atech, who prepared it",
        "atech": "'A. Tech' is user atech, who prepared it",
        "A.\u200bTech": "is user atech, who prepared it",
        "\u0410. Tech": "approved by: 'А. Tech' mixes scripts (Cyrillic, Latin)",
    }
    capsys.readouterr()
    for approved, found in attacks.items():
        code = _issue(url, run, out, "--prepared-by", "A. Tech", "--authorised-by", approved)
        err = capsys.readouterr().err
        assert code == 2 and found in err, (approved, err)
        assert not out.exists()
    people = ("--prepared-by", "atech", "--authorised-by", "quality-manager",
              "--authorised-function", "head of laboratory")  # fmt: skip
    assert _issue(url, run, out, *people) == 0
    assert (
        "two-person rule: prepared by A. Tech and authorised by Quality Manager: two users of "
        "the records" in capsys.readouterr().out
    )
    text = " ".join(" ".join(page.extract_text() for page in PdfReader(out).pages).split())
    assert "Prepared by A. Tech" in text
    assert "Authorised by Quality Manager head of laboratory" in text
    dcc = PdfReader(out).attachments["certificate.xml"][0].decode("utf-8")
    assert '<dcc:content lang="en">Quality Manager</dcc:content>' in dcc
    assert "<dcc:role>head of laboratory</dcc:role>" in dcc
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab as Records

    (row,) = [c for c in Records(open_engine(url)).register() if c.file == str(out.resolve())]
    assert (row.prepared_by, row.approved_by) == ("A. Tech", "Quality Manager")


def test_without_records_the_certificate_says_the_rule_is_not_checked(
    complete_run: Path, tmp_path: Path, capsys
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    argv = ["certificate", str(run), "--customer", CUSTOMER,
            "--customer-address", "1 Test Street, 00-001 Testtown", "--authorised-by", "T. Ester",
            "--authorised-function", "head of laboratory", "--temperature", "23",
            "--mounting", "stud", "--out", str(tmp_path / "c.pdf")]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "two-person rule: NOT checked: without records the signatories are names as typed" in out
