"""The customer a certificate is issued to (issue 35 point 5, migration 0014): bound at issue
to the sensor's owner then, kept when the sensor changes owner, never changed afterwards (the
rules refuse it, the chain names it: tests/app/records/db/test_records_attacks.py), and filled
by the upgrade for certificates issued before it from the sensor's owner at upgrade."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import pytest
from sqlalchemy import Engine, insert, select, text
from sqlalchemy.orm import Session

from app.records.db import chain_check, chain_rules
from app.records.db.chain_check import quick_check, verify
from app.records.db.engine import SCHEMA_HEAD, make_engine, upgrade
from app.records.db.lab import Lab, RecordsError
from app.records.db.models import Certificate, Customer, Run, Sensor, Stand
from tests.app.records.db.test_chain import _lab_day, _sealed_folder
from tests.records_db import seed_lab


def _bound(engine: Engine) -> dict[str, str]:
    """Each certificate's number -> the name of the customer it is issued to."""
    with engine.connect() as c:
        rows = c.execute(
            select(Certificate.number, Customer.name).join(
                Customer, Certificate.customer_id == Customer.id
            )
        ).all()
    return dict(rows)


def test_a_certificate_stays_with_the_customer_it_was_issued_to(
    engine: Engine, tmp_path: Path
) -> None:
    lab = _lab_day(engine, tmp_path)
    (number,) = (c.number for c in lab.register())
    assert _bound(engine) == {number: "ACME Ltd"}
    lab.add_customer("Buyer GmbH")
    moved = lab.move_sensor("SN-1", owner="Buyer GmbH")
    assert moved.owner_id != lab.certificate(number).customer_id
    assert _bound(engine) == {number: "ACME Ltd"}  # the sale took no certificate along
    assert lab.sensor("SN-1").owner.name == "Buyer GmbH"
    assert verify(engine) == []  # the move is chained like every write


def test_moving_a_sensor_names_an_unknown_sensor_or_customer(
    engine: Engine, tmp_path: Path
) -> None:
    lab = _lab_day(engine, tmp_path)
    with pytest.raises(RecordsError, match="owner: no customer named 'Nobody'"):
        lab.move_sensor("SN-1", owner="Nobody")
    with pytest.raises(RecordsError, match="serial: no sensor 'SN-9'"):
        lab.move_sensor("SN-9", owner="ACME Ltd")
    assert lab.sensor("SN-1").owner.name == "ACME Ltd"


def test_a_certificate_is_refused_when_its_sensor_changed_owner_while_issuing(
    engine: Engine, tmp_path: Path
) -> None:
    """register_issue names the owner it read for the PDF: a sensor moved since is refused,
    and no number is taken."""
    lab = _lab_day(engine, tmp_path)
    (first,) = lab.register()
    lab.add_customer("Buyer GmbH")
    buyer = lab.move_sensor("SN-1", owner="Buyer GmbH").owner_id
    acme = first.customer_id
    with pytest.raises(RecordsError, match="customer: sensor SN-1 changed owner while"):
        lab.issue_certificate(
            run_id="r1",
            prepared_by="alice",
            approved_by="Bob QM",
            replaces=first.number,
            reason="address corrected",
            customer_id=acme,
        )
    assert [c.number for c in lab.register()] == [first.number]
    amended = lab.issue_certificate(
        run_id="r1",
        prepared_by="alice",
        approved_by="Bob QM",
        replaces=first.number,
        reason="address corrected",
        customer_id=buyer,
    )
    assert amended.customer_id == buyer  # an amendment after the sale: the owner now
    assert verify(engine) == []


def test_sqlite_refuses_a_certificate_issued_to_nobody(records_url: str, tmp_path: Path) -> None:
    """SQLite cannot add a NOT NULL column: the trigger of migration 0014 stands in for it."""
    engine = make_engine(records_url)
    _lab_day(engine, tmp_path)
    with pytest.raises(Exception, match=chain_rules.CUSTOMER_MESSAGE), engine.begin() as c:
        c.execute(
            text(
                "INSERT INTO certificates (number, prefix, sequence, run_id, sensor_id, state, "
                "prepared_by, approved_by, issued_utc) SELECT 'X-1', 'X-', 1, run_id, sensor_id, "
                "'issued', 'a', 'b', issued_utc FROM certificates"
            )
        )
    engine.dispose()


