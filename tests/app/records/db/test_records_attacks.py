"""Issue 33 points 1-2: each attacker against each rule of the records, on SQLite and
PostgreSQL, one row of ATTACKS per (attack, attacker). The attackers:

- file access: any SQL on the database (SQLite: the file; PostgreSQL: a superuser, as whoever
  holds the server's data directory is), triggers dropped and put back, entries computed by
  hand or signed with a key of his own, but not the lab's records key;
- application role: PostgreSQL's `accelcal_app` of docs/records.md (no DDL, no DELETE), holding
  the records key as a workstation does; on SQLite (no roles) the application's own connection
  with plain statements;
- administrator: the owner of the tables, holding the records key.

Each row says what must happen: refused (the statement fails, naming the rule), reported (`db
verify` and the quick check name what they found) or allowed (the rule permits it).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path

import pytest
from sqlalchemy import Connection, Engine, insert, text

from app.cli import main
from app.records.db import chain, chain_check, chain_rules, records_key
from app.records.db.chain_check import ChainBroken, quick_check, verify
from app.records.db.engine import make_engine
from app.records.db.lab import Lab
from app.records.db.models import ChainEntry
from tests.app.records.db.test_chain import _lab_day, _without_triggers

ROLE_SQL = Path(__file__).parents[4] / "docs" / "records.md"


class Attacker(StrEnum):
    FILE = "file access"
    APP = "application role"
    ADMIN = "administrator"


class Outcome(StrEnum):
    REFUSED = "refused"  # the statement fails with `expected` in its message
    REPORTED = "reported"  # db verify and the quick check name `expected`
    ALLOWED = "allowed"  # the rule permits it (nothing to report)


@dataclass
class Scene:
    """One attack's stage: the lab's engine (owner), the attacker's, the certificate, where."""

    owner: Engine
    attacker: Engine
    number: str
    folder: Path
    dialect: str
    before_withdrawal: int  # the signed head before the withdrawal's entries


def forge(c: Connection, key: records_key.RecordsKey | None) -> None:
    """What the issue's attacker did: enter every unclaimed journal row and every live row the
    chain does not derive as new entries computed by hand, after the current head; signed with
    `key` (a key of the attacker's own, entered in records_keys) or not signed at all."""
    tables = chain.chained_tables()
    live = chain_check._live_state(c, tables)
    changes = [
        chain.Change("update", j.table_name, j.row_key, live.get((j.table_name, j.row_key)), j.id)
        for j in chain_check._unclaimed_rows(c)
    ]
    state = chain_check._walk(chain.read_entries(c)).state
    state.update({(ch.table_name, ch.row_key): ch.row for ch in changes if ch.row})
    changes += [
        chain.Change("update", p.table, p.key, live.get((p.table, p.key)))
        for p in chain_check._compare(state, live, tables)
    ]
    head = chain.head(c)
    assert head is not None
    seq, prev = head.seq, head.hash
    rows = []
    for change in changes:
        seq += 1
        fields = {
            "seq": seq,
            "at_utc": datetime.now(UTC).isoformat(),
            "actor": "alice",
            "action": change.action,
            "table_name": change.table_name,
            "row_key": change.row_key,
            "row": change.row,
            "journal_id": change.journal_id,
            "schema_fingerprint": chain.schema_fingerprint(c),
        }
        prev = chain.entry_hash(prev, **fields)
        before = rows[-1]["hash"] if rows else head.hash
        rows.append(
            {**fields, "prev_hash": before, "hash": prev, "signature": None, "key_id": None}
        )
    if key is not None:
        rows[-1]["signature"] = key.sign_head(head.seq + 1, seq, prev)
        rows[-1]["key_id"] = key.key_id
        chain._register_key(c, key)
    c.execute(insert(ChainEntry), rows)


def _own_key(tmp_path: Path) -> records_key.RecordsKey:
    return records_key.create_key(tmp_path / "mallory" / "key.pem")


