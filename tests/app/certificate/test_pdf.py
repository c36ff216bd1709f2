"""The PDF certificate: every ISO/IEC 17025 item, numbers as stored, refusals, reproducibility."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
import stat
import subprocess

import pytest
from pypdf import PdfReader

from app import formatting as fmt
from app.certificate import CertificateError, CertificateInfo, build
from app.records.run_folder import load_run

INFO = CertificateInfo(
    customer="ACME Ltd",
    customer_address="1 Test Street, 00-001 Testtown",
    authorised_by="J. Smith, head of laboratory",
    temperature_c=23.0,
    mounting="stud-mounted back-to-back, 2 N m",
)


def text_of(path) -> str:
    return "\n".join(page.extract_text() for page in PdfReader(path).pages)


def fresh_root(run, tmp_path):
    """The shared run copied under a runs root of its own (a register that issued nothing)."""
    copy = tmp_path / "runs" / run.name
    shutil.copytree(run, copy, ignore=shutil.ignore_patterns("certificate*"))
    return copy


def test_every_mandatory_item_and_the_stored_numbers(complete_run, tmp_path):
    run = fresh_root(complete_run, tmp_path)
    pdf = build(run, INFO, tmp_path / "c.pdf")
    text = text_of(pdf)
    record = load_run(run)
    results = record.results_object()
    value, u = fmt.round_gum(
        results.reference.sensitivity_mv_per_ms2, results.reference.expanded_uncertainty_mv_per_ms2
    )
    number = f"AC-{record.run_id}"
    for item in [
        "CALIBRATION CERTIFICATE",
        "accelcal demonstration laboratory",
        "Gliwice",
        number,
        "ACME Ltd",
        "SN-42",
        "piezoelectric accelerometer",
        "Date of calibration",
        "Date of issue",
        "ISO 16063-21",
        "multisine",
        "Ambient temperature",
        "23.0",
        "stud-mounted",
        "Excitation level",
        "REF-8305-SIM",
        "SIM-CAL-2026-001",
        "2026-06-01",
        "Reference frequency",
        f"({value} ± {u}) mV/(m/s²)",
        "k = 2.00",
        "95.45 %",
        "Uncertainty statement",
        "Statement of conformity",
        "guarded",
        "J. Smith",
        "results relate only to the item",
        record.software_version,
        record.raw_data_sha256,
        record.run_id,
        "Uncertainty budget",
        "reference standard calibration",
    ]:
        assert item in text, item
    words = " ".join(text.split())  # the column says what it is: the calibration's U (issue 35)
    assert "U vs. ISO 16063-21 limit" in words
    assert "a statement about the uncertainty of the calibration, not about the sensor" in words
    pages = len(PdfReader(pdf).pages)
    for page in range(1, pages + 1):
        assert f"page {page} of {pages}" in text
    assert text.count(number) >= pages + 1  # the number on every page


def test_reproducible_bytes_and_never_overwritten(complete_run, tmp_path, monkeypatch):
    """The same run and options give the same bytes: the run copied under another runs root
    (whose register has not issued the number yet). The creation date is the real one unless
    $SOURCE_DATE_EPOCH fixes it (issue 27: no longer 2000-01-01 in invariant mode)."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1764028800")  # 2025-11-25T00:00:00Z
    info = dataclasses.replace(INFO, certificate_number="LAB-REPRO-1")
    copy = tmp_path / "elsewhere" / complete_run.name
    shutil.copytree(complete_run, copy, ignore=shutil.ignore_patterns("certificate*"))
    first = build(complete_run, info, tmp_path / "a.pdf").read_bytes()
    # another folder: a number a file carries is never given again in its folder (issue 23)
    second = build(copy, info, tmp_path / "other" / "b.pdf").read_bytes()
    assert hashlib.sha256(first).digest() == hashlib.sha256(second).digest()
    with pytest.raises(CertificateError, match="never overwritten"):
        build(complete_run, INFO, tmp_path / "a.pdf")
    with pytest.raises(CertificateError, match="--certificate-number: LAB-REPRO-1 is already"):
        build(copy, info, tmp_path / "c.pdf")


