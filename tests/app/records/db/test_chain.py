"""The records' hash chain on SQLite and PostgreSQL: every direct SQL edit (UPDATE, DELETE, DROP
TRIGGER + edit + CREATE TRIGGER, back-dated INSERT, an edited audit trail or chain) is named by
`db verify` (table and key, exit 2) and stops the next certificate (quick check); a chain
rewritten consistently is caught by the head a run's seal names; the PostgreSQL application
role of docs/records.md cannot disable triggers."""

from __future__ import annotations

import hashlib
import itertools
import json
import re
from collections.abc import Callable
from datetime import UTC, date, datetime
from pathlib import Path

import pytest
from sqlalchemy import Engine, select, text
from sqlalchemy.orm import Session

from app.cli import main
from app.records.db import chain
from app.records.db.chain_check import ChainBroken, after_migration, quick_check, verify
from app.records.db.engine import make_engine, resolve_url, upgrade
from app.records.db.lab import Lab
from app.records.db.models import Run, Sensor, Stand
from app.records.seal import write_seal
from tests.app.records.db.test_run_records import add_sim_reference
from tests.records_db import postgres_database, seed_lab


def _sealed_folder(folder: Path, head: str | None) -> str:
    """A minimal sealed run folder (manifest, results, seal naming `head`); the manifest's
    SHA-256."""
    folder.mkdir()
    (folder / "results.json").write_text('{"run_id": "r1"}', encoding="utf-8")
    (folder / "manifest.json").write_text(json.dumps({"folder": str(folder)}), encoding="utf-8")
    write_seal(folder, "r1", "test", records_chain_head=head)
    return hashlib.sha256((folder / "manifest.json").read_bytes()).hexdigest()


def _lab_day(engine: Engine, runs: Path, *, seal_head: str | None = "chain") -> Lab:
    """A customer, model, sensor, reference, a run indexed from a sealed folder (whose seal
    names the chain head, unless `seal_head` says otherwise) and its certificate."""
    lab = seed_lab(
        Lab(engine, actor="alice"), {"SN-1": "ACME Ltd"}, addresses={"ACME Ltd": "1 Road"}
    )
    lab.add_reference(
        "REF-1",
        model="8305",
        serial="R1",
        certificate_number="PTB-1",
        calibration_date=date(2026, 1, 1),
        due_date=date(2027, 1, 1),
        table=[(160.0, 0.125, 0.005, None)],
    )
    with engine.connect() as c:
        head = chain.head_hash(c) if seal_head == "chain" else seal_head
    manifest = _sealed_folder(runs / "r1", head)
    with Session(engine) as s:
        s.add(
            Run(
                run_id="r1",
                manifest_sha256=manifest,
                folder=str(runs / "r1"),
                status="complete",
                started_utc=datetime(2026, 11, 23, tzinfo=UTC),
                dut_id="SN-1",
                stand=Stand(stand_file_sha256="b" * 64, name="stand"),
                sensor=s.scalar(select(Sensor)),
                sensitivity_mv_per_ms2=10.31,
            )
        )
        s.commit()
    lab.issue_certificate(run_id="r1", prepared_by="alice", approved_by="Bob QM")
    return lab


def _id(engine: Engine, query: str) -> str:
    with engine.connect() as c:
        return str(c.execute(text(query)).scalar())


def _sql(engine: Engine, *statements: str) -> None:
    with engine.begin() as c:
        for statement in statements:
            c.execute(text(statement))


def _without_triggers(engine: Engine, table: str, *edits: str) -> None:
    """Drop `table`'s triggers, make the edits, recreate the triggers exactly as they were."""
    with engine.begin() as c:
        if c.dialect.name == "sqlite":
            rows = c.execute(
                text("SELECT name, sql FROM sqlite_master WHERE type='trigger' AND tbl_name=:t"),
                {"t": table},
            ).all()
            for name, _ in rows:
                c.execute(text(f"DROP TRIGGER {name}"))
            for edit in edits:
                c.execute(text(edit))
            for _, sql in rows:
                c.execute(text(sql))
        else:
            rows = c.execute(
                text(
                    "SELECT tgname, pg_get_triggerdef(oid), tgenabled::text FROM pg_trigger "
                    "WHERE tgrelid = CAST(:t AS regclass) AND NOT tgisinternal"
                ),
                {"t": table},
            ).all()
            for name, _, _ in rows:
                c.execute(text(f"DROP TRIGGER {name} ON {table}"))
            for edit in edits:
                c.execute(text(edit))
            for name, definition, enabled in rows:
                c.execute(text(definition))
                if enabled == "A":
                    c.execute(text(f"ALTER TABLE {table} ENABLE ALWAYS TRIGGER {name}"))