def _attack_sql(scene: Scene, *statements: str) -> None:
    with scene.attacker.begin() as c:
        for statement in statements:
            c.execute(text(statement))


def _drop_edit_forge(
    scene: Scene, table: str, edit: str, key: records_key.RecordsKey | None
) -> None:
    """File access: the table's triggers dropped, the edit made, the triggers put back, the
    chain extended by hand (signed with `key`, or not)."""
    _without_triggers(scene.attacker, table, edit)
    with scene.attacker.begin() as c:
        if scene.dialect == "sqlite":  # the schema cookie put back too (nothing reads it now)
            c.exec_driver_sql("PRAGMA schema_version")
        forge(c, key)


REVIVE = "UPDATE certificates SET state = 'issued', reason = NULL WHERE number = '{number}'"
EDIT = "UPDATE certificates SET approved_by = 'Mallory' WHERE number = '{number}'"
ADD_USER = (
    "INSERT INTO users (username, display_name, password_hash, active, created_utc) "
    "VALUES ('mallory', 'Mallory', 'x', {true}, '2026-11-27 00:00:00')"
)


def _true(scene: Scene) -> str:
    return "1" if scene.dialect == "sqlite" else "true"


def revive_by_hand(scene: Scene, tmp_path: Path) -> None:
    _drop_edit_forge(scene, "certificates", REVIVE.format(number=scene.number), None)


def revive_signed_own_key(scene: Scene, tmp_path: Path) -> None:
    edit = REVIVE.format(number=scene.number)
    _drop_edit_forge(scene, "certificates", edit, _own_key(tmp_path))


def revive_then_the_lab_writes(scene: Scene, tmp_path: Path) -> None:
    """The entries computed by hand, then the lab's next write signs a head on top of them."""
    revive_by_hand(scene, tmp_path)
    Lab(scene.owner, actor="alice").add_customer("Next Customer Ltd")


def revive_plainly(scene: Scene, tmp_path: Path) -> None:
    _attack_sql(scene, REVIVE.format(number=scene.number))


def edit_issued_by_hand(scene: Scene, tmp_path: Path) -> None:
    _drop_edit_forge(scene, "certificates", EDIT.format(number=scene.number), _own_key(tmp_path))


def edit_issued_plainly(scene: Scene, tmp_path: Path) -> None:
    _attack_sql(scene, "UPDATE certificates SET approved_by = 'Mallory' WHERE state = 'issued'")


REBIND = (
    "UPDATE certificates SET customer_id = (SELECT id FROM customers WHERE name = 'Rival Ltd') "
    "WHERE number = '{number}'"
)


def _rival(scene: Scene) -> str:
    """The customer a certificate is rebound to (added by the lab, signed); the edit."""
    Lab(scene.owner, actor="alice").add_customer("Rival Ltd")
    return REBIND.format(number=scene.number)


def rebind_by_hand(scene: Scene, tmp_path: Path) -> None:
    """Issue 35 point 5: an issued certificate given to another customer (the portal would
    show it to them), its triggers dropped and put back, the chain left as it was."""
    _without_triggers(scene.attacker, "certificates", _rival(scene))


def rebind_signed_own_key(scene: Scene, tmp_path: Path) -> None:
    _drop_edit_forge(scene, "certificates", _rival(scene), _own_key(tmp_path))


def rebind_plainly(scene: Scene, tmp_path: Path) -> None:
    _attack_sql(scene, _rival(scene))


def add_user_by_hand(scene: Scene, tmp_path: Path) -> None:
    _attack_sql(scene, ADD_USER.format(true=_true(scene)))
    with scene.attacker.begin() as c:
        forge(c, _own_key(tmp_path))


def add_user_plainly(scene: Scene, tmp_path: Path) -> None:
    _attack_sql(scene, ADD_USER.format(true=_true(scene)))