def test_metadata_dated_now_unless_source_date_epoch(complete_run, tmp_path, monkeypatch):
    """The PDF's creation date is the moment it was written (UTC), not reportlab's invariant
    2000-01-01; $SOURCE_DATE_EPOCH (reproducible builds) sets it."""
    import datetime

    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    before = datetime.datetime.now(datetime.UTC).replace(microsecond=0)
    info = dataclasses.replace(INFO, certificate_number="T-NOW")
    pdf = build(complete_run, info, tmp_path / "n.pdf")
    created = PdfReader(pdf).metadata.creation_date.replace(tzinfo=datetime.UTC)
    assert before <= created <= datetime.datetime.now(datetime.UTC)
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1764028800")
    info = dataclasses.replace(INFO, certificate_number="T-SDE")
    pdf = build(complete_run, info, tmp_path / "s.pdf")
    created = PdfReader(pdf).metadata.creation_date
    assert created.strftime("%Y-%m-%d %H:%M:%S") == "2025-11-25 00:00:00"


def test_missing_items_are_refused_by_name(complete_run, tmp_path):
    with pytest.raises(CertificateError) as info:
        build(complete_run, CertificateInfo(customer="ACME Ltd"), tmp_path / "x.pdf")
    message = str(info.value)
    for name in ("authorised_by", "mounting"):
        assert name in message
    assert "customer (--customer)" not in message  # given
    # issue 35: the temperature the stand's sensor read at run start is the default
    assert "temperature_c" not in message
    assert not (tmp_path / "x.pdf").exists()


def test_aborted_run_is_refused(aborted_run, tmp_path):
    run = tmp_path / aborted_run.name
    shutil.copytree(aborted_run, run)
    assert json.loads((run / "results.json").read_text())["status"] == "aborted"
    with pytest.raises(CertificateError, match="the run is aborted"):
        build(run, INFO, tmp_path / "x.pdf")


def test_cli_certificate_default_place_and_exit_codes(complete_run, tmp_path, capsys):
    from app.cli import main

    run = tmp_path / "runs" / complete_run.name  # the session's run stays as it is
    shutil.copytree(complete_run, run)
    argv = [
        "certificate",
        str(run),
        "--customer",
        "ACME Ltd",
        "--customer-address",
        "1 Test Street, 00-001 Testtown",
        "--authorised-by",
        "J. Smith",
        "--temperature",
        "23",
        "--mounting",
        "stud",
    ]
    assert main(argv) == 0
    assert (run / "certificate.pdf").exists()
    capsys.readouterr()
    assert main(argv) == 2  # not overwritten
    assert main(["certificate", str(run), "--out", "/tmp/never.pdf"]) == 2
    assert "missing mandatory item(s)" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("pdftoppm") is None, reason="poppler-utils not installed")
def test_the_pdf_renders(complete_run, tmp_path):
    pdf = build(complete_run, INFO, tmp_path / "r.pdf")
    subprocess.run(["pdftoppm", "-r", "40", "-png", str(pdf), str(tmp_path / "p")], check=True)
    pages = sorted(tmp_path.glob("p-*.png"))
    assert len(pages) == len(PdfReader(pdf).pages) and all(p.stat().st_size > 5000 for p in pages)