def test_a_lab_day_verifies_and_each_write_is_one_linked_entry(
    engine: Engine, tmp_path: Path
) -> None:
    _lab_day(engine, tmp_path)
    assert verify(engine) == []
    with engine.connect() as c:
        entries = chain.read_entries(c)
        sensor_id = c.execute(text("SELECT id FROM sensors")).scalar()
        journal = c.execute(text("SELECT count(*) FROM records_journal")).scalar()
    assert quick_check(engine) == entries[-1].hash
    assert [e.seq for e in entries] == list(range(1, len(entries) + 1))
    assert entries[0].prev_hash == chain.GENESIS
    assert all(a.hash == b.prev_hash for a, b in itertools.pairwise(entries))
    # every journal row (trigger) is claimed by exactly one entry, and only the first entry
    # (the migration's schema entry) and none else claims none
    assert sorted(e.journal_id for e in entries if e.journal_id) == list(range(1, journal + 1))
    # the sensor's entry holds its full content, hashed as sha256(prev || canonical entry)
    sensor = next(e for e in entries if e.table_name == "sensors" and e.action == "insert")
    assert sensor.row_key == str(sensor_id)
    assert json.loads(sensor.row or "")["serial"] == "SN-1"
    fields = {
        "seq": sensor.seq,
        "at_utc": sensor.at_utc,
        "actor": "alice",
        "action": "insert",
        "table_name": "sensors",
        "row_key": sensor.row_key,
        "row": sensor.row,
        "journal_id": sensor.journal_id,
        "schema_fingerprint": sensor.schema_fingerprint,
    }
    by_hand = json.dumps(fields, sort_keys=True, separators=(",", ":"))
    assert sensor.hash == hashlib.sha256((sensor.prev_hash + by_hand).encode()).hexdigest()


def _update_certificate(engine: Engine) -> str:
    """The rules' trigger refuses the edit itself (test_records_attacks); with every trigger of
    the table dropped and put back, the edit is named."""
    key = _id(engine, "SELECT id FROM certificates")
    _without_triggers(engine, "certificates", "UPDATE certificates SET approved_by = 'Mallory'")
    return f"certificates {key}: changed outside the application (approved_by)"


def _update_run(engine: Engine) -> str:
    key = _id(engine, "SELECT id FROM runs")
    _sql(engine, "UPDATE runs SET sensitivity_mv_per_ms2 = 10.2")
    return f"runs {key}: "


def _update_due_date(engine: Engine) -> str:
    key = _id(engine, "SELECT id FROM sensors")
    _sql(engine, "UPDATE sensors SET due_date = '2099-01-01'")
    return f"sensors {key}: "


def _delete_reference_point(engine: Engine) -> str:
    key = _id(engine, "SELECT id FROM reference_points")
    _sql(engine, "DELETE FROM reference_points")
    return f"reference_points {key}: "


def _untraced_update(engine: Engine) -> str:
    key = _id(engine, "SELECT id FROM sensor_models")
    _without_triggers(engine, "sensor_models", "UPDATE sensor_models SET tolerance_percent = 50")
    return f"sensor_models {key}: changed outside the application (tolerance_percent)"


def _back_dated_insert(engine: Engine) -> str:
    _sql(
        engine,
        "INSERT INTO customers (name, address) VALUES ('Shadow Corp', '')",
        "INSERT INTO runs (run_id, manifest_sha256, folder, status, started_utc, dut_id, "
        "stand_id) SELECT 'r0', 'c', '/nowhere', 'complete', '2020-01-01 00:00:00', 'SN-1', "
        "id FROM stands",
    )
    return "runs " + _id(engine, "SELECT id FROM runs WHERE run_id = 'r0'") + ": "


def _edited_audit_trail(engine: Engine) -> str:
    key = _id(engine, "SELECT max(id) FROM audit_trail")
    _without_triggers(
        engine, "audit_trail", f"UPDATE audit_trail SET actor = 'bob' WHERE id = {key}"
    )
    return f"audit_trail {key}: changed outside the application (actor)"


