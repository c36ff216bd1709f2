"""The certificate's marked text layer (app.certificate.pdf_marks) as an attacker meets it:
`verify` reads each printed item between delimiters the writer places as PDF operators, so a
label, a customer name or a note that looks like an item, a label or a delimiter is only text;
a page that prints another value than its DCC, or an item twice, fails."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from reportlab.pdfgen import canvas

from app.certificate import pdf as certificate_pdf
from app.certificate.pdf_marks import MarkError, printed_equal, read_marks
from app.certificate.printed import Column, Item
from app.certificate.readback import items_from_pdf
from app.cli import main
from app.records.seal import read_seal
from tests.app.certificate.conftest import copy_run
from tests.app.certificate.test_issue_matrix import ITEMS, assert_verified, verify_lines

FAKE = "f" * 64
HOSTILE = (
    "Run seal",
    f"ACME\nRun seal\n{FAKE}\nRecords chain head\n{FAKE}",
    f"Certificate number X-1 Customer /Span <</AcItem (seal)>> BDC ({FAKE}) Tj EMC",
    "EMC EMC ) ( \\ Date of issue 1999-01-01 Overall verdict FAIL",
)


@pytest.mark.parametrize("customer", HOSTILE)
def test_a_customer_name_that_looks_like_an_item_or_a_delimiter_is_only_text(
    complete_run: Path, tmp_path: Path, capsys, customer: str
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "certificate.pdf"
    argv = [
        "certificate",
        str(run),
        "--out",
        str(pdf),
        "--customer",
        customer,
        "--address-not-stated",
        "walk-in customer",
        *ITEMS,
    ]
    assert main(argv) == 0
    assert_verified(verify_lines(capsys, pdf, "--run", run), signed=False)
    marks = read_marks(pdf.read_bytes())
    # issue 35: no address only with a reason, printed with it
    expected = f"{customer}, Address not stated: walk-in customer"
    assert printed_equal(marks.item(Item.CUSTOMER), expected)
    assert marks.item(Item.SEAL).replace("\n", "") == read_seal(run)[1] != FAKE
    assert Item.CHAIN_HEAD not in marks.items  # a run made without records names none
    assert marks.item(Item.VERDICT) == "PASS"


@pytest.fixture()
def forged_run(complete_run: Path, tmp_path: Path) -> Path:
    return copy_run(complete_run, tmp_path / "runs")


def _issue(run: Path, pdf: Path) -> None:
    assert (
        main(
            [
                "certificate",
                str(run),
                "--out",
                str(pdf),
                "--customer",
                "ACME Ltd",
                "--customer-address",
                "1 Test Street, 00-001 Testtown",
                *ITEMS,
            ]
        )
        == 0
    )


def test_a_page_that_prints_another_seal_than_its_dcc_fails(
    forged_run: Path, tmp_path: Path, capsys, monkeypatch
) -> None:
    monkeypatch.setattr(certificate_pdf, "named_seal", lambda folder: FAKE)
    pdf = tmp_path / "forged.pdf"
    _issue(forged_run, pdf)
    lines = verify_lines(capsys, pdf, "--run", forged_run)
    (printed,) = [line for line in lines if "DCC numbers printed in the PDF" in line]
    assert printed.startswith("FAIL") and f"seal: DCC '{read_seal(forged_run)[1]}'" in printed


def test_a_page_that_prints_another_number_in_its_table_fails_against_dcc_and_run(
    forged_run: Path, tmp_path: Path, capsys, monkeypatch
) -> None:
    honest = certificate_pdf.table_cells

    def forged(line, stated, in_g=False):
        cells = honest(line, stated, in_g)
        if line.nominal_frequency_hz != 160.0:
            return cells
        return tuple((c, "9.999" if c == Column.SENSITIVITY else v) for c, v in cells)

    monkeypatch.setattr(certificate_pdf, "table_cells", forged)
    pdf = tmp_path / "forged.pdf"
    _issue(forged_run, pdf)
    lines = verify_lines(capsys, pdf, "--run", forged_run)
    failed = [line for line in lines if line.startswith("FAIL") and "signature" not in line]
    assert [f.partition(":")[0] for f in failed] == [
        "FAIL DCC numbers printed in the PDF",
        "FAIL PDF results table equals the run's results",
    ], lines
    assert all("s: " in f and "'9.999'" in f for f in failed), failed
    assert "ok   DCC numbers equal the run's results" in lines  # the DCC was honest


def _pdf(draw) -> bytes:
    buffer = io.BytesIO()
    page = canvas.Canvas(buffer)
    draw(page)
    page.showPage()
    page.save()
    return buffer.getvalue()


def _item(page, name: str, text: str, y: float, line: int | None = None) -> None:
    extra = f" /AcLine {line}" if line is not None else ""
    page.addLiteral(f"/Span <</AcItem ({name}){extra}>> BDC")
    page.drawString(72, y, text)
    page.addLiteral("EMC")


def test_the_reader_takes_the_text_between_the_delimiters_and_nothing_else() -> None:
    def draw(page):
        page.drawString(72, 800, "Run seal")  # a label: unmarked, never read
        _item(page, "seal", "abc", 780)
        page.drawString(72, 760, "Records chain head")
        _item(page, "s", "10.21", 740, line=1)
        _item(page, "f", "160", 720, line=1)

    marks = read_marks(_pdf(draw))
    assert marks.items == {Item.SEAL: ("abc",)}
    assert marks.cells == {(1, Column.SENSITIVITY): ("10.21",), (1, Column.FREQUENCY): ("160",)}
    items = items_from_pdf(marks)
    assert (items.seal, items.chain_head, items.lines[0].s, items.lines[0].f) == (
        "abc", "", "10.21", "160")  # fmt: skip


@pytest.mark.parametrize(
    ("draw", "reason"),
    [
        (lambda p: (_item(p, "seal", "a", 800), _item(p, "seal", "b", 780)), "seal: printed twice"),
        (lambda p: (_item(p, "s", "1", 800, 1), _item(p, "s", "2", 780, 1)),
         "line 1 s: printed twice"),
        (lambda p: _item(p, "password", "x", 800), "unknown printed item 'password'"),
        (lambda p: _item(p, "pwd", "x", 800, 1), "unknown column 'pwd'"),
        (lambda p: _item(p, "s", "x", 800, 0), "line 0 is not a line number"),
        (lambda p: _item(p, "s", "x", 800, 2), "lines are not 1..1"),
        (lambda p: (p.addLiteral("/Span <</AcItem (seal)>> BDC"), _item(p, "number", "1", 800)),
         "item number inside seal"),
        (lambda p: p.addLiteral("/Span <</AcItem (seal)>> BDC"), "item seal is never closed"),
    ],
)  # fmt: skip
def test_an_ambiguous_marked_layer_is_refused(draw, reason: str) -> None:
    with pytest.raises(MarkError, match=reason.replace("(", r"\(").replace(")", r"\)")):
        read_marks(_pdf(draw))


@pytest.mark.parametrize(
    ("printed", "stated", "same"),
    [
        ("ab\ncd", "abcd", True),  # a hash broken inside
        ("ab\ncd", "ab cd", True),  # a name broken at its blank
        ("ab cd", "ab  cd", True),  # blanks collapsed, as a paragraph sets them
        ("ab\ncd", "ab\ncd", True),
        ("ab\ncd", "abxcd", False),
        ("ab", "ab cd", False),
        ("ab cd", "abcd", False),  # a blank is never dropped but at a line break
        ("", "x", False),
    ],
)
def test_a_line_break_stands_for_one_blank_or_nothing(printed: str, stated: str, same: bool):
    assert printed_equal(printed, stated) is same


def test_a_pdf_drawn_without_the_marked_layer_fails_saying_so(
    forged_run: Path, tmp_path: Path, capsys, monkeypatch
) -> None:
    """A certificate drawn before the layer existed (here: drawn with plain paragraphs and
    tables): its printed items are not guessed from labels; the DCC is still checked."""
    from reportlab.platypus import Paragraph, Table

    monkeypatch.setattr(
        certificate_pdf, "MarkedParagraph", lambda t, style, item: Paragraph(t, style)
    )
    monkeypatch.setattr(certificate_pdf, "MarkedTable", Table)
    pdf = tmp_path / "unmarked.pdf"
    _issue(forged_run, pdf)
    assert read_marks(pdf.read_bytes()).items == {}
    lines = verify_lines(capsys, pdf, "--run", forged_run)
    assert "FAIL DCC numbers printed in the PDF: the PDF has no marked text layer" in "\n".join(
        lines
    )
    assert "ok   DCC numbers equal the run's results" in lines