def add_user_through_the_application(scene: Scene, tmp_path: Path) -> None:
    from app.web.users import add_user

    add_user(scene.attacker, "mallory", "s3cret-Pa55w0rd-long", display_name="Mallory")


def forged_entry_of_a_customer(scene: Scene, tmp_path: Path) -> None:
    """An entry appended with the records key that says a row is what it is not."""
    with scene.attacker.begin() as c:
        row = chain.live_row(c, chain.chained_tables()["customers"], "1")
        assert row is not None
        chain.append(
            c,
            actor="mallory",
            changes=[chain.Change("update", "customers", "1", row.replace("ACME", "EVIL"))],
        )


def rewrite_tail_own_key(scene: Scene, tmp_path: Path) -> None:
    """The chain deleted after the head the run's seal names and rebuilt with another key,
    the withdrawal undone."""
    _rewrite_tail(scene, _own_key(tmp_path))


def rewrite_tail_lab_key(scene: Scene, tmp_path: Path) -> None:
    """The same by the administrator, who holds the records key."""
    _rewrite_tail(scene, records_key.require_key())


def _rewrite_tail(scene: Scene, key: records_key.RecordsKey) -> None:
    import json

    seal_head = json.loads((scene.folder / "seal.json").read_text())["records_chain_head"]
    with scene.attacker.begin() as c:
        (seq,) = c.execute(
            text("SELECT seq FROM records_chain WHERE hash = :h"), {"h": seal_head}
        ).one()
        _disable(c, "records_chain", "records_journal", "certificates")
        c.execute(text("DELETE FROM records_chain WHERE seq > :s"), {"s": seq})
        c.execute(text(REVIVE.format(number=scene.number)))
        c.execute(text("DELETE FROM records_journal"))
        _enable(c)
        forge(c, key)


def truncate_to_a_signed_head(scene: Scene, tmp_path: Path) -> None:
    """The withdrawal's entries cut off (the head before them is signed by the lab's key) and
    the certificate put back as it was: nothing to forge."""
    with scene.attacker.begin() as c:
        _disable(c, "records_chain", "records_journal", "certificates")
        seq = scene.before_withdrawal
        c.execute(text("DELETE FROM records_chain WHERE seq > :s"), {"s": seq})
        c.execute(text(REVIVE.format(number=scene.number)))
        unclaimed = (
            "DELETE FROM records_journal WHERE id NOT IN "
            "(SELECT journal_id FROM records_chain WHERE journal_id IS NOT NULL)"
        )
        c.execute(text(unclaimed))
        _enable(c)


def _disable(c: Connection, *tables: str) -> None:
    """Every trigger of `tables` off (SQLite: dropped, kept in c.info for _enable)."""
    for table in tables:
        if c.dialect.name == "sqlite":
            query = "SELECT name, sql FROM sqlite_master WHERE type='trigger' AND tbl_name=:t"
            rows = c.execute(text(query), {"t": table}).all()
            for name, _ in rows:
                c.execute(text(f"DROP TRIGGER {name}"))
        else:
            query = (
                "SELECT tgname, tgenabled::text FROM pg_trigger "
                "WHERE tgrelid = CAST(:t AS regclass) AND NOT tgisinternal"
            )
            rows = [
                (f"{name} ON {table}", state)
                for name, state in c.execute(text(query), {"t": table})
            ]
            c.execute(text(f"ALTER TABLE {table} DISABLE TRIGGER USER"))
        c.info.setdefault("triggers", []).extend(rows)


def _enable(c: Connection) -> None:
    """The triggers _disable turned off back exactly as they were."""
    for name, how in c.info.pop("triggers", []):
        if c.dialect.name == "sqlite":
            c.execute(text(how))
        else:
            trigger, table = name.split(" ON ")
            always = "ALWAYS " if how == "A" else ""
            c.execute(text(f"ALTER TABLE {table} ENABLE {always}TRIGGER {trigger}"))


