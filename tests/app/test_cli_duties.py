"""Issue 27 wiring in the CLI: `accelcal validate` (the report, exit 0; a failed case exit 1;
removing a budget term: tests/app/test_validation.py), `accelcal web` (the options of python -m
app.web, bad ones exit 2) and `accelcal records user add NAME` (the password from stdin or a
prompt, never from argv; audited without the hash)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.cli import build_parser, main
from app.records.db.engine import open_engine
from app.records.db.models import AuditEntry, User

pytestmark = pytest.mark.integration


def test_validate_writes_the_report_and_exits_0(tmp_path: Path, capsys) -> None:
    out = tmp_path / "report.pdf"
    assert main(["validate", "--out", str(out)]) == 0
    assert out.read_bytes().startswith(b"%PDF")
    assert json.loads(out.with_suffix(".json").read_text())["passed"] is True
    assert f"validation passed: report {out}" in capsys.readouterr().out


def test_validate_exits_1_when_a_case_fails(tmp_path: Path, monkeypatch) -> None:
    from app.validation import cases

    original = cases.run_all

    def one_failed():  # type: ignore[no-untyped-def]
        import dataclasses

        results = original()
        return [dataclasses.replace(results[0], passed=False), *results[1:]]

    monkeypatch.setattr(cases, "run_all", one_failed)
    assert main(["validate", "--out", str(tmp_path / "r.pdf")]) == 1


def test_validate_refuses_a_report_path_that_is_no_pdf(tmp_path: Path, capsys) -> None:
    assert main(["validate", "--out", str(tmp_path / "r.txt")]) == 2
    assert "--out" in capsys.readouterr().err


def test_validate_writes_to_the_labs_validation_folder_by_default(monkeypatch, tmp_path) -> None:
    """Without --out the report goes where the certificate looks for it."""
    from app.cli.validate import default_out

    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(tmp_path / "v"))
    out = default_out()
    assert out.parent == tmp_path / "v" and out.parent.is_dir() and out.suffix == ".pdf"


def test_web_takes_the_options_of_python_m_app_web() -> None:
    args = build_parser().parse_args(
        ["web", "--db", "sqlite://", "--port", "8123", "--verify-url", "https://x.example/v"]
    )
    assert (args.command, args.port, args.verify_url) == ("web", 8123, "https://x.example/v")


@pytest.mark.parametrize(
    ("options", "message"),
    [(["--port", "0"], "--port"), (["--verify-url", "ftp://x"], "verify_url")],
)
def test_web_refuses_bad_options_with_exit_2(options, message, capsys) -> None:
    assert main(["web", "--db", "sqlite://", *options]) == 2
    assert message in capsys.readouterr().err


@pytest.fixture
def db_url(tmp_path: Path) -> str:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    open_engine(url, create=True).dispose()
    return url


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
