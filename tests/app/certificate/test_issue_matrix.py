"""Every way the lab issues a certificate is verified (issue 31 point 6): `accelcal verify --run`
(signed ones with --trust) and the web view pass each certificate issued by the CLI without
and with records, by the GUI's certificate dialog, signed and unsigned, amended, for a long
customer name and for a 100-line plan."""

from __future__ import annotations

import html
import os
import re
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from app.certificate import dcc_sign
from app.cli import main
from tests.app.certificate.conftest import SENSOR, Lab, Pki, copy_run

pytestmark = pytest.mark.integration

ITEMS = ("--authorised-by", "J. Smith", "--prepared-by", "A. Tech", "--temperature", "23",
         "--mounting", "stud, 2 N m")  # fmt: skip
UNSIGNED = "signature: the PDF is not signed: nothing proves who issued it"
UNSIGNED_DCC = f"{dcc_sign.CHECK}: {dcc_sign.UNSIGNED_DETAIL}"  # its own signature (issue 35)


def verify_lines(capsys: pytest.CaptureFixture[str], pdf: Path, *argv: str | Path) -> list[str]:
    """`accelcal verify PDF ARGV...`'s report lines (its exit status checked against them)."""
    capsys.readouterr()
    code = main(["verify", str(pdf), *map(str, argv)])
    lines = capsys.readouterr().out.strip().splitlines()
    assert code == (0 if lines[-1] == "certificate verified" else 2), lines
    return lines


def assert_verified(lines: list[str], signed: bool) -> None:
    """Signed: every check passed. Unsigned: every check passed but the signatures', the
    PDF's and the DCC's own (issue 35), which say only that they are not signed."""
    failed = [line for line in lines[:-1] if not line.startswith("ok   ")]
    if signed:
        assert not failed and lines[-1] == "certificate verified", lines
    else:
        assert failed == [f"FAIL {UNSIGNED}", f"FAIL {UNSIGNED_DCC}"], lines
        assert lines[-1] == f"certificate NOT verified: {UNSIGNED}"
    names = {line[5:].partition(":")[0] for line in lines[:-1]}
    for check in ("DCC numbers printed in the PDF", "run seal recomputed and named by the "
                  "certificate", "DCC numbers equal the run's results"):  # fmt: skip
        assert check in names, lines