def _edited_chain(engine: Engine) -> str:
    seq = _id(engine, "SELECT seq FROM records_chain WHERE table_name = 'certificates'")
    _without_triggers(
        engine,
        "records_chain",
        f"UPDATE records_chain SET actor = 'mallory' WHERE seq = {seq}",
    )
    return f"records_chain {seq}: hash does not match its content"


TAMPERING: dict[str, Callable[[Engine], str]] = {
    "update certificate": _update_certificate,
    "update run": _update_run,
    "update due date": _update_due_date,
    "delete": _delete_reference_point,
    "drop trigger, edit, create trigger": _untraced_update,
    "back-dated insert": _back_dated_insert,
    "edited audit trail": _edited_audit_trail,
    "edited chain": _edited_chain,
}


@pytest.mark.parametrize("edit", sorted(TAMPERING))
def test_each_direct_edit_is_named_by_db_verify_and_stops_the_next_certificate(
    engine: Engine, tmp_path: Path, edit: str, capsys: pytest.CaptureFixture[str]
) -> None:
    _lab_day(engine, tmp_path)
    url = engine.url.render_as_string(hide_password=False)
    assert main(["db", "verify", "--db", url]) == 0
    capsys.readouterr()
    expected = TAMPERING[edit](engine)
    assert any(str(p).startswith(expected) for p in verify(engine)), verify(engine)
    assert main(["db", "verify", "--db", url]) == 2
    out, err = capsys.readouterr()
    assert f"BROKEN {expected}" in out
    assert "records:" in err and "broken" in err
    with pytest.raises(ChainBroken):
        quick_check(engine)
    argv = [
        "certificate",
        str(tmp_path / "r1"),
        "--db",
        url,
        "--prepared-by",
        "A. Tech",
        "--authorised-by",
        "Bob QM",
    ]
    assert main(argv) == 2
    assert "see `accelcal db verify`" in capsys.readouterr().err
    assert main(["db", "import", str(tmp_path), "--db", url]) == 2


def test_the_replica_role_does_not_hide_an_edit_on_postgresql(
    engine: Engine, tmp_path: Path
) -> None:
    if engine.dialect.name != "postgresql":
        pytest.skip("session_replication_role is PostgreSQL's")
    _lab_day(engine, tmp_path)
    key = _id(engine, "SELECT id FROM customers")
    _sql(
        engine,
        "SET LOCAL session_replication_role = replica",
        "UPDATE customers SET name = 'Mallory Ltd'",
    )
    with pytest.raises(ChainBroken, match=f"customers {key}: "):
        quick_check(engine)
    # the journal trigger fired although replication triggers were off (ENABLE ALWAYS)
    journal = f"customers {key}: update outside the application (journal"
    assert any(str(p).startswith(journal) for p in verify(engine))


def test_a_consistently_rewritten_chain_is_caught_by_the_head_a_seal_names(
    engine: Engine, tmp_path: Path
) -> None:
    """Even by someone holding the records key (this test does): the rebuilt chain signs, but
    it lacks the head a seal names and the head this workstation signed last."""
    _lab_day(engine, tmp_path)
    _sql(engine, "UPDATE customers SET name = 'Mallory Ltd'")
    with engine.connect() as c:
        last = chain.head(c)
    assert last is not None

    with engine.begin() as c:  # the whole chain rebuilt from the live rows
        if c.dialect.name == "sqlite":
            c.execute(text("DROP TRIGGER records_chain_no_delete"))
            c.execute(text("DELETE FROM records_chain"))
        else:
            trigger = "TRIGGER records_chain_append_only"
            c.execute(text(f"ALTER TABLE records_chain DISABLE {trigger}"))
            c.execute(text("DELETE FROM records_chain"))
            c.execute(text(f"ALTER TABLE records_chain ENABLE ALWAYS {trigger}"))
        after_migration(c)
    problems = [str(p) for p in verify(engine)]
    seal = tmp_path / "r1" / "seal.json"
    assert problems == [
        f"records_chain {last.seq}: the head this workstation signed last (hash "
        f"{last.hash[:16]}...) is not in the chain (records cut back or rebuilt)",
        f"{seal}: names chain head "
        f"{json.loads(seal.read_text())['records_chain_head'][:16]}..., not in the chain "
        "(records rewritten?)",
    ]


