"""Opening, creating and migrating the records database on both engines."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import pytest
from sqlalchemy import inspect, text

from app.records.db.engine import (
    SCHEMA_HEAD,
    DatabaseError,
    current_revision,
    head_revision,
    make_engine,
    open_engine,
    resolve_url,
    upgrade,
)
from app.records.db.lab import Lab


def test_urls_resolve_from_option_then_environment_then_the_user_data_dir(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    assert resolve_url() == f"sqlite:///{tmp_path}/data/accelcal/records.sqlite"
    monkeypatch.setenv("ACCELCAL_DB", "postgresql://lab@db.example/records")
    assert resolve_url() == "postgresql+psycopg://lab@db.example/records"
    assert resolve_url("sqlite:///x.sqlite") == "sqlite:///x.sqlite"
    with pytest.raises(DatabaseError, match=r"^--db: unsupported database 'mysql'"):
        resolve_url("mysql://lab@db/records")
    with pytest.raises(DatabaseError, match=r"^--db: not a database URL"):
        resolve_url("records.sqlite")


def test_the_default_sqlite_file_is_created_only_on_request_in_wal_mode(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    with pytest.raises(DatabaseError, match="does not exist; `accelcal db upgrade` creates it"):
        open_engine()  # opening is no first use: nothing created
    assert not (tmp_path / "accelcal").exists()
    engine = open_engine(create=True)  # `accelcal db upgrade`'s request
    assert (tmp_path / "accelcal" / "records.sqlite").is_file()
    assert current_revision(engine) == head_revision(engine) == SCHEMA_HEAD
    with engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA busy_timeout").scalar() == 30000


def test_a_database_named_explicitly_is_never_created_silently(empty_url: str) -> None:
    sqlite = empty_url.startswith("sqlite")
    said = "does not exist; `accelcal db upgrade` creates it" if sqlite else "no accelcal schema"
    with pytest.raises(DatabaseError, match=said):
        open_engine(empty_url)
    if sqlite:  # not even an empty file is left behind
        assert not Path(empty_url.removeprefix("sqlite:///")).exists()
    else:
        with pytest.raises(DatabaseError, match="no accelcal schema; run `accelcal db upgrade`"):
            open_engine(empty_url)


def test_an_older_schema_is_refused_until_upgraded_and_keeps_its_data(empty_url: str) -> None:
    engine = make_engine(resolve_url(empty_url))
    upgrade(engine, "0001")
    Lab(engine, actor="t").add_customer("ACME Ltd")
    with engine.begin() as conn:  # a sensor with two complete runs, written at schema 0001
        for statement in (
            "INSERT INTO sensor_models (id, maker, model, nominal_sensitivity, unit, "
            "tolerance_percent, frequency_min_hz, frequency_max_hz, preset, level_ms2) "
            "VALUES (1, 'PCB', '352C33', 10, 'mV/(m/s^2)', 5, 1, 10000, 'piezo', 5)",
            "INSERT INTO sensors (id, serial, model_id, owner_id, interval_months) "
            "VALUES (1, 'SN-1', 1, 1, 6)",
            "INSERT INTO stands (id, stand_file_sha256, name) VALUES (1, 'ab', 'stand')",
        ):
            conn.execute(text(statement))
        for k, started in enumerate(("2025-08-31 10:00:00+00:00", "2025-03-01 10:00:00+00:00")):
            conn.execute(
                text(
                    "INSERT INTO runs (run_id, manifest_sha256, folder, status, started_utc, "
                    "dut_id, stand_id, sensor_id) VALUES "
                    "(:id, :id, '/r', 'complete', :started, 'SN-1', 1, 1)"
                ),
                {"id": f"r{k}", "started": datetime.fromisoformat(started)},
            )
    with pytest.raises(
        DatabaseError, match=f"schema revision 0001, this program needs {SCHEMA_HEAD}"
    ):
        open_engine(empty_url)
    assert upgrade(engine) == ("0001", SCHEMA_HEAD)
    indexes = {ix["name"] for ix in inspect(engine).get_indexes("runs")}
    assert "ix_runs_sensor_started" in indexes
    reopened = open_engine(empty_url)
    with reopened.connect() as conn:
        assert conn.execute(text("SELECT name FROM customers")).scalars().all() == ["ACME Ltd"]
        due = conn.execute(text("SELECT due_date FROM sensors")).scalar()
    # last complete run 2025-08-31 + 6 months: February has no 31st -> 2026-02-28
    assert str(due) == "2026-02-28"
    assert upgrade(reopened) == (SCHEMA_HEAD, SCHEMA_HEAD)  # a second upgrade changes nothing


def test_an_unreachable_server_is_named(tmp_path: Path) -> None:
    url = f"postgresql://nobody@/records?host={tmp_path}&connect_timeout=2"
    with pytest.raises(DatabaseError, match="cannot connect"):
        open_engine(url)
