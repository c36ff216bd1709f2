"""`accelcal run` with the records: the DUT from its sensor record, the reference standard's
due date, the finished run indexed, and an unreachable database losing nothing."""

from __future__ import annotations

import json
from datetime import date
from pathlib import Path

import pytest
from sqlalchemy import select

from app.cli import main
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.records.db.models import AuditEntry
from app.records.run_folder import inspect_run
from tests.records_db import add_staff, new_records

RUN = ["run", "--sim", "--dut", "piezo", "--periods", "3", "--seed", "1"]


def add_sim_reference(url: str, due: date) -> None:
    """The simulated stand's reference standard (REF-8305-SIM, serial SIM-0001) on record,
    due on `due`, with a flat table (the runs here only need it on record)."""
    Lab(open_engine(url), actor="t").add_reference(
        "REF-8305-SIM",
        model="8305",
        serial="SIM-0001",
        certificate_number="SIM-CAL-2026-001",
        calibration_date=date(2025, 6, 1),
        due_date=due,
        table=[(160.0, 1.0, 0.005, None)],
    )


@pytest.fixture
def lab_url(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """A lab whose reference standard is on record and in date (issue 24: with records in
    use, the stand's reference standard must be on record)."""
    url = new_lab(tmp_path / "lab.sqlite", monkeypatch)
    add_sim_reference(url, date(2099, 1, 1))
    return url


def new_lab(path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """A lab with customer ACME Ltd, model 4533-B and sensor SN-7; no reference standard."""
    url = new_records(path)
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    lab = Lab(open_engine(url), actor="t")
    lab.add_customer("ACME Ltd", "1 Test Street")
    lab.add_model(
        "Brüel & Kjær",
        "4533-B",
        nominal_sensitivity=100.0,
        unit="mV/g",
        tolerance_percent=3,
        frequency_min_hz=1,
        frequency_max_hz=10000,
        level_ms2=4.0,
    )
    lab.add_sensor("SN-7", model="4533-B", owner="ACME Ltd")
    return url


def _record(out: Path) -> dict:
    (folder,) = out.iterdir()
    return json.loads((folder / "results.json").read_text())


def test_run_takes_the_dut_from_its_sensor_record_and_is_indexed(
    lab_url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "runs"
    assert main([*RUN, "--sensor", "SN-7", "--db", lab_url, "--out", str(out), "--json"]) == 0
    err = capsys.readouterr().err
    assert "sensor SN-7: Brüel & Kjær 4533-B, owner ACME Ltd" in err
    assert "records: run indexed" in err
    assert "reference standard REF-8305-SIM: certificate SIM-CAL-2026-001, due 2099-01-01" in err
    record = _record(out)
    assert record["dut"]["id"] == "SN-7"
    # 100 mV/g = 100 / 9.80665 mV/(m/s^2) = 10.19716 by hand
    assert record["dut"]["nominal_sensitivity_mv_per_ms2"] == pytest.approx(10.197162, rel=1e-6)
    assert record["level_ms2"] == 4.0
    assert record["settings"]["tolerance_percent"] == 3
    history = Lab(open_engine(lab_url)).history("SN-7")
    assert [p.run_id for p in history.points] == [record["run_id"]]


def test_an_unknown_sensor_is_refused_before_anything_moves(
    lab_url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "runs"
    assert main([*RUN, "--sensor", "SN-0", "--db", lab_url, "--out", str(out)]) == 2
    assert "--sensor: serial: no sensor 'SN-0'" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())


def test_an_expired_reference_standard_is_refused_unless_overridden(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    lab_url = new_lab(tmp_path / "expired.sqlite", monkeypatch)
    add_sim_reference(lab_url, date(2026, 6, 1))
    out = tmp_path / "runs"
    assert main([*RUN, "--db", lab_url, "--out", str(out)]) == 2
    assert "REF-8305-SIM was due for calibration on 2026-06-01" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())
    argv = [*RUN, "--db", lab_url, "--out", str(out), "--reference-override", "PTB slot in May"]
    assert main(argv) == 0
    assert "used under the override: PTB slot in May" in capsys.readouterr().err
    (folder,) = out.iterdir()
    with Lab(open_engine(lab_url)).session() as s:
        trail = s.scalars(
            select(AuditEntry).where(AuditEntry.action == "override").order_by(AuditEntry.id)
        ).all()
        # granted (keyed by the reference standard), then with the run when it was indexed
        assert [(e.table_name, e.row_key) for e in trail] == [
            ("reference_standards", "REF-8305-SIM"),
            ("runs", folder.name),
        ]
        assert all(json.loads(e.changes)["why"] == "PTB slot in May" for e in trail)


def test_an_unreachable_database_loses_nothing_and_the_next_import_indexes_the_run(
    lab_url: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    out = tmp_path / "runs"
    down = f"postgresql://nobody@/records?host={tmp_path}&connect_timeout=2"
    monkeypatch.setenv("ACCELCAL_DB", down)
    assert main([*RUN, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "records not reachable, reference due date not checked" in err
    assert "but was not indexed" in err and "accelcal db import" in err
    (folder,) = out.iterdir()
    assert inspect_run(folder).state == "complete"
    assert main(["db", "import", str(out), "--db", lab_url]) == 0
    assert "1 imported" in capsys.readouterr().out


def test_a_certificate_through_the_records_takes_customer_sensor_and_number_from_them(
    lab_url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pypdf import PdfReader

    out = tmp_path / "runs"
    assert main([*RUN, "--sensor", "SN-7", "--db", lab_url, "--out", str(out)]) == 0
    (folder,) = out.iterdir()
    base = [
        "certificate",
        str(folder),
        "--db",
        lab_url,
        "--temperature",
        "23",
        "--mounting",
        "stud",
        "--prepared-by",
        "A. Tech",
        "--authorised-by",
        "J. Smith",
    ]
    assert main([*base, "--certificate-number", "X-1"]) == 2
    assert "--certificate-number: the records' register numbers" in capsys.readouterr().err
    add_staff(lab_url, ("atech", "A. Tech"), ("jsmith", "J. Smith"))  # persons on record
    Lab(open_engine(lab_url)).set_setting("two_person_rule", "on")
    assert main([*base, "--prepared-by", "j. smith"]) == 2
    assert "two-person rule" in capsys.readouterr().err
    assert not (folder / "certificate.pdf").exists()  # refused: nothing written, no number
    assert main([*base, "--prepared-by", "A. Tech"]) == 0
    year = date.today().year
    assert f"certificate ACC-{year}-0001" in capsys.readouterr().out
    text = " ".join(page.extract_text() for page in PdfReader(folder / "certificate.pdf").pages)
    assert "ACME Ltd" in text and "Brüel & Kjær 4533-B" in text and "SN-7" in text
    amended = tmp_path / "amended.pdf"
    assert (
        main(
            [
                *base,
                "--prepared-by",
                "A. Tech",
                "--out",
                str(amended),
                "--replaces",
                f"ACC-{year}-0001",
                "--reason",
                "address corrected",
            ]
        )
        == 0
    )
    assert f"certificate ACC-{year}-0002" in capsys.readouterr().out
    register = Lab(open_engine(lab_url)).register()
    assert [(c.number, c.state, c.replaces) for c in register] == [
        (f"ACC-{year}-0001", "replaced", None),
        (f"ACC-{year}-0002", "issued", f"ACC-{year}-0001"),
    ]


def test_run_teds_identifies_the_dut_in_the_records(
    lab_url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from app.stand.teds import open_port
    from hardware.teds import decode

    identity = decode(open_port(None, "piezo", seed=1).read()).basic.identity
    lab = Lab(open_engine(lab_url), actor="t")
    lab.add_sensor("SN-TEDS", model="4533-B", owner="ACME Ltd", teds_identity=identity)
    out = tmp_path / "runs"
    assert main([*RUN, "--teds", "--db", lab_url, "--out", str(out), "--json"]) == 0
    assert f"TEDS identity {identity}" in capsys.readouterr().err
    assert _record(out)["dut"]["id"] == "SN-TEDS"
    assert main([*RUN, "--teds", "--out", str(tmp_path / "no-db"), "--json"]) == 0
    record = _record(tmp_path / "no-db")
    assert record["dut"]["id"] == f"TEDS-{identity.replace('/', '-')}"
    assert record["dut"]["nominal_sensitivity_mv_per_ms2"] == pytest.approx(10.2, rel=2e-4)