_CERTIFICATE = (
    "INSERT INTO certificates (number, prefix, sequence, run_id, sensor_id, state, reason, "
    "prepared_by, approved_by, issued_utc) SELECT :number, 'ACC-', :seq, id, sensor_id, "
    ":state, :reason, 'alice', 'Bob QM', started_utc FROM runs"
)


def test_the_upgrade_binds_earlier_certificates_to_the_owner_at_upgrade(
    empty_url: str, tmp_path: Path
) -> None:
    """A lab at revision 0013 with an issued and a withdrawn certificate, whose sensor was
    sold before the upgrade: both are bound to the owner at upgrade (docs/records.md says
    so; the rules that refuse editing them are set aside for it), every filled row is
    chained, and the rules hold over the new column afterwards."""
    engine = make_engine(empty_url)
    upgrade(engine, "0013")
    lab = seed_lab(Lab(engine, actor="alice"), {"SN-1": "ACME Ltd"})
    lab.add_customer("Buyer GmbH")
    with Session(engine) as s:
        stand = Stand(stand_file_sha256="b" * 64, name="stand")
        s.add(stand)
        s.flush()
        sensor = s.scalar(select(Sensor))
        assert sensor is not None
        # the 0013 run index's columns only (the ORM's Run has runs.batch_id, migration 0015)
        s.execute(
            insert(Run).values(
                run_id="r1",
                manifest_sha256=_sealed_folder(tmp_path / "r1", None),
                folder=str(tmp_path / "r1"),
                status="complete",
                started_utc=datetime(2026, 11, 23, tzinfo=UTC),
                dut_id="SN-1",
                stand_id=stand.id,
                sensor_id=sensor.id,
            )
        )
        s.commit()
    with engine.begin() as c:  # the 0013 register's rows, chained as a migration enters them
        for seq, state, reason in ((1, "issued", None), (2, "withdrawn", "wrong sensor")):
            values = {"number": f"ACC-{seq}", "seq": seq, "state": state, "reason": reason}
            c.execute(text(_CERTIFICATE), values)
        chain_check.after_migration(c)
    lab.move_sensor("SN-1", owner="Buyer GmbH")
    assert upgrade(engine) == ("0013", SCHEMA_HEAD)
    assert _bound(engine) == {"ACC-1": "Buyer GmbH", "ACC-2": "Buyer GmbH"}
    assert verify(engine) == []
    quick_check(engine)
    for number, rule in (
        ("ACC-1", chain_rules.FROZEN_MESSAGE),
        ("ACC-2", chain_rules.FINAL_MESSAGE),
    ):
        with pytest.raises(Exception, match=rule), engine.begin() as c:
            c.execute(
                text("UPDATE certificates SET customer_id = 1 WHERE number = :n"), {"n": number}
            )
    assert _bound(engine) == {"ACC-1": "Buyer GmbH", "ACC-2": "Buyer GmbH"}
    engine.dispose()


def test_the_move_command_gives_the_sensor_and_names_a_wrong_owner(
    records_url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from app.cli import main

    engine = make_engine(records_url)
    lab = _lab_day(engine, tmp_path)
    lab.add_customer("Buyer GmbH")
    (number,) = (c.number for c in lab.register())
    capsys.readouterr()
    assert main(["sensors", "move", "SN-1", "--owner", "Nobody", "--db", records_url]) == 2
    err = capsys.readouterr().err
    assert "owner: no customer named 'Nobody'" in err and "Traceback" not in err
    assert main(["sensors", "move", "SN-1", "--owner", "Buyer GmbH", "--db", records_url]) == 0
    out = capsys.readouterr().out
    assert "sensor SN-1 now owned by Buyer GmbH" in out
    assert lab.sensor("SN-1").owner.name == "Buyer GmbH"
    assert _bound(engine) == {number: "ACME Ltd"}
    engine.dispose()