def test_a_seal_naming_an_unknown_head_is_broken_and_an_old_seal_without_one_is_not(
    engine: Engine, tmp_path: Path
) -> None:
    _lab_day(engine, tmp_path, seal_head="f" * 64)
    assert [p.table for p in verify(engine)] == [str(tmp_path / "r1" / "seal.json")]
    (tmp_path / "old").mkdir()
    manifest = _sealed_folder(tmp_path / "old" / "r1", None)
    assert "records_chain_head" not in (tmp_path / "old" / "r1" / "seal.json").read_text()
    with Session(engine) as s:
        s.add(
            Run(
                run_id="r-old",
                manifest_sha256=manifest,
                folder=str(tmp_path / "old" / "r1"),
                status="complete",
                started_utc=datetime(2026, 11, 20, tzinfo=UTC),
                dut_id="SN-1",
                stand_id=s.scalar(select(Stand.id)),
            )
        )
        s.commit()
    assert len(verify(engine)) == 1  # still only the unknown head


def test_an_edited_run_folder_of_an_indexed_run_is_named(engine: Engine, tmp_path: Path) -> None:
    _lab_day(engine, tmp_path)
    results = tmp_path / "r1" / "results.json"
    results.write_text('{"run_id": "r1", "sensitivity": 99}', encoding="utf-8")
    key = _id(engine, "SELECT id FROM runs")
    assert [str(p) for p in verify(engine)] == [
        f"runs {key} (r1): {results}: hash mismatch with the run's seal "
        f"({tmp_path / 'r1' / 'seal.json'})"
    ]


def test_an_orm_write_outside_the_lab_is_chained_too(engine: Engine, tmp_path: Path) -> None:
    _lab_day(engine, tmp_path)
    with Session(engine) as s:
        s.scalars(select(Sensor)).one().due_date = date(2027, 6, 1)
        s.commit()
    assert verify(engine) == []


def test_an_upgrade_enters_existing_rows_and_refuses_a_broken_chain(tmp_path: Path) -> None:
    engine = make_engine(resolve_url(f"sqlite:///{tmp_path / 'old.sqlite'}"))
    upgrade(engine, "0006")
    _sql(engine, "INSERT INTO customers (name, address) VALUES ('Before Chain', '')")
    upgrade(engine)
    assert verify(engine) == []
    with engine.connect() as c:
        entries = chain.read_entries(c)
    assert [(e.action, e.table_name) for e in entries] == [
        ("migrate", "customers"),
        ("schema", ""),
    ]
    _sql(engine, "UPDATE customers SET name = 'Renamed'")
    with engine.begin() as c:  # pretend a newer program: the check runs before migrating
        from app.records.db.chain_check import before_migration

        with pytest.raises(ChainBroken, match="customers 1: "):
            before_migration(c)
    engine.dispose()


