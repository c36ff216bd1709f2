"""`--json` on every list command (issue 31 point 3): a JSON array of objects with stable keys
(every row the same keys), dates ISO 8601, numbers as numbers; the output parsed as a script
would parse it, on an SQLite records file."""

from __future__ import annotations

import argparse
import json
import shutil
from datetime import UTC, date, datetime, timedelta
from pathlib import Path

import pytest

from app.cli import build_parser, main
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.web.users import add_user

pytestmark = pytest.mark.integration  # a records database per test (make test-fast: not)

TODAY = datetime.now(UTC).date()


@pytest.fixture
def db(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    url = f"sqlite:///{tmp_path / 'lab.sqlite'}"
    monkeypatch.setenv("ACCELCAL_DB", url)
    assert main(["db", "upgrade"]) == 0
    return url


@pytest.fixture
def lab(db: str) -> Lab:
    """Two customers, two models (one with its phase tolerance), three sensors, a reference
    standard due in 10 days."""
    lab = Lab(open_engine(db), actor="qm")
    lab.add_customer("ACME Ltd", "1 Road, Town")
    lab.add_customer("Bäcker GmbH")  # non-ASCII kept as it is
    lab.add_model(
        "PCB", "352C33", nominal_sensitivity=100.0, unit="mV/g", tolerance_percent=5,
        frequency_min_hz=1, frequency_max_hz=10000, level_ms2=8.0, phase_tolerance_deg=3.0,
    )  # fmt: skip
    lab.add_model(
        "B&K", "4533-B", nominal_sensitivity=10.2, unit="mV/(m/s^2)", tolerance_percent=2.5,
        frequency_min_hz=0.5, frequency_max_hz=12800,
    )  # fmt: skip
    lab.add_sensor("SN-7", model="352C33", owner="ACME Ltd")
    lab.add_sensor("SN-8", model="4533-B", owner="Bäcker GmbH", interval_months=24)
    lab.add_sensor("CS-1", model="4533-B", owner="ACME Ltd", check_standard=True)
    lab.add_reference(
        "REF-1", model="8305", serial="123", certificate_number="PTB-1",
        calibration_date=TODAY - timedelta(days=355), due_date=TODAY + timedelta(days=10),
        table=[(160.0, 0.125, 0.005, None), (1000.0, 0.126, 0.006, 0.5)],
    )  # fmt: skip
    return lab


def _json(argv: list[str], capsys: pytest.CaptureFixture[str]) -> object:
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def _rows(argv: list[str], capsys: pytest.CaptureFixture[str], keys: set[str]) -> list[dict]:
    rows = _json([*argv, "--json"], capsys)
    assert isinstance(rows, list)
    for row in rows:
        assert isinstance(row, dict) and set(row) == keys, row
    return rows


def test_customers_list(lab, capsys):
    rows = _rows(["customers", "list"], capsys, {"name", "address"})
    assert rows == [
        {"name": "ACME Ltd", "address": "1 Road, Town"},
        {"name": "Bäcker GmbH", "address": ""},
    ]


def test_models_list_numbers_are_numbers(lab, capsys):
    keys = {
        "maker", "model", "nominal_sensitivity", "unit", "tolerance_percent", "frequency_min_hz",
        "frequency_max_hz", "preset", "level_ms2", "phase_tolerance_deg",
    }  # fmt: skip
    rows = _rows(["models", "list"], capsys, keys)
    by_model = {r["model"]: r for r in rows}
    pcb = by_model["352C33"]
    assert pcb["nominal_sensitivity"] == 100.0 and pcb["unit"] == "mV/g"
    assert pcb["tolerance_percent"] == 5.0 and pcb["level_ms2"] == 8.0
    assert pcb["phase_tolerance_deg"] == 3.0 and pcb["frequency_max_hz"] == 10000.0
    assert by_model["4533-B"]["phase_tolerance_deg"] is None
    assert by_model["4533-B"]["frequency_min_hz"] == 0.5


def test_sensors_list_with_its_search(lab, capsys):
    keys = {
        "serial", "maker", "model", "owner", "interval_months", "teds_identity",
        "check_standard", "last_calibrated_utc", "due_date",
    }  # fmt: skip
    rows = _rows(["sensors", "list"], capsys, keys)
    assert [r["serial"] for r in rows] == ["CS-1", "SN-7", "SN-8"]
    sn8 = rows[2]
    assert sn8["owner"] == "Bäcker GmbH" and sn8["interval_months"] == 24
    assert sn8["check_standard"] is False and rows[0]["check_standard"] is True
    assert sn8["last_calibrated_utc"] is None and sn8["due_date"] is None
    assert [r["serial"] for r in _rows(["sensors", "list", "--search", "SN-"], capsys, keys)] == [
        "SN-7",
        "SN-8",
    ]


def test_refs_list_dates_are_iso_8601(lab, capsys):
    keys = {
        "identifier", "model", "serial", "certificate_number", "calibration_date", "due_date",
        "table_rows",
    }  # fmt: skip
    (ref,) = _rows(["refs", "list"], capsys, keys)
    assert ref["identifier"] == "REF-1" and ref["table_rows"] == 2
    assert date.fromisoformat(ref["due_date"]) == TODAY + timedelta(days=10)
    assert date.fromisoformat(ref["calibration_date"]) == TODAY - timedelta(days=355)


def test_due_lists_never_calibrated_sensors_and_the_reference(lab, capsys):
    keys = {"kind", "identifier", "owner", "due_date", "overdue"}
    rows = _rows(["due", "--days", "30"], capsys, keys)
    by_id = {r["identifier"]: r for r in rows}
    assert by_id["REF-1"]["due_date"] == (TODAY + timedelta(days=10)).isoformat()
    assert by_id["REF-1"]["overdue"] is False
    assert by_id["SN-7"]["due_date"] is None and by_id["SN-7"]["overdue"] is False
    assert "REF-1" not in {r["identifier"] for r in _rows(["due", "--days", "5"], capsys, keys)}


def test_an_empty_list_is_an_empty_array(db, capsys):
    for argv in (["customers", "list"], ["register", "list"], ["register", "reviews"]):
        assert _json([*argv, "--json"], capsys) == []
    assert _json(["records", "user", "list", "--json"], capsys) == []


def test_users_list_never_shows_the_password_hash(db, capsys):
    add_user(open_engine(db), "alice", "a long password 1", display_name="Alice A.")
    (user,) = _rows(
        ["records", "user", "list"], capsys, {"username", "display_name", "active", "created_utc"}
    )
    assert user["username"] == "alice" and user["display_name"] == "Alice A."
    assert user["active"] is True
    created = datetime.fromisoformat(user["created_utc"])
    assert created.utcoffset() == timedelta(0)
    assert abs(datetime.now(UTC) - created) < timedelta(minutes=5)
    capsys.readouterr()
    assert main(["records", "user", "list"]) == 0
    out = capsys.readouterr().out
    assert "alice\tAlice A.\tactive" in out and "argon2" not in out


@pytest.fixture
def issued(lab: Lab, complete_run: Path, tmp_path: Path) -> tuple[Lab, str]:
    """The session's complete run (sensor SN-42) indexed, its certificate issued and under
    review."""
    lab.add_sensor("SN-42", model="352C33", owner="ACME Ltd")
    copy = tmp_path / "runs" / complete_run.name
    shutil.copytree(complete_run, copy)
    assert lab.import_runs(copy).imported
    number = lab.issue_certificate(
        run_id=complete_run.name, prepared_by="P. Rep", approved_by="A. Pro"
    ).number
    assert lab.open_review(number, subject="impact of REF-1", reason="REF-1 recalibrated")
    return lab, number


def test_register_list_and_reviews(issued, complete_run, capsys):
    _, number = issued
    keys = {
        "number", "state", "reason", "issued_utc", "run_id", "sensor_serial", "prepared_by",
        "approved_by", "replaces", "as_found_run_id", "under_review",
    }  # fmt: skip
    (row,) = _rows(["register", "list"], capsys, keys)
    assert row["number"] == number and row["state"] == "issued"
    assert row["run_id"] == complete_run.name and row["sensor_serial"] == "SN-42"
    assert row["under_review"] == "impact of REF-1" and row["replaces"] is None
    assert datetime.fromisoformat(row["issued_utc"]).utcoffset() == timedelta(0)
    review_keys = {"number", "subject", "reason", "opened_utc"}
    (review,) = _rows(["register", "reviews"], capsys, review_keys)
    assert review == {
        "number": number,
        "subject": "impact of REF-1",
        "reason": "REF-1 recalibrated",
        "opened_utc": review["opened_utc"],
    }
    assert datetime.fromisoformat(review["opened_utc"]).utcoffset() == timedelta(0)


def test_history_is_one_object(issued, complete_run, capsys):
    history = _json(["history", "SN-42", "--json"], capsys)
    assert isinstance(history, dict)
    assert set(history) == {"serial", "points", "drift_percent_per_year"}
    assert history["serial"] == "SN-42" and history["drift_percent_per_year"] is None
    (point,) = history["points"]
    assert point["run_id"] == complete_run.name
    assert isinstance(point["sensitivity_mv_per_ms2"], float)
    assert point["reference_frequency_hz"] > 0
    datetime.fromisoformat(point["started_utc"])


def test_control_is_an_array_of_charts(issued, complete_run, capsys):
    lab, _ = issued
    lab.add_sensor("CS-9", model="352C33", owner="ACME Ltd", check_standard=True)
    assert _json(["control", "CS-9", "--json"], capsys) == []  # no runs of it on record
    keys = {
        "serial", "stand", "centre_mv_per_ms2", "lower_mv_per_ms2", "upper_mv_per_ms2",
        "warning", "points",
    }  # fmt: skip
    (chart,) = _rows(["control", "SN-42"], capsys, keys)
    assert chart["serial"] == "SN-42" and chart["centre_mv_per_ms2"] is None  # < 5 runs
    (point,) = chart["points"]
    assert point["run_id"] == complete_run.name
    assert isinstance(point["sensitivity_mv_per_ms2"], float)


def _list_commands(parser: argparse.ArgumentParser, name: str = ""):
    """Every command whose name says it lists (list, reviews, due, history, control)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for command, sub in action.choices.items():
                yield from _list_commands(sub, f"{name} {command}".strip())
    last = name.split()[-1] if name else ""
    if last in {"list", "reviews", "due", "history", "control"}:
        yield name, parser


def test_every_list_command_has_json():
    found = dict(_list_commands(build_parser()))
    assert {
        "customers list", "models list", "sensors list", "refs list", "due", "history",
        "register list", "register reviews", "records user list", "control",
    } <= set(found)  # fmt: skip
    for name, parser in found.items():
        assert any("--json" in a.option_strings for a in parser._actions), name