def quick_check_bypass(scene: Scene, tmp_path: Path) -> None:
    """Issue 33: drop the journal trigger, edit an old row, recreate it, reset the cookie."""
    with scene.attacker.begin() as c:
        cookie = (
            c.exec_driver_sql("PRAGMA schema_version").scalar()
            if scene.dialect == "sqlite"
            else None
        )
    _without_triggers(scene.attacker, "customers", "UPDATE customers SET name = 'EVIL Ltd'")
    if cookie is not None:
        raw = scene.attacker.raw_connection()
        try:
            raw.execute("PRAGMA writable_schema = ON")
            raw.execute(f"PRAGMA schema_version = {cookie}")
            raw.execute("PRAGMA writable_schema = OFF")
            raw.commit()
        finally:
            raw.close()


def drop_a_trigger(scene: Scene, tmp_path: Path) -> None:
    _attack_sql(scene, "DROP TRIGGER records_rule_certificates ON certificates")


def delete_chain(scene: Scene, tmp_path: Path) -> None:
    _attack_sql(scene, "DELETE FROM records_chain")


@dataclass(frozen=True)
class Attack:
    """One row: what is tried, by whom, on which engines, what must happen, and the text the
    refusal or the report must contain."""

    case: str
    attacker: Attacker
    run: Callable[[Scene, Path], None]
    outcome: Outcome
    expected: str
    dialects: tuple[str, ...] = ("sqlite", "postgresql")


NOT_SIGNED = "are not covered by a signed head (appended without the records key"
OTHER_KEY = "not the configured records key"
SLIPPED_IN = "does not verify (an entry forged, edited or slipped in unsigned before it)"
LAST_HEAD = "the head this workstation signed last"
CUSTOMER_EDITED = "customers 1: changed outside the application (name)"
REBOUND = "certificates 1: changed outside the application (customer_id)"
ISSUED_CASES = ("edited issued certificate", "rebound certificate")  # the others: withdrawn
FINAL, FROZEN, USERS = (
    chain_rules.FINAL_MESSAGE,
    chain_rules.FROZEN_MESSAGE,
    chain_rules.USERS_MESSAGE,
)
FILE, APP, ADMIN = Attacker.FILE, Attacker.APP, Attacker.ADMIN
REFUSED, REPORTED, ALLOWED = Outcome.REFUSED, Outcome.REPORTED, Outcome.ALLOWED
PG = ("postgresql",)
ATTACKS = [
    Attack("revived withdrawal", FILE, revive_by_hand, REPORTED, NOT_SIGNED),
    Attack("revived withdrawal", FILE, revive_signed_own_key, REPORTED, OTHER_KEY),
    Attack("revived withdrawal", FILE, revive_then_the_lab_writes, REPORTED, SLIPPED_IN),
    Attack("revived withdrawal", APP, revive_plainly, REFUSED, FINAL),
    Attack("revived withdrawal", ADMIN, revive_plainly, REFUSED, FINAL),
    Attack("edited issued certificate", FILE, edit_issued_by_hand, REPORTED, OTHER_KEY),
    Attack("edited issued certificate", APP, edit_issued_plainly, REFUSED, FROZEN),
    Attack("edited issued certificate", ADMIN, edit_issued_plainly, REFUSED, FROZEN),
    Attack("rebound certificate", FILE, rebind_by_hand, REPORTED, REBOUND),
    Attack("rebound certificate", FILE, rebind_signed_own_key, REPORTED, OTHER_KEY),
    Attack("rebound certificate", APP, rebind_plainly, REFUSED, FROZEN),
    Attack("rebound certificate", ADMIN, rebind_plainly, REFUSED, FROZEN),
    Attack("added user", FILE, add_user_by_hand, REPORTED, OTHER_KEY),
    Attack("added user", APP, add_user_plainly, REFUSED, USERS, PG),
    Attack("added user", APP, add_user_through_the_application, REFUSED, USERS, PG),
    Attack("added user", ADMIN, add_user_through_the_application, ALLOWED, ""),
    Attack("forged entry", APP, forged_entry_of_a_customer, REPORTED, CUSTOMER_EDITED),
    Attack("rewritten tail", FILE, rewrite_tail_own_key, REPORTED, OTHER_KEY),
    Attack("rewritten tail", APP, delete_chain, REFUSED, "permission denied", PG),
    Attack("rewritten tail", ADMIN, rewrite_tail_lab_key, REPORTED, LAST_HEAD),
    Attack("cut back to a signed head", FILE, truncate_to_a_signed_head, REPORTED, LAST_HEAD),
    Attack("quick-check bypass", FILE, quick_check_bypass, REPORTED, CUSTOMER_EDITED),
    Attack("quick-check bypass", APP, drop_a_trigger, REFUSED, "must be owner", PG),
]


