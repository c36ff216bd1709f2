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
