"""Issue 24 points 2 and 3 on SQLite and PostgreSQL: the stand's reference standard comes from
the records (refused when not on record; its table is the one the analysis uses; a differing
stand-file table is refused), the table's uncertainty is read in percent, and every override
is in results.json, run.log, the audit trail, the PDF and the DCC."""

from __future__ import annotations

import json
from datetime import UTC, date, datetime
from pathlib import Path

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.cli import main
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.records.db.models import AuditEntry
from app.records.db.reference_table import read_reference_table
from app.records.db.references import ReferenceTable
from app.records.db.store import RecordsError
from tests.lab_stand import lab_stand_file
from tests.records_db import new_records, seed_lab

ARGS = ["--dut", "piezo", "--periods", "3", "--seed", "1", "--fresh-response"]
RUN = ["run", "--sim", *ARGS]
FLAT = [(160.0, 1.0, 0.005, None)]


@pytest.fixture
def url(migrated_url: str, monkeypatch: pytest.MonkeyPatch) -> str:
    """A lab on each engine with customer, model and sensor SN-7; no reference standard."""
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    seed_lab(Lab(open_engine(migrated_url), actor="t"), {"SN-7": "ACME Ltd"})
    return migrated_url


def _add_reference(url: str, table: list, *, due: date = date(2099, 1, 1)) -> None:
    Lab(open_engine(url), actor="t").add_reference(
        "REF-8305-SIM",
        model="8305",
        serial="SIM-0001",
        certificate_number="PTB-2026-17",
        calibration_date=date(2025, 6, 1),
        due_date=due,
        table=table,
    )


def _folder(out: Path) -> Path:
    (folder,) = out.iterdir()
    return folder


def _overrides_in_audit(url: str) -> list[AuditEntry]:
    with Session(open_engine(url)) as s:
        query = select(AuditEntry).where(AuditEntry.action == "override").order_by(AuditEntry.id)
        return list(s.scalars(query).all())


# ---- point 2: the reference standard must be on record ----------------------------------


