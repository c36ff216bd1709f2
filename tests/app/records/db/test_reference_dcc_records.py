"""Issue 35 point 4 on SQLite and PostgreSQL: `accelcal refs add --dcc` reads a reference
standard's DCC written by hand into the records (table, identity, SHA-256, the file kept), the
next certificate made with that reference names the DCC's identity and SHA-256 (PDF text and
DCC), a malformed DCC is refused (exit 2) naming the element, and a recalibration from a CSV
table takes the DCC out of force."""

from __future__ import annotations

import hashlib
import json
from datetime import date
from pathlib import Path

import pytest

from app.cli import main
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from tests.records_db import seed_lab

DATA = Path(__file__).parents[3] / "data" / "refdcc"
RUN = ["run", "--sim", "--dut", "piezo", "--periods", "3", "--seed", "1", "--fresh-response"]
CERTIFICATE = [
    "--temperature",
    "23",
    "--mounting",
    "stud",
    "--prepared-by",
    "A. Tech",
    "--authorised-by",
    "J. Smith",
]


@pytest.fixture
def url(migrated_url: str, monkeypatch: pytest.MonkeyPatch) -> str:
    """A lab on each engine with customer, model and sensor SN-7; no reference standard."""
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    seed_lab(Lab(open_engine(migrated_url), actor="t"), {"SN-7": "ACME Ltd"})
    return migrated_url


def _add(url: str, dcc: str, *extra: str, identifier: str = "REF-8305-SIM") -> int:
    argv = ["refs", "add", identifier, "--dcc", str(DATA / dcc), "--due", "2099-03-04"]
    return main([*argv, "--db", url, *extra])