def test_the_application_role_cannot_disable_triggers_and_works(
    request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    """docs/records.md: an owner role migrates, the application role only reads and writes."""
    server = request.getfixturevalue("postgres_server")
    url = resolve_url(postgres_database(server))
    owner = make_engine(url)
    upgrade(owner)
    database = owner.url.database
    role_sql = (Path(__file__).parents[4] / "docs" / "records.md").read_text(encoding="utf-8")
    block = role_sql.split("```sql", 1)[1].split("```", 1)[0]
    with owner.connect().execution_options(isolation_level="AUTOCOMMIT") as c:
        # the role is the server's: another test may have made it already (test_records_attacks)
        exists = c.execute(text("SELECT 1 FROM pg_roles WHERE rolname = 'accelcal_app'")).first()
        for statement in filter(str.strip, block.replace(":database", f'"{database}"').split(";")):
            if not (exists and statement.strip().startswith("CREATE ROLE")):
                c.execute(text(statement))
    app_url = owner.url.set(username="accelcal_app", password="app-secret")
    app_engine = make_engine(app_url.render_as_string(hide_password=False))
    _lab_day(app_engine, tmp_path)  # the application works under the role
    assert verify(app_engine) == []
    for attack in (
        "ALTER TABLE certificates DISABLE TRIGGER USER",
        "ALTER TABLE records_chain DISABLE TRIGGER ALL",
        "SET session_replication_role = replica",
        "DROP TRIGGER records_journal_note ON certificates",
        "UPDATE audit_trail SET actor = 'x'",
        "DELETE FROM records_chain",
        "DELETE FROM certificates",
    ):
        with app_engine.connect() as c, pytest.raises(Exception) as info:
            c.execute(text(attack))
        assert "permission denied" in str(info.value) or "must be owner" in str(info.value)
    assert quick_check(app_engine)
    app_engine.dispose()
    owner.dispose()


def test_a_run_and_its_certificate_name_the_chain_head_and_db_verify_checks_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """End to end on SQLite: the run's seal names the head the quick check returned, the DCC
    states it, and an edited DCC in the run folder is named by `db verify`."""
    url = f"sqlite:///{tmp_path / 'lab.sqlite'}"
    assert main(["db", "upgrade", "--db", url]) == 0
    assert main(["customers", "add", "ACME Ltd", "--address", "1 Test Street", "--db", url]) == 0
    model = ["models", "add", "PCB", "352C33", "--nominal", "10", "--unit", "mV/(m/s^2)"]
    assert main([*model, "--tolerance", "5", "--fmin", "1", "--fmax", "10000", "--db", url]) == 0
    assert (
        main(["sensors", "add", "SN-1", "--model", "352C33", "--owner", "ACME Ltd", "--db", url])
        == 0
    )
    add_sim_reference(url, date(2099, 1, 1))  # with records, the stand's reference is on record
    engine = make_engine(resolve_url(url))
    head_before = quick_check(engine)
    runs = tmp_path / "runs"
    assert main(["run", "--sensor", "SN-1", "--db", url, "--periods", "3", "--out", str(runs)]) == 0
    (folder,) = runs.iterdir()
    seal = json.loads((folder / "seal.json").read_text())
    assert seal["records_chain_head"] == head_before
    certificate = [
        "certificate",
        str(folder),
        "--db",
        url,
        "--prepared-by",
        "A. Tech",
        "--authorised-by",
        "Bob QM",
    ]
    assert main([*certificate, "--temperature", "23", "--mounting", "stud"]) == 0
    dcc = (folder / "certificate.xml").read_text(encoding="utf-8")
    assert head_before in dcc and "Records chain head (SHA-256)" in dcc
    capsys.readouterr()
    assert main(["db", "verify", "--db", url]) == 0
    (folder / "certificate.xml").chmod(0o644)
    (folder / "certificate.xml").write_text(dcc.replace(folder.name, "OTHER-RUN"), "utf-8")
    assert main(["db", "verify", "--db", url]) == 2
    assert "names run 'OTHER-RUN'" in capsys.readouterr().out
    engine.dispose()


@pytest.mark.parametrize("how", ["journal", "schema"])
def test_the_quick_check_catches_an_edit_of_a_row_outside_its_window(
    engine: Engine, tmp_path: Path, how: str
) -> None:
    """The model's entry lies before the last QUICK_WINDOW entries: an edit with the triggers in
    place is seen by its journal row, one with the triggers dropped and recreated by the
    schema fingerprint."""
    from app.records.db.chain_check import QUICK_WINDOW

    lab = _lab_day(engine, tmp_path)
    for number in range(QUICK_WINDOW // 2 + 1):  # a customer and its audit entry each
        lab.add_customer(f"Customer {number}")
    key = _id(engine, "SELECT id FROM sensor_models")
    with engine.connect() as c:
        window = chain.read_entries(c, last=QUICK_WINDOW)
    assert all(e.table_name != "sensor_models" for e in window)
    quick_check(engine)
    edit = "UPDATE sensor_models SET tolerance_percent = 50"
    if how == "journal":
        _sql(engine, edit)
        with pytest.raises(ChainBroken, match=f"sensor_models {key}: update outside"):
            quick_check(engine)
    else:  # SQLite: the same definitions back (no schema cookie consulted); PostgreSQL: new oids
        _without_triggers(engine, "sensor_models", edit)
        first = (
            f"sensor_models {key}: changed outside the application (tolerance_percent)"
            if engine.dialect.name == "sqlite"
            else "schema: the schema or its triggers changed"
        )
        with pytest.raises(ChainBroken, match=re.escape(first)):
            quick_check(engine)
    assert f"sensor_models {key}: changed outside the application (tolerance_percent)" in [
        str(p) for p in verify(engine)
    ]
