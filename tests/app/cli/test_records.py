"""`accelcal records user add NAME` (issue 27): the password from stdin or a prompt, never from
argv; audited without the hash."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.cli import main
from app.records.db.engine import open_engine
from app.records.db.models import AuditEntry, User
from tests.records_db import new_records

pytestmark = pytest.mark.integration


@pytest.fixture
def db_url(tmp_path: Path) -> str:
    return new_records(tmp_path / "records.sqlite")


def test_user_add_reads_the_password_from_stdin_and_audits_no_hash(
    db_url: str, monkeypatch, capsys
) -> None:
    secret = "a long enough password"
    monkeypatch.setattr("sys.stdin", io.StringIO(secret + "\n"))
    code = main(["records", "user", "add", "qm", "--display-name", "Q. Manager",
                 "--password-stdin", "--db", db_url])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    from app.web.users import password_matches

    with Session(open_engine(db_url)) as s:
        user = s.scalar(select(User).where(User.username == "qm"))
        assert user is not None and user.display_name == "Q. Manager"
        assert password_matches(user.password_hash, secret)  # the newline is not part of it
        trail = " ".join(e.changes for e in s.scalars(select(AuditEntry)))
    assert user.password_hash not in trail and secret not in trail


def test_user_add_takes_no_password_option(db_url: str, capsys) -> None:
    assert main(["records", "user", "add", "qm", "--password", "x" * 20, "--db", db_url]) == 2
    assert "unrecognized arguments" in capsys.readouterr().err


def test_user_add_refuses_a_short_password_and_a_missing_terminal(
    db_url: str, monkeypatch, capsys
) -> None:
    monkeypatch.setattr("sys.stdin", io.StringIO("short\n"))
    assert main(["records", "user", "add", "qm", "--password-stdin", "--db", db_url]) == 2
    assert "password: shorter than 12" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # not a terminal: no prompt possible
    assert main(["records", "user", "add", "qm", "--db", db_url]) == 2
    assert "--password-stdin" in capsys.readouterr().err