def test_a_reference_not_on_record_refuses_the_run_naming_it_unless_overridden(
    url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """On a stand whose reference is a lab's (its table in the stand file); the simulator's
    own reference is exempt (tests/app/test_first_use.py)."""
    out = tmp_path / "runs"
    lab = ["run", "--stand", str(lab_stand_file(tmp_path)), *ARGS]  # RUN on that stand
    assert main([*lab, "--db", url, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "reference standard REF-8305-SIM (serial SIM-0001)" in err
    assert "is not in the records" in err and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())  # nothing moved, nothing written
    assert _overrides_in_audit(url) == []

    why = "bought last week, entry pending"
    assert main([*lab, "--db", url, "--out", str(out), "--reference-override", why]) == 0
    folder = _folder(out)
    record = json.loads((folder / "results.json").read_text())
    (override,) = record["overrides"]
    assert override["kind"] == "unrecorded reference" and override["why"] == why
    assert "REF-8305-SIM (serial SIM-0001)" in override["what"]
    assert f"reason: {why}" in (folder / "run.log").read_text()
    # granted, keyed by the reference standard; again with the run id when it was indexed
    granted, indexed = _overrides_in_audit(url)
    assert json.loads(granted.changes)["why"] == why
    assert granted.row_key == "REF-8305-SIM" and granted.table_name == "reference_standards"
    assert json.loads(indexed.changes) == override
    assert (indexed.table_name, indexed.row_key) == ("runs", folder.name)


def test_a_reference_on_record_by_serial_is_found_and_needs_no_override(
    url: str, tmp_path: Path
) -> None:
    """The stand file names REF-8305-SIM, serial SIM-0001; the records know it by its serial
    under another id: it is the same reference standard."""
    from app.procedure.request import DutChoice, build_request

    Lab(open_engine(url), actor="t").add_reference(
        "B&K-8305-0001",
        model="8305",
        serial="SIM-0001",
        certificate_number="PTB-2026-17",
        calibration_date=date(2025, 6, 1),
        due_date=date(2099, 1, 1),
        table=FLAT,
    )
    request, notes = build_request(DutChoice(db=url, records=True), out=tmp_path)
    assert request.reference is not None and request.reference.identifier == "B&K-8305-0001"
    assert request.overrides == ()
    assert any("certificate PTB-2026-17, due 2099-01-01" in n for n in notes)


def test_the_records_table_is_the_one_the_run_uses(url: str, tmp_path: Path) -> None:
    """Two records tables, equal but for 1000 Hz where the second is 1.25 times the first:
    the sensitivity at 1000 Hz is the DUT/reference ratio times the reference's sensitivity
    there, so it is 1.25 times larger (by hand: S_dut = S_ref * V_dut / V_ref); 800 Hz and
    1250 Hz are table points themselves, so every other line stays. The drive is equalised
    on the reference's reading, so the second run's noise is not the first's: 5e-5 relative
    (the lines' type A is about 1e-3)."""
    from app.stand import config as stand_config
    from app.stand.open import open_stand

    chain = open_stand(stand_config.load(None), dut="piezo", seed=1).chain  # the sim's own
    rows = list(
        zip(
            chain.frequencies_hz,
            chain.sensitivity_mv_per_ms2,
            [0.005] * len(chain.frequencies_hz),
            chain.phase_deg,
            strict=True,
        )
    )
    factor = 1.25
    changed = [(f, s * factor if f == 1000.0 else s, u, p) for f, s, u, p in rows]
    second = tmp_path / "second.sqlite"
    second_url = new_records(second)
    sensitivities = []
    for db, table, out in ((url, rows, "a"), (second_url, changed, "b")):
        _add_reference(db, table)
        assert main([*RUN, "--db", db, "--out", str(tmp_path / out)]) == 0
        record = json.loads((_folder(tmp_path / out) / "results.json").read_text())
        assert record["stand"]["reference"]["table_from"] == "records"
        assert record["stand"]["reference"]["certificate_number"] == "PTB-2026-17"
        lines = record["results"]["lines"]
        sensitivities.append({ln["frequency_hz"]: ln["sensitivity_mv_per_ms2"] for ln in lines})
    first, then = sensitivities
    assert then[1000.0] / first[1000.0] == pytest.approx(factor, rel=5e-5)
    for frequency in first:
        if frequency != 1000.0:
            assert then[frequency] / first[frequency] == pytest.approx(1.0, rel=5e-5)
    # the records' table equal to the simulator's own certificate: the very run without records
    assert main([*RUN, "--out", str(tmp_path / "none")]) == 0
    record = json.loads((_folder(tmp_path / "none") / "results.json").read_text())
    assert {
        ln["frequency_hz"]: ln["sensitivity_mv_per_ms2"] for ln in record["results"]["lines"]
    } == first


def test_a_stand_file_table_that_differs_from_the_records_is_refused_naming_both(
    url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from importlib import resources

    from app.procedure.request import DutChoice, build_request

    _add_reference(url, [(160.0, 1.0, 0.005, 0.25), (1000.0, 1.01, 0.005, 0.5)])
    text = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
    same, other = tmp_path / "same.toml", tmp_path / "other.toml"
    table = "gain = 10.0\nfrequencies_hz = [160.0, 1000.0]\nphase_deg = [0.25, 0.5]\n"
    same.write_text(text.replace("gain = 10.0\n", table + "sensitivity_mv_per_ms2 = [1.0, 1.01]\n"))
    other.write_text(
        text.replace("gain = 10.0\n", table + "sensitivity_mv_per_ms2 = [1.0, 1.02]\n")
    )
    request, _ = build_request(DutChoice(stand_file=same, db=url, records=True), out=tmp_path)
    assert request.reference is not None
    from app.procedure.run import with_reference
    from app.stand import config as stand_config

    config = with_reference(stand_config.load(same), request.reference)
    assert config.reference.sensitivity_mv_per_ms2 == (1.0, 1.01)
    out = tmp_path / "runs"
    assert main(["run", *ARGS, "--stand", str(other), "--db", url, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"the [reference] table of {other} differs from the records' table of " in err
    assert "REF-8305-SIM (certificate PTB-2026-17)" in err
    assert not out.exists() or not any(out.iterdir())
    # an override reason does not make two sources of one reference right
    argv = ["run", *ARGS, "--stand", str(other), "--db", url, "--reference-override", "x"]
    assert main([*argv, "--out", str(out)]) == 2


# ---- point 3: the override everywhere -----------------------------------------------------


def test_an_expired_reference_override_is_in_results_audit_pdf_and_dcc(
    url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pypdf import PdfReader

    from app.certificate.dcc import validation_error

    _add_reference(url, FLAT, due=date(2026, 6, 1))
    out = tmp_path / "runs"
    base = [*RUN, "--sensor", "SN-7", "--db", url, "--out", str(out)]
    assert main(base) == 2
    err = capsys.readouterr().err
    assert "reference: REF-8305-SIM was due for calibration on 2026-06-01" in err
    why = "new cert in transit"
    before = datetime.now(UTC).replace(microsecond=0)
    assert main([*base, "--reference-override", why]) == 0
    folder = _folder(out)
    record = json.loads((folder / "results.json").read_text())
    (override,) = record["overrides"]
    assert override["kind"] == "expired reference" and override["why"] == why
    assert (
        override["what"] == "reference standard REF-8305-SIM was due for calibration on 2026-06-01"
    )
    assert datetime.fromisoformat(override["when_utc"]) >= before
    assert override["who"]  # the operating-system user
    assert why in (folder / "run.log").read_text()
    granted, indexed = _overrides_in_audit(url)
    for entry in (granted, indexed):
        assert json.loads(entry.changes) == override and entry.actor == override["who"]
    assert [e.table_name for e in (granted, indexed)] == ["reference_standards", "runs"]

    assert (
        main(
            [
                "certificate",
                str(folder),
                "--db",
                url,
                "--temperature",
                "23",
                "--mounting",
                "stud",
                "--prepared-by",
                "A. Tech",
                "--authorised-by",
                "J. Smith",
            ]
        )
        == 0
    )
    pdf = folder / "certificate.pdf"
    words = " ".join(" ".join(page.extract_text().split()) for page in PdfReader(pdf).pages)
    assert "Overrides" in words and f"Reason: {why}" in words
    assert "expired reference" in words and "PTB-2026-17" in words
    xml = pdf.with_suffix(".xml").read_bytes()
    assert validation_error(xml) is None
    assert b"Override: expired reference" in xml and why.encode() in xml


def test_a_run_without_override_states_none(url: str, tmp_path: Path) -> None:
    """No override: no "overrides" key (results.json as older accelcal wrote it) and no
    audit entry."""
    _add_reference(url, FLAT)
    out = tmp_path / "runs"
    assert main([*RUN, "--db", url, "--out", str(out), "--reference-override", "unused"]) == 0
    record = json.loads((_folder(out) / "results.json").read_text())
    assert "overrides" not in record
    assert _overrides_in_audit(url) == []


# ---- the calibration table's uncertainty in percent --------------------------------------


def test_the_table_uncertainty_is_read_in_percent_and_a_fraction_header_is_refused(
    url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table = tmp_path / "ref.csv"
    table.write_text(
        "frequency_hz,sensitivity_mv_per_ms2,relative_expanded_uncertainty_percent,phase_deg\n"
        "160,0.125,0.5,0.25\n1000,0.126,1.2,0.5\n"
    )
    argv = [
        "refs",
        "add",
        "REF-1",
        "--model",
        "8305",
        "--serial",
        "1",
        "--certificate",
        "PTB-9",
        "--calibrated",
        "2026-01-10",
        "--due",
        "2027-01-10",
        "--db",
        url,
        "--table",
    ]
    assert main([*argv, str(table)]) == 0
    (ref,) = Lab(open_engine(url)).references()
    stored = ReferenceTable.of(ref)
    assert stored.relative_expanded_uncertainty == (0.005, 0.012)  # 0.5 % and 1.2 %
    assert stored.phase_deg == (0.25, 0.5)

    fraction = tmp_path / "fraction.csv"
    fraction.write_text(
        "frequency_hz,sensitivity_mv_per_ms2,relative_expanded_uncertainty\n160,0.125,0.005\n"
    )
    assert main([*argv[:2], "REF-2", *argv[3:], str(fraction)]) == 2
    err = capsys.readouterr().err
    assert "column 'relative_expanded_uncertainty' does not say its unit" in err
    assert "in percent (0.5 means 0.5 %)" in err
    assert main(["refs", "add", "--help"]) == 0
    assert "percent (0.5 means 0.5 %)" in " ".join(capsys.readouterr().out.split())


def test_read_reference_table_rows_and_refusals(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text("# a comment\n10,1.0,0.5\n\n20,1.1,2,1.5\n")  # no header: percent
    assert read_reference_table(path) == [(10.0, 1.0, 0.005, None), (20.0, 1.1, 0.02, 1.5)]
    path.write_text("frequency_hz,sensitivity,u_%\n10,1.0,0.5\n")
    with pytest.raises(RecordsError, match="column 2 is 'sensitivity', expected"):
        read_reference_table(path)
    path.write_text("freq,s,u %\n10,1.0,0.5\n")
    with pytest.raises(RecordsError, match="column 1 is 'freq'"):
        read_reference_table(path)
    path.write_text("10,1.0\n")
    with pytest.raises(RecordsError, match="line 1: expected 3 or 4 columns"):
        read_reference_table(path)
    with pytest.raises(RecordsError, match="--table: no such file"):
        read_reference_table(tmp_path / "missing.csv")


def test_a_table_with_a_phase_on_some_rows_only_is_refused_by_the_run(
    url: str, tmp_path: Path
) -> None:
    from app.procedure.request import DutChoice, ReferenceRefusal, build_request

    _add_reference(url, [(160.0, 1.0, 0.005, 0.3), (1000.0, 1.0, 0.005, None)])
    with pytest.raises(ReferenceRefusal, match="REF-8305-SIM states a phase on some rows only"):
        build_request(DutChoice(db=url, records=True), out=tmp_path)