def test_sweep_section_with_sensitivity_against_level_and_linearity(tmp_path):
    from pathlib import Path

    from app.procedure.run import RunRequest
    from app.procedure.sweep import run_sweep

    # its own piezo sweep: the session's (tests/conftest.py sweep_run) is of the capacitive DUT,
    # whose compression at 7 m/s^2 brings warnings that block a certificate
    sweep = run_sweep(RunRequest(dut="piezo", dut_id="SN-7", periods=3, out=tmp_path), [3.0, 6.0])
    run = tmp_path / sweep.summary["run_ids"][0]
    assert stat.S_IMODE(Path(sweep.summary["path"]).stat().st_mode) == 0o444  # stored, read-only
    pdf = build(run, INFO, tmp_path / "s.pdf", Path(sweep.summary["path"]))
    text = text_of(pdf)
    assert "Sensitivity against excitation level" in text and "Linearity:" in text
    assert "3 m/s²" in text and "6 m/s²" in text
    reference = sweep.summary["sensitivity_mv_per_ms2"][1][
        sweep.summary["frequencies_hz"].index(160.0)
    ]
    assert f"{reference:.4g}" in text
    other = tmp_path / "other.json"
    other.write_text('{"status": "complete", "sensitivity_mv_per_ms2": [], "run_ids": []}')
    with pytest.raises(CertificateError, match="does not include run"):
        build(run, INFO, tmp_path / "t.pdf", other)


def test_names_beyond_latin_1_print_as_themselves_in_an_embedded_font(complete_run, tmp_path):
    """Łukasz Żółć, Jiří Dvořák, Jürgen Weiß: the packaged DejaVu Sans is embedded and used for
    all text (the PDF base fonts have no Latin Extended-A glyphs; they would print boxes)."""
    info = dataclasses.replace(
        INFO,
        customer="Łukasz Żółć, Gdańsk",
        authorised_by="Jiří Dvořák, kierownik laboratorium",
        mounting="Jürgen Weiß: stud, 2 N m",
    )
    pdf = build(complete_run, info, tmp_path / "utf.pdf")
    text = text_of(pdf)
    for name in ("Łukasz Żółć", "Gdańsk", "Jiří Dvořák", "Jürgen Weiß"):
        assert name in text
    reader = PdfReader(pdf)
    fonts = set()
    for page in reader.pages:
        for font in page["/Resources"]["/Font"].values():
            font = font.get_object()
            fonts.add(str(font["/BaseFont"]))
            descendants = font.get("/DescendantFonts")
            descriptor = (
                descendants[0].get_object()["/FontDescriptor"]
                if descendants
                else font.get("/FontDescriptor")
            )
            if "DejaVu" in str(font["/BaseFont"]):
                assert "/FontFile2" in descriptor.get_object()  # the TrueType program embedded
    assert fonts and all("DejaVuSans" in f for f in fonts), fonts


def test_packaged_font_ships_with_its_license():
    from importlib import resources

    data = resources.files("app").joinpath("data")
    for name in ("DejaVuSans.ttf", "DejaVuSans-Bold.ttf"):
        assert data.joinpath(name).read_bytes()[:4] == b"\x00\x01\x00\x00"  # TrueType
    assert "Bitstream" in data.joinpath("DejaVu-LICENSE.txt").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"customer": "   "}, "customer (--customer)"),
        ({"authorised_by": "\t"}, "authorised_by (--authorised-by)"),
        ({"temperature_c": float("nan")}, "temperature_c (--temperature): nan"),
        ({"temperature_c": -300.0}, "temperature_c (--temperature): -300.0"),
        ({"temperature_c": float("inf")}, "temperature_c (--temperature)"),
        ({"issue_date": "banana"}, "issue_date (--issue-date): 'banana'"),
        ({"issue_date": "2026-13-01"}, "issue_date (--issue-date)"),
        ({"issue_date": "2026-1-5"}, "issue_date (--issue-date)"),
    ],
)
def test_bad_fields_are_refused_by_name_whatever_the_caller(
    complete_run, tmp_path, change, message
):
    """The GUI's dialog calls the same code as the CLI: the checks are in app.certificate."""
    out = tmp_path / "bad.pdf"
    with pytest.raises(CertificateError) as info:
        build(complete_run, dataclasses.replace(INFO, **change), out)
    assert message in str(info.value)
    assert not out.exists()