def test_a_certificate_of_a_run_made_with_records_verifies(
    lab: Lab, records_runs: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    """The defect of issue 31: the PDF reader took the "Records chain head" line into the
    seal's value, so every certificate of a run made with the records failed."""
    run = records_runs[1]
    pdf = tmp_path / "certificate.pdf"
    capsys.readouterr()
    assert main(["certificate", str(run), "--db", lab.url, "--out", str(pdf), *ITEMS]) == 0
    number = _number(capsys.readouterr().out)
    assert_verified(verify_lines(capsys, pdf, "--run", run), signed=False)
    assert_web_verified(lab, number, signed=False, trust=None)  # "Some checks failed" before


def web_lines(lab: Lab, number: str, trust: Path | None) -> tuple[bool, list[str]]:
    """The web view's certificate page for `number` (signed in, with the lab's CA certificate
    `trust`): whether it says every check passed, and its check rows as 'pass NAME' / 'FAIL
    NAME: DETAIL'."""
    from starlette.testclient import TestClient

    from app.records.db.engine import open_engine
    from app.web.server import WebConfig, create_app
    from app.web.store import Store, open_read_only
    from app.web.users import add_user

    engine = open_engine(lab.url)
    try:
        add_user(engine, "qm", "correct horse battery", display_name="QM", actor="test")
    except Exception:  # added by an earlier test of the session
        pass
    finally:
        engine.dispose()
    reader = open_read_only(lab.url)
    try:
        client = TestClient(create_app(Store(reader), WebConfig(secret_key="k" * 40, trust=trust)))
        login = client.get("/login").text
        csrf = re.search(r'name="csrf" value="([^"]+)"', login).group(1)  # type: ignore[union-attr]
        data = {"username": "qm", "password": "correct horse battery", "csrf": csrf}
        assert client.post("/login", data=data, follow_redirects=False).status_code == 303
        page = client.get(f"/certificates/{number}").text
    finally:
        reader.dispose()
    rows = re.findall(
        r'<td class="(ok|bad|note)">(pass|FAIL|not signed)</td><td>([^<]*)</td><td>([^<]*)</td>',
        page,
    )
    return 'id="verified" class="ok">Every check passed' in page, [
        html.unescape(f"{word} {name}") + (html.unescape(f": {detail}") if cls != "ok" else "")
        for cls, word, name, detail in rows
    ]


def assert_web_verified(lab: Lab, number: str, signed: bool, trust: Path | None) -> None:
    """The web view shows `number` verified: every check passed (signed, with the CA), or
    (unsigned) every check but the signature's, which says only that it is not signed: a
    failure where the web view names the lab's CA, "not signed, by the laboratory's policy"
    where it names none (issue 35: a lab that does not sign)."""
    verified, rows = web_lines(lab, number, trust)
    assert any(r == f"pass the PDF is certificate {number}" for r in rows), rows
    assert "pass DCC numbers printed in the PDF" in rows, rows
    assert "pass PDF results table equals the run's results" in rows, rows
    failed = [r for r in rows if r.startswith("FAIL")]
    if signed:
        assert verified and not failed, rows
    elif trust is not None:
        assert not verified and failed == [f"FAIL {UNSIGNED}", f"FAIL {UNSIGNED_DCC}"], rows
    else:  # the PDF's signature and the DCC's (issue 35), each "not signed" by policy
        policy = [r for r in rows if r.startswith("not signed ")]
        assert verified and not failed and len(policy) == 2, rows
        assert policy[0].startswith("not signed signature"), rows
        assert policy[1].startswith(f"not signed {dcc_sign.CHECK}"), rows
        assert all("not signed, by the laboratory's policy" in p for p in policy), rows


def _number(out: str) -> str:
    return re.search(r"^certificate (\S+): ", out, re.M).group(1)  # type: ignore[union-attr]


def test_the_cli_without_records_unsigned_and_signed(
    complete_run: Path, pki: Pki, sign_password: str, tmp_path: Path, capsys
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    argv = [
        "certificate",
        str(run),
        "--customer",
        "ACME Ltd",
        "--customer-address",
        "1 Test Street, 00-001 Testtown",
        *ITEMS,
    ]
    assert main(argv) == 0  # <run>/certificate.pdf, numbered by the run folder's register
    assert_verified(verify_lines(capsys, run / "certificate.pdf", "--run", run), signed=False)
    signed = tmp_path / "signed.pdf"
    assert main([*argv, "--out", str(signed), "--sign", str(pki.key)]) == 0
    lines = verify_lines(capsys, signed, "--run", run, "--trust", pki.ca)
    assert_verified(lines, signed=True)


def test_the_cli_with_records_then_its_signed_amendment(
    lab: Lab, records_runs: tuple[Path, Path], pki: Pki, sign_password: str, capsys
) -> None:
    run = records_runs[0]
    capsys.readouterr()
    assert main(["certificate", str(run), "--db", lab.url, *ITEMS]) == 0
    original = _number(capsys.readouterr().out)
    assert_verified(verify_lines(capsys, run / "certificate.pdf", "--run", run), signed=False)
    argv = ["certificate", str(run), "--db", lab.url, "--replaces", original, "--reason",
            "mounting corrected", "--sign", str(pki.key), *ITEMS]  # fmt: skip
    assert main(argv) == 0  # no --out: the next free certificate-2.pdf of the run
    amendment = _number(capsys.readouterr().out)
    pdf = run / "certificate-2.pdf"
    assert_verified(verify_lines(capsys, pdf, "--run", run, "--trust", pki.ca), signed=True)
    assert_web_verified(lab, original, signed=False, trust=pki.ca)
    assert_web_verified(lab, amendment, signed=True, trust=pki.ca)


def test_a_long_customer_name_wrapped_onto_several_lines(
    complete_run: Path, tmp_path: Path, capsys
) -> None:
    from app.certificate.pdf_marks import read_marks
    from app.certificate.printed import Item

    run = copy_run(complete_run, tmp_path / "runs")
    customer = " ".join(["Physikalisch-Technische Kalibrierlaboratorien Braunschweig"] * 4)
    address = "Bundesallee 100, 38116 Braunschweig, " + "Gebäude " * 12 + "Raum 1"
    argv = [
        "certificate",
        str(run),
        "--customer",
        customer,
        "--customer-address",
        "1 Test Street, 00-001 Testtown",
        "--customer-address",
        address,
    ]
    assert main([*argv, *ITEMS]) == 0
    pdf = run / "certificate.pdf"
    assert len(read_marks(pdf.read_bytes()).items[Item.CUSTOMER]) >= 3  # it did wrap
    assert_verified(verify_lines(capsys, pdf, "--run", run), signed=False)


def test_a_100_line_plan_of_a_long_named_customer_with_records(
    lab: Lab, run_100: Path, capsys
) -> None:
    from app.certificate.pdf_marks import read_marks
    from app.certificate.printed import Item

    capsys.readouterr()
    assert main(["certificate", str(run_100), "--db", lab.url, *ITEMS]) == 0
    number = _number(capsys.readouterr().out)
    pdf = run_100 / "certificate.pdf"
    marks = read_marks(pdf.read_bytes())
    assert marks.lines == 100 and len(set(marks.line_pages.values())) >= 2  # over pages
    assert len(marks.items[Item.CUSTOMER]) >= 3  # the customer's name and address wrap
    assert_verified(verify_lines(capsys, pdf, "--run", run_100), signed=False)
    assert_web_verified(lab, number, signed=False, trust=None)


# --- the GUI's certificate dialog ---------------------------------------------------------


class Person:
    """Fills the real certificate dialog as a person would, presses OK (the dialog's own
    check runs) and answers Yes to the question that names the run."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, fields: dict[str, str]):
        from PySide6.QtWidgets import QMessageBox

        from app.gui import certificate_dialog, certify

        self.questions: list[str] = []
        self.refusals: list[str] = []
        person = self

        def exec_(dialog: Any) -> int:
            for key, value in fields.items():
                target = dialog.prepared if key == "prepared_by" else dialog.edits.get(key)
                (dialog.temperature if key == "temperature" else target).setText(value)
            dialog.accept()
            return dialog.result()

        monkeypatch.setattr(certificate_dialog.CertificateDialog, "exec", exec_)
        monkeypatch.setattr(
            QMessageBox,
            "question",
            lambda parent, title, text, *a: (
                person.questions.append(text) or QMessageBox.StandardButton.Yes
            ),
        )
        monkeypatch.setattr(
            QMessageBox, "warning", lambda p, t, text, *a: person.refusals.append(text)
        )
        monkeypatch.setattr(certify.QDesktopServices, "openUrl", lambda url: True)


GUI_FIELDS = {"authorised_by": "J. Smith", "prepared_by": "A. Tech", "temperature": "23",
              "customer_address": "1 Test Street, 00-001 Testtown",
              "mounting": "stud, 2 N m"}  # fmt: skip


def _window(qtbot: Any, runs: Path, db: str | None) -> Any:
    from app.gui.main_window import MainWindow

    window = MainWindow(out=runs, paced=False, db=db)
    qtbot.addWidget(window)
    window.records.wait()
    return window


def test_the_gui_dialog_with_records_then_the_cli_amends_it_signed(
    lab: Lab, tmp_path: Path, pki: Pki, sign_password: str, qtbot, monkeypatch, capsys
) -> None:
    """A third run of SN-7 certified by the GUI's dialog through the records' register, then
    amended by the CLI, signed."""
    from tests.app.certificate.conftest import _new_run

    run = _new_run(lab.runs, "--sensor", SENSOR, "--seed", "3", "--db", lab.url)
    window = _window(qtbot, lab.runs, lab.url)
    assert window.records.lab is not None and window.open_run(run)
    person = Person(monkeypatch, GUI_FIELDS)
    pdf = window.certificate_action()
    assert pdf == run / "certificate.pdf" and not person.refusals, person.refusals
    assert "enter it in the register" in person.questions[0] and run.name in person.questions[0]
    number = window.last_certificate
    assert_verified(verify_lines(capsys, pdf, "--run", run), signed=False)
    assert_web_verified(lab, number, signed=False, trust=None)
    argv = ["certificate", str(run), "--db", lab.url, "--replaces", number, "--reason",
            "temperature corrected", "--sign", str(pki.key), *ITEMS]  # fmt: skip
    assert main(argv) == 0
    amended = run / "certificate-2.pdf"
    lines = verify_lines(capsys, amended, "--run", run, "--trust", pki.ca)
    assert_verified(lines, signed=True)


def test_the_gui_dialog_without_records(
    complete_run: Path, tmp_path: Path, qtbot, monkeypatch, capsys
) -> None:
    monkeypatch.setenv("ACCELCAL_DB", f"sqlite:///{tmp_path / 'none.sqlite'}")  # no schema
    run = copy_run(complete_run, tmp_path / "runs")
    window = _window(qtbot, run.parent, None)
    assert window.records.lab is None and window.open_run(run)
    person = Person(monkeypatch, {**GUI_FIELDS, "customer": "ACME Ltd"})
    pdf = window.certificate_action()
    assert pdf == run / "certificate.pdf" and not person.refusals, person.refusals
    assert "register" not in person.questions[0]
    assert_verified(verify_lines(capsys, pdf, "--run", run), signed=False)
