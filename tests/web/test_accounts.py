"""Customers' portal accounts (issue 35 point 5) made by staff: `accelcal records account ...`
and app.web.accounts. Bound to one records customer, argon2id as the staff's, audited without
the hash, the records' chain intact after every write, refusals naming the field (exit 2)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.cli import main
from app.records.db.chain_check import quick_check, verify
from app.records.db.engine import open_engine
from app.records.db.lab import Lab, RecordsError
from app.records.db.models import AuditEntry, ChainEntry, CustomerAccount
from app.web.accounts import add_account, list_accounts
from app.web.users import add_user, password_matches
from tests.records_db import new_records

pytestmark = pytest.mark.integration

SECRET = "a customer's long password"


@pytest.fixture
def db_url(tmp_path: Path) -> str:
    url = new_records(tmp_path / "records.sqlite")
    Lab(open_engine(url), actor="test").add_customer("ACME Ltd", "1 Test Street")
    return url


def _add(db_url: str, monkeypatch, *argv: str, password: str = SECRET) -> int:
    monkeypatch.setattr("sys.stdin", io.StringIO(password + "\n"))
    return main(["records", "account", "add", *argv, "--password-stdin", "--db", db_url])


def test_account_add_binds_the_customer_hashes_and_audits_no_hash(
    db_url: str, monkeypatch, capsys
) -> None:
    code = _add(db_url, monkeypatch, "acme.buyer", "--customer", "ACME Ltd",
                "--display-name", "ACME purchasing")  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert "account acme.buyer added for customer ACME Ltd" in capsys.readouterr().out
    engine = open_engine(db_url)
    with Session(engine) as s:
        account = s.scalar(select(CustomerAccount))
        assert account is not None and account.customer.name == "ACME Ltd"
        assert account.password_hash.startswith("$argon2id$")
        assert password_matches(account.password_hash, SECRET)
        trail = [e for e in s.scalars(select(AuditEntry)) if e.table_name == "customer_accounts"]
        chained = " ".join(e.row or "" for e in s.scalars(select(ChainEntry)))
    assert len(trail) == 1 and trail[0].action == "insert"
    assert json.loads(trail[0].changes)["customer"] == "ACME Ltd"
    assert account.password_hash not in trail[0].changes and SECRET not in trail[0].changes
    assert account.password_hash not in chained  # the chain keeps its SHA-256 only
    assert verify(engine) == []  # the chain walks clean, the row's entry signed
    quick_check(engine)  # what a run checks first: raises ChainBroken when not


def test_account_list_disable_enable_passwd_remove(db_url: str, monkeypatch, capsys) -> None:
    assert _add(db_url, monkeypatch, "acme.buyer", "--customer", "ACME Ltd") == 0
    capsys.readouterr()
    assert main(["records", "account", "list", "--json", "--db", db_url]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert row["username"] == "acme.buyer" and row["customer"] == "ACME Ltd" and row["active"]
    assert "hash" not in json.dumps(row)
    assert main(["records", "account", "disable", "acme.buyer", "--db", db_url]) == 0
    engine = open_engine(db_url)
    assert [a.active for a in list_accounts(engine)] == [False]
    assert main(["records", "account", "enable", "acme.buyer", "--db", db_url]) == 0
    assert [a.active for a in list_accounts(engine)] == [True]
    monkeypatch.setattr("sys.stdin", io.StringIO("a brand new password\n"))
    argv = ["records", "account", "passwd", "acme.buyer", "--password-stdin", "--db", db_url]
    assert main(argv) == 0
    with Session(engine) as s:
        account = s.scalar(select(CustomerAccount))
        assert account is not None and password_matches(
            account.password_hash, "a brand new password"
        )
    assert main(["records", "account", "remove", "acme.buyer", "--db", db_url]) == 0
    assert list_accounts(engine) == []
    with Session(engine) as s:
        actions = [
            e.action
            for e in s.scalars(select(AuditEntry).order_by(AuditEntry.id))
            if e.table_name == "customer_accounts"
        ]
    # add, disable, enable, passwd, remove: each audited once
    assert actions == ["insert", "update", "update", "update", "delete"]
    assert verify(engine) == []


@pytest.mark.parametrize(
    ("argv", "password", "message"),
    [
        (["acme.buyer", "--customer", "Nobody Inc"], SECRET, "customer: no customer 'Nobody Inc'"),
        (["acme.buyer", "--customer", "ACME Ltd"], "short", "password: shorter than 12"),
        (["a b", "--customer", "ACME Ltd"], SECRET, "username: 'a b' must be"),
        (["qm", "--customer", "ACME Ltd"], SECRET, "username: 'qm' is a staff user's name"),
    ],
)
def test_account_add_refusals_name_the_field(
    db_url: str, monkeypatch, capsys, argv: list[str], password: str, message: str
) -> None:
    add_user(open_engine(db_url), "qm", "a staff password", display_name="QM", actor="test")
    assert _add(db_url, monkeypatch, *argv, password=password) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert list_accounts(open_engine(db_url)) == []


def test_unknown_accounts_and_a_second_add_are_refused(db_url: str, monkeypatch, capsys) -> None:
    for action in ("disable", "enable", "remove"):
        assert main(["records", "account", action, "nobody", "--db", db_url]) == 2
        assert "username: no customer account 'nobody'" in capsys.readouterr().err
    engine = open_engine(db_url)
    add_account(engine, "acme.buyer", SECRET, customer="ACME Ltd", display_name="A", actor="t")
    with pytest.raises(RecordsError, match=r"username: 'acme\.buyer' already exists"):
        add_account(engine, "acme.buyer", SECRET, customer="ACME Ltd", display_name="A")
    assert main(["records", "account", "add", "x1", "--customer", "ACME Ltd", "--password",
                 SECRET, "--db", db_url]) == 2  # fmt: skip
    assert "unrecognized arguments" in capsys.readouterr().err


def test_on_postgresql_accounts_are_the_administrators_and_the_portal_reads_them() -> None:
    """Migration 0012 on PostgreSQL: the owner adds an account; the application role may
    disable one but not add, re-enable or rebind one (the rule's trigger); the web view's
    read-only engine finds the account with its customer and that customer's sensors only."""
    import os
    import shutil
    import tempfile

    from sqlalchemy import text
    from sqlalchemy.exc import DBAPIError

    from app.records.db.chain_rules import ACCOUNTS_MESSAGE
    from app.records.db.engine import make_engine, resolve_url, upgrade
    from app.web.store import Store, open_read_only
    from tests.pg_server import start_pgserver

    folder = Path(tempfile.mkdtemp(prefix="accelcal-portal-pg-"))  # short: the socket lives here
    try:
        server = start_pgserver(folder)
    except Exception as exc:  # no wheel, no start
        shutil.rmtree(folder, ignore_errors=True)
        if os.environ.get("CI") == "true":
            pytest.fail(f"PostgreSQL could not start in CI: {exc}")
        pytest.skip(f"PostgreSQL could not start: {exc}")
    try:
        url = resolve_url(server.get_uri())
        owner = make_engine(url)
        upgrade(owner)
        lab = Lab(owner, actor="test")
        lab.add_customer("ACME Ltd")
        lab.add_customer("Other GmbH")
        lab.add_model("Sim", "P-100", nominal_sensitivity=10.0, unit="mV/(m/s^2)",
                      tolerance_percent=5.0, frequency_min_hz=10.0,
                      frequency_max_hz=10000.0)  # fmt: skip
        lab.add_sensor("SN-PG-1", model="P-100", owner="ACME Ltd")
        lab.add_sensor("SN-PG-2", model="P-100", owner="Other GmbH")
        add_account(owner, "acme.pg", SECRET, customer="ACME Ltd", display_name="A", actor="t")
        with owner.begin() as c:
            c.execute(text("CREATE ROLE portal_app NOLOGIN"))
            c.execute(
                text("GRANT SELECT, INSERT, UPDATE ON ALL TABLES IN SCHEMA public TO portal_app")
            )
            c.execute(text("GRANT USAGE, SELECT ON ALL SEQUENCES IN SCHEMA public TO portal_app"))
        refused = [
            "INSERT INTO customer_accounts (username, display_name, customer_id, password_hash, "
            "active, created_utc) SELECT 'forged', 'F', id, 'x', true, now() FROM customers "
            "WHERE name = 'Other GmbH'",
            "UPDATE customer_accounts SET customer_id = "
            "(SELECT id FROM customers WHERE name = 'Other GmbH')",
            "UPDATE customer_accounts SET password_hash = 'x'",
        ]
        for statement in refused:
            with pytest.raises(DBAPIError, match="only an administrator"), owner.begin() as c:
                c.execute(text("SET LOCAL ROLE portal_app"))
                c.execute(text(statement))
        assert "only an administrator" in ACCOUNTS_MESSAGE
        with owner.begin() as c:  # disabling is the application's to do
            c.execute(text("SET LOCAL ROLE portal_app"))
            c.execute(text("UPDATE customer_accounts SET active = false"))
        with pytest.raises(DBAPIError, match="only an administrator"), owner.begin() as c:
            c.execute(text("SET LOCAL ROLE portal_app"))
            c.execute(text("UPDATE customer_accounts SET active = true"))
        owner.dispose()
        engine = open_read_only(url)
        store = Store(engine)
        account = store.account("acme.pg")
        assert account is not None and account.customer == "ACME Ltd" and not account.active
        assert [s.serial for s in store.customer_sensors(account.customer_id)] == ["SN-PG-1"]
        assert store.customer_sensors(account.customer_id, "SN-PG-2") == []
        engine.dispose()
    finally:
        server.cleanup()
        shutil.rmtree(folder, ignore_errors=True)