def test_a_hand_written_dcc_is_accepted_and_named_on_the_next_certificate(
    url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pypdf import PdfReader

    from app.certificate.dcc import validation_error

    signed = DATA / "signed.xml"
    sha256 = hashlib.sha256(signed.read_bytes()).hexdigest()
    assert _add(url, "signed.xml", "--dcc-certificate", str(DATA / "signer.pem")) == 0
    said = capsys.readouterr().out
    assert "reference REF-8305-SIM added from its DCC (5 table rows, due 2099-03-04)" in said
    assert "signature: signed by DCC signing, National Vibration Laboratory, verified" in said
    assert f"SHA-256: {sha256}" in said
    lab = Lab(open_engine(url))
    table = lab.reference_table("REF-8305-SIM", "")
    assert table is not None and table.dcc is not None
    assert table.certificate_number == "NMI-VIB-2026-0412"  # the DCC's uniqueIdentifier
    assert (table.model, table.serial, str(table.calibration_date)) == (
        "8305-001",
        "SIM-0001",
        "2026-03-04",
    )
    assert table.frequencies_hz == (10, 80, 160, 1000, 10000)
    assert table.sensitivity_mv_per_ms2 == (1.0051, 1.0, 0.9998, 1.0004, 1.017)
    assert table.relative_expanded_uncertainty[1] == pytest.approx(0.004)
    assert table.phase_deg == (-0.1, -0.05, 0.0, 0.1, 0.4)
    assert (table.dcc.unique_identifier, table.dcc.sha256) == ("NMI-VIB-2026-0412", sha256)
    assert table.dcc.laboratory == "National Vibration Laboratory (DKD-K-99001)"
    kept = lab.reference_dcc("REF-8305-SIM")
    assert kept is not None and kept.content == signed.read_bytes()
    assert kept.file_name == "signed.xml"

    out = tmp_path / "runs"
    assert main([*RUN, "--sensor", "SN-7", "--db", url, "--out", str(out)]) == 0
    (folder,) = out.iterdir()
    reference = json.loads((folder / "results.json").read_text())["stand"]["reference"]
    assert reference["dcc_identifier"] == "NMI-VIB-2026-0412"
    assert reference["dcc_sha256"] == sha256
    assert reference["certificate_number"] == "NMI-VIB-2026-0412"
    assert main(["certificate", str(folder), "--db", url, *CERTIFICATE]) == 0
    pdf = folder / "certificate.pdf"
    words = " ".join(" ".join(page.extract_text().split()) for page in PdfReader(pdf).pages)
    assert (
        "Its DCC DCC NMI-VIB-2026-0412 of National Vibration Laboratory (DKD-K-99001) "
        f"SHA-256 {sha256}" in words
    )
    xml = pdf.with_suffix(".xml").read_bytes()
    assert validation_error(xml) is None
    assert b'refType="vib_referenceDcc"' in xml
    assert b"<dcc:value>NMI-VIB-2026-0412</dcc:value>" in xml
    assert f"<dcc:value>{sha256}</dcc:value>".encode() in xml
    # verify reads the certificate as before: every check but the (absent) PAdES signature
    capsys.readouterr()
    main(["verify", str(pdf), "--run", str(folder), "--db", url])
    checks = capsys.readouterr().out.splitlines()
    assert [line for line in checks if line.startswith("FAIL")] == [
        "FAIL signature: the PDF is not signed: nothing proves who issued it",
        "FAIL DCC signature (XAdES, enveloped): the DCC is not signed: nothing proves who "
        "issued it",
    ]
    assert "ok   DCC numbers printed in the PDF" in checks
    assert "ok   embedded DCC valid (DCC 3.3.0)" in checks


def test_a_malformed_dcc_is_refused_naming_the_element_and_nothing_is_added(
    url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _add(url, "bad_missing_u.xml") == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert (
        "dcc:results/dcc:result/dcc:data/dcc:list/dcc:quantity[2]: a sensitivity without its "
        "expanded uncertainty" in err
    )
    assert _add(url, "bad_not_vibration.xml") == 2
    assert "is not a vibration transducer calibration" in capsys.readouterr().err
    assert Lab(open_engine(url)).references() == []


def test_options_that_contradict_the_dcc_are_refused_and_model_names_it(
    url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _add(url, "points_pc_radian.xml", "--serial", "2291018") == 2
    assert "--serial: 2291018 differs from the DCC's 2291017" in capsys.readouterr().err
    assert _add(url, "points_pc_radian.xml", "--calibrated", "2026-03-05") == 2
    assert "--calibrated: 2026-03-05 differs from the DCC's 2026-03-04" in capsys.readouterr().err
    assert _add(url, "points_pc_radian.xml", "--model", "4371 V", "--serial", "2291017") == 0
    said = capsys.readouterr().out
    assert "a charge sensitivity: kept in mV/(m/s^2) at 1 mV/pC" in said
    assert "U stated with k = 2.2: kept as the relative U at k = 2" in said
    (ref,) = Lab(open_engine(url)).references()
    assert (ref.model, ref.serial, ref.certificate_number) == ("4371 V", "2291017", "CAL-2026-77-B")


def test_table_options_stay_required_without_a_dcc(
    url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table = tmp_path / "t.csv"
    table.write_text("160,1.0,0.5\n")
    argv = ["refs", "add", "R", "--table", str(table), "--due", "2099-01-01", "--db", url]
    assert main(argv) == 2
    assert "--model: required with --table" in capsys.readouterr().err
    both = [*argv, "--dcc", str(DATA / "lists_mv_degree.xml")]
    assert main(both) == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_the_dcc_kept_is_written_back_byte_for_byte_and_never_over_a_file(
    url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _add(url, "points_pc_radian.xml", identifier="REF-C") == 0
    out = tmp_path / "back.xml"
    assert main(["refs", "dcc", "REF-C", "--out", str(out), "--db", url]) == 0
    assert out.read_bytes() == (DATA / "points_pc_radian.xml").read_bytes()
    sha256 = hashlib.sha256(out.read_bytes()).hexdigest()
    assert "DCC CAL-2026-77-B of Accredited Vibration Lab Nord" in capsys.readouterr().out
    assert main(["refs", "dcc", "REF-C", "--out", str(out), "--db", url]) == 2
    assert "exists; it is never overwritten" in capsys.readouterr().err
    assert main(["refs", "dcc", "REF-NONE", "--out", str(tmp_path / "x.xml"), "--db", url]) == 2
    assert "reference REF-NONE: no DCC in force" in capsys.readouterr().err
    assert Lab(open_engine(url)).reference_dcc("REF-C").identity.sha256 == sha256  # type: ignore[union-attr]


def test_a_recalibration_from_a_csv_takes_the_dcc_out_of_force(url: str) -> None:
    assert _add(url, "lists_mv_degree.xml") == 0
    lab = Lab(open_engine(url), actor="t")
    lab.update_reference(
        "REF-8305-SIM",
        model="8305",
        serial="SIM-0001",
        certificate_number="PAPER-2027-1",
        calibration_date=date(2027, 3, 1),
        due_date=date(2028, 3, 1),
        table=[(160.0, 1.0, 0.005, None)],
    )
    table = lab.reference_table("REF-8305-SIM", "")
    assert table is not None and table.dcc is None
    assert lab.reference_dcc("REF-8305-SIM") is None
    # a certificate's details change without a new table: the DCC stays in force
    assert _add(url, "hybrid_interval_khz.xml", identifier="REF-B") == 0
    lab.update_reference(
        "REF-B",
        model="KS94B.100",
        serial="58233",
        certificate_number="VL-26-1180",
        calibration_date=date(2026, 3, 4),
        due_date=date(2027, 6, 1),
    )
    kept = lab.reference_table("REF-B", "")
    assert kept is not None and kept.dcc is not None
    assert kept.dcc.unique_identifier == "VL-26-1180"
