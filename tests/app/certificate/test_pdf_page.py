"""The certificate as a reader meets it (issue 27 point 4): the laboratory's name whole in the
running header, the table of results not started with a few rows on page 1, the statement of
conformity whole on one page and in the overall verdict's words, the customer's address, the
phase sign convention, mV/g for a model in mV/g, "Prepared by", and no bench advice."""

from __future__ import annotations

import dataclasses
import shutil

import pytest
from pypdf import PdfReader
from reportlab.pdfbase import pdfmetrics

from app import formatting as fmt
from app.certificate import CertificateInfo, build, pdf
from app.certificate import text as certificate_text
from app.certificate.pdf_charts import FONT_BOLD
from app.certificate.pdf_marks import read_marks
from app.certificate.pdf_page import HEADER_PT, MIN_HEADER_PT, header_lines
from app.records.run_folder import load_run
from dsp.conformity import DECISION_RULE, Verdict

INFO = CertificateInfo(
    customer="ACME Ltd",
    customer_address="Industriestraße 12, 38100 Braunschweig",
    authorised_by="J. Smith, head of laboratory",
    temperature_c=23.0,
    mounting="stud, 2 N m",
    prepared_by="A. Technician",
    sensitivity_unit="mV/g",
)


def _certificate(run, tmp_path, info=INFO):
    copy = tmp_path / "runs" / run.name
    shutil.copytree(run, copy, ignore=shutil.ignore_patterns("certificate*"))
    return build(copy, info, tmp_path / "c.pdf")


def _rows_per_page(path) -> list[int]:
    """How many lines of the results table each page prints (its marked text layer)."""
    marks = read_marks(path.read_bytes())
    pages = len(PdfReader(path).pages)
    return [sum(1 for page in marks.line_pages.values() if page == i) for i in range(pages)]


def test_header_keeps_the_whole_laboratory_name():
    """Short: one line at the full size; longer: smaller; longer still: two lines at the
    smallest size, every word kept, each line within the room."""
    room = 300.0
    assert header_lines("Short lab", room) == (HEADER_PT, ["Short lab"])
    name = "x" * 60
    size, lines = header_lines(name, room)
    assert lines == [name] and MIN_HEADER_PT <= size < HEADER_PT
    assert pdfmetrics.stringWidth(name, FONT_BOLD, size) <= room
    long = " ".join(["Physikalisch-Technische Kalibrierlaboratorien"] * 3)
    size, lines = header_lines(long, room)
    assert size == MIN_HEADER_PT and len(lines) == 2 and " ".join(lines) == long
    assert all(pdfmetrics.stringWidth(line, FONT_BOLD, size) <= room for line in lines)


def test_pages_of_a_25_line_certificate(complete_run, tmp_path):
    """No table started with a handful of rows on page 1; the statement of conformity whole
    on one page; address, convention, mV/g and Prepared by printed."""
    path = _certificate(complete_run, tmp_path)
    pages = [page.extract_text() for page in PdfReader(path).pages]
    rows = _rows_per_page(path)
    first_rows = rows[0]
    assert first_rows == 0 or first_rows >= 10, f"{first_rows} rows on page 1"
    whole = "\n".join(pages)
    assert sum(rows) == 25  # every row, once
    with_statement = [p for p in pages if "Statement of conformity" in p]
    assert (
        len(with_statement) == 1
        and "frequencies." in with_statement[0].split("Statement of conformity")[1]
    )
    assert "ACME Ltd, Industriestraße 12, 38100 Braunschweig" in whole.replace("\n", " ")
    assert "positive when the" in whole and "leads the acceleration" in whole.replace("\n", " ")
    assert "Prepared by" in whole and "A. Technician" in whole
    results = load_run(complete_run).results_object()
    r = results.reference
    in_g, u_in_g = fmt.round_gum(
        r.sensitivity_mv_per_ms2 * 9.80665, r.expanded_uncertainty_mv_per_ms2 * 9.80665
    )
    assert f"({in_g} ± {u_in_g}) mV/g" in whole
    line = results.lines[-1]
    last_in_g = fmt.round_gum(
        line.sensitivity_mv_per_ms2 * 9.80665, line.expanded_uncertainty_mv_per_ms2 * 9.80665
    )[0]
    assert f"within {last_in_g}" in whole.replace("\n", " ")  # the last column of its row