def _ids() -> Iterator[str]:
    for attack in ATTACKS:
        yield f"{attack.case}-{attack.attacker}-{attack.run.__name__}"


def _app_engine(owner: Engine) -> Engine:
    """The application role of docs/records.md on the owner's database (the role made once
    per server, the grants per database)."""
    block = ROLE_SQL.read_text(encoding="utf-8").split("```sql", 1)[1].split("```", 1)[0]
    database = owner.url.database
    with owner.connect().execution_options(isolation_level="AUTOCOMMIT") as c:
        exists = c.execute(text("SELECT 1 FROM pg_roles WHERE rolname = 'accelcal_app'")).first()
        for statement in filter(str.strip, block.replace(":database", f'"{database}"').split(";")):
            if exists and statement.strip().startswith("CREATE ROLE"):
                continue
            c.execute(text(statement))
    url = owner.url.set(username="accelcal_app", password="app-secret")
    return make_engine(url.render_as_string(hide_password=False))


@pytest.mark.parametrize("attack", ATTACKS, ids=list(_ids()))
def test_each_attacker_against_each_rule(
    engine: Engine, tmp_path: Path, attack: Attack, capsys: pytest.CaptureFixture[str]
) -> None:
    dialect = engine.dialect.name
    if dialect not in attack.dialects:
        pytest.skip(f"{attack.attacker} on {dialect}: no roles on SQLite (docs/records.md)")
    lab = _lab_day(engine, tmp_path)
    number = lab.register()[0].number
    with engine.connect() as c:
        before = chain.head(c)
    assert before is not None and before.signature is not None
    if attack.case not in ISSUED_CASES:  # the others attack a withdrawn one
        lab.withdraw_certificate(number, "wrong sensor")  # the lab's last write, signed
    assert verify(engine) == []
    attacker = (
        _app_engine(engine) if attack.attacker == Attacker.APP and dialect != "sqlite" else engine
    )
    scene = Scene(engine, attacker, number, tmp_path / "r1", dialect, before.seq)
    try:
        if attack.outcome == Outcome.REFUSED:
            with pytest.raises(Exception, match=re.escape(attack.expected)):
                attack.run(scene, tmp_path)
            assert verify(engine) == []  # nothing of it reached the records
            return
        attack.run(scene, tmp_path)
    finally:
        if attacker is not engine:
            attacker.dispose()
    if attack.outcome == Outcome.ALLOWED:
        assert verify(engine) == []
        return
    problems = [str(p) for p in verify(engine)]
    assert any(attack.expected in p for p in problems), problems
    with pytest.raises(ChainBroken, match="see `accelcal db verify`") as info:
        quick_check(engine)
    assert str(info.value).startswith("records: ")
    capsys.readouterr()
    url = engine.url.render_as_string(hide_password=False)
    assert main(["db", "verify", "--db", url]) == 2
    out = capsys.readouterr().out
    assert attack.expected in out and "BROKEN" in out