@pytest.mark.parametrize("cut", [0, 1, 2, 3])
def test_table_not_started_with_a_few_rows_whatever_room_page_1_leaves(
    complete_run, tmp_path, monkeypatch, cut
):
    """Page 1 shortened by the verdict's reasons (a run without a verdict has none): the table
    starts on page 1 with at least 10 rows or on page 2, never with a handful."""
    original = pdf._verdict_section

    def shorter(results):
        return original(dataclasses.replace(results, verdict_reasons=results.verdict_reasons[:cut]))

    monkeypatch.setattr(pdf, "_verdict_section", shorter)
    info = dataclasses.replace(INFO, sensitivity_unit="")
    rows = _rows_per_page(_certificate(complete_run, tmp_path, info))[0]
    assert rows == 0 or rows >= 10, f"{rows} rows on page 1"


def test_without_mv_per_g_no_extra_column_and_no_address_said_so(complete_run, tmp_path):
    info = dataclasses.replace(  # issue 35: no address only with the reason, stated
        INFO, sensitivity_unit="mV/(m/s^2)", customer_address="", address_not_stated="walk-in"
    )
    whole = "\n".join(
        p.extract_text() for p in PdfReader(_certificate(complete_run, tmp_path, info)).pages
    )
    assert "mV/g" not in whole
    assert "ACME Ltd, Address not stated: walk-in" in whole


@pytest.mark.parametrize(
    ("verdict", "words"),
    [
        (Verdict.PASS, "the item <b>conforms</b> to its specification"),
        (Verdict.FAIL, "the item <b>does not conform</b> to its specification"),
        (Verdict.INDETERMINATE, "INDETERMINATE, <b>conformity not stated</b>"),
    ],
)
def test_statement_of_conformity_words_the_overall_verdict(verdict, words):
    """Every check of the verdict, not the characteristic alone: a FAIL of the sensitivity
    with a characteristic passing at every line still does not conform."""
    statement = certificate_text.conformity_statement(verdict, 5.0, ["pass"] * 3)
    assert words in statement and DECISION_RULE in statement
    assert "3 pass, 0 fail, 0 inconclusive, 0 not stated of 3" in statement


def test_no_bench_advice_on_the_certificate(complete_run):
    """A mounting finding is stated; what to check at the bench is not (PDF and DCC)."""
    results = load_run(complete_run).results_object()
    reason = (
        "mounting: a resonance near 1250 Hz inside the calibrated range (+409 % there): check "
        "the mounting (stud torque, contact surface, cable clamping)"
    )
    failed = dataclasses.replace(results, verdict="FAIL", verdict_reasons=(reason,))
    section = pdf._verdict_section(failed)
    texts = " ".join(p.text for p in section[0]._content if hasattr(p, "text"))
    assert "a resonance near 1250 Hz inside the calibrated range (+409 % there)" in texts
    assert "check the mounting" not in texts and "stud torque" not in texts
    declaration = certificate_text.dcc_declaration("FAIL", [reason])
    assert "resonance near 1250 Hz" in declaration and "check the mounting" not in declaration


@pytest.fixture(scope="module")
def run_100_lines(tmp_path_factory):
    """A complete simulated run of 100 lines (20 Hz to 2.5 kHz, geometric, 160 Hz among them,
    on the piezo plan's 0.5 Hz bins; 2 m/s^2 per line keeps the table within its stroke)."""
    import numpy as np

    from app.procedure.run import RunRequest, execute

    lines = np.unique(np.append(np.round(np.geomspace(20, 2500, 99) * 2) / 2, 160.0))
    assert len(lines) == 100
    out = tmp_path_factory.mktemp("runs100")
    finished = execute(
        RunRequest(
            dut="piezo",
            dut_id="SN-42",
            periods=3,
            level_ms2=2.0,
            tolerance_percent=5.0,
            frequencies_hz=tuple(float(f) for f in lines),
            out=out,
        )
    )
    return out / str(finished.record.run_id)


SIGN_OFF = ("Prepared by", "Authorised by", "signature:", "Date of issue", "Raw data SHA-256")
STATEMENTS = ("Uncertainty statement", "Statement of conformity", "Notes")


@pytest.mark.parametrize("lines", [25, 100])
def test_the_sign_off_never_stands_alone_on_the_last_page(
    complete_run, run_100_lines, tmp_path, lines
):
    """The sign-off block is on the last page only, with the statements before it (or at
    least results rows) on that page too: at 25 lines (4 pages) it once stood alone on
    page 4; at 100 lines (5 pages)."""
    run = complete_run if lines == 25 else run_100_lines
    path = _certificate(run, tmp_path)
    pages = [page.extract_text() for page in PdfReader(path).pages]
    rows = _rows_per_page(path)
    assert sum(rows) == lines
    last = pages[-1]
    assert all(word in last for word in SIGN_OFF)
    assert not any("Prepared by" in page for page in pages[:-1])
    with_it = [h for h in STATEMENTS if h in last] or rows[-1]
    assert with_it, f"page {len(pages)} holds the sign-off alone: {last[:300]!r}"
    assert "Statement of conformity" in last  # the statements sit with the signature
