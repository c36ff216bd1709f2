"""Closing a certificate review (issue 27, ISO/IEC 17025 7.10), on SQLite and PostgreSQL:
confirmed only while the certificate stands, amended only by an amendment of the same sensor
that replaces it (each refusal names why); who, why and when kept, audited and chained
(`db verify` passes); `register review` and `register reviews` on the command line."""

from __future__ import annotations

import contextlib
import json
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import Engine, select, text

from app.cli import main
from app.procedure.run import RunRequest, execute
from app.records.db.lab import Lab, RecordsError
from app.records.db.models import AuditEntry, Certificate
from app.records.db.reviews import impact_subject
from tests.records_db import seed_lab

SUBJECT = impact_subject("SIM-0001")


@pytest.fixture(scope="module")
def other_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A complete run of sensor SN-43 (another sensor than the session's SN-42 run)."""
    out = tmp_path_factory.mktemp("other")
    finished = execute(RunRequest(dut="piezo", dut_id="SN-43", periods=3, out=out))
    return out / str(finished.record.run_id)


@pytest.fixture
def lab_numbers(
    engine: Engine, complete_run: Path, other_run: Path, tmp_path: Path
) -> tuple[Lab, str, str, str]:
    """Records with certificate A of SN-42's run (under review for SUBJECT), its amendment B
    (same run, replaces A) not yet issued, and C of SN-43's run: (lab, url, A, C)."""
    lab = Lab(engine, actor="qm")
    seed_lab(lab, {"SN-42": "ACME Ltd", "SN-43": "ACME Ltd"}, nominal_sensitivity=10.0)
    for run in (complete_run, other_run):
        copy = tmp_path / "runs" / run.name
        shutil.copytree(run, copy)
        assert lab.import_runs(copy).imported
    a = lab.issue_certificate(
        run_id=complete_run.name, prepared_by="P. Rep", approved_by="A. Pro"
    ).number
    c = lab.issue_certificate(run_id=other_run.name, prepared_by="P. Rep", approved_by="A. Pro")
    assert lab.open_review(a, subject=SUBJECT, reason="under review: impact of reference SIM-0001")
    return lab, engine.url.render_as_string(hide_password=False), a, c.number


def _review_updates(engine: Engine) -> list[AuditEntry]:
    with engine.connect() as conn:
        rows = conn.execute(
            select(AuditEntry.__table__).where(
                AuditEntry.table_name == "certificate_reviews", AuditEntry.action == "update"
            )
        ).all()
    return list(rows)


def test_a_review_is_confirmed_with_who_and_why_audited_and_chained(
    lab_numbers, engine: Engine, capsys: pytest.CaptureFixture[str]
) -> None:
    lab, url, a, _ = lab_numbers
    assert [r.number for r in lab.reviews(open_only=True)] == [a]
    assert lab.reviews(number=a)[0].reference == "SIM-0001"
    with pytest.raises(RecordsError, match="reason: must not be blank"):
        lab.close_review(a, outcome="confirmed", reason="  ")
    with pytest.raises(RecordsError, match="amended by: an amended review names the amendment"):
        lab.close_review(a, outcome="amended", reason="replaced")
    with pytest.raises(RecordsError, match="amended by: a confirmed review names no amendment"):
        lab.close_review(a, outcome="confirmed", reason="stands", amended_by=a)
    assert lab.reviews(open_only=True) and _review_updates(engine) == []  # nothing written
    (closed,) = lab.close_review(a, outcome="confirmed", reason="change 0.1 U: stands")
    assert (closed.outcome, closed.closed_by, closed.close_reason, closed.amended_by) == (
        "confirmed",
        "qm",
        "change 0.1 U: stands",
        None,
    )
    assert closed.closed_utc is not None and lab.reviews(open_only=True) == []
    (entry,) = _review_updates(engine)
    changes = json.loads(entry.changes)
    assert entry.actor == "qm" and changes["close_reason"] == [None, "change 0.1 U: stands"]
    assert changes["outcome"] == [None, "confirmed"] and changes["closed_utc"][1]
    with pytest.raises(RecordsError, match=f"number: {a} has no open review"):
        lab.close_review(a, outcome="confirmed", reason="again")
    assert main(["db", "verify", "--db", url]) == 0, capsys.readouterr().err


@contextlib.contextmanager
def _rules_suspended(engine: Engine) -> Iterator[None]:
    """The certificate rules' triggers off (SQLite: dropped; PostgreSQL: disabled), then back
    exactly as they were (the schema fingerprint unchanged)."""
    with engine.begin() as c:
        if c.dialect.name == "sqlite":
            query = (
                "SELECT name, sql FROM sqlite_master WHERE name LIKE 'records_rule_certificate%'"
            )
            rules = c.execute(text(query)).all()
            for name, _ in rules:
                c.execute(text(f"DROP TRIGGER {name}"))
        else:
            c.execute(text("ALTER TABLE certificates DISABLE TRIGGER records_rule_certificates"))
    yield
    with engine.begin() as c:
        if c.dialect.name == "sqlite":
            for _, sql in rules:
                c.execute(text(sql))
        else:
            c.execute(
                text("ALTER TABLE certificates ENABLE ALWAYS TRIGGER records_rule_certificates")
            )


def test_a_review_is_closed_as_amended_only_by_an_amendment_of_that_certificate(
    lab_numbers, engine: Engine, complete_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lab, url, a, c = lab_numbers
    with pytest.raises(RecordsError, match="amended by: no certificate 'NOPE-1'"):
        lab.close_review(a, outcome="amended", reason="r", amended_by="NOPE-1")
    with pytest.raises(RecordsError, match=f"amended by: {c} replaces none, not {a}"):
        lab.close_review(a, outcome="amended", reason="r", amended_by=c)
    b = lab.issue_certificate(
        run_id=complete_run.name,
        prepared_by="P. Rep",
        approved_by="A. Pro",
        replaces=a,
        reason="sensitivity corrected (impact of SIM-0001)",
    ).number
    with pytest.raises(RecordsError, match=f"number: {a} is replaced, not in force"):
        lab.close_review(a, outcome="confirmed", reason="stands")
    # states the database's rules (migration 0011) no longer let anyone reach: made here with
    # those rules suspended, so that the review's own checks are still tried
    with _rules_suspended(engine), lab.session() as s:  # as if B were withdrawn
        s.scalar(select(Certificate).where(Certificate.number == b)).state = "withdrawn"
    with pytest.raises(RecordsError, match=f"amended by: {b} is withdrawn"):
        lab.close_review(a, outcome="amended", reason="r", amended_by=b)
    with _rules_suspended(engine), lab.session() as s:  # then C pointed at A (other sensor)
        s.scalar(select(Certificate).where(Certificate.number == b)).state = "issued"
        s.scalar(select(Certificate).where(Certificate.number == c)).replaces = a
    with pytest.raises(RecordsError, match=f"amended by: {c} is a certificate of another sensor"):
        lab.close_review(a, outcome="amended", reason="r", amended_by=c)
    assert _review_updates(engine) == []
    (closed,) = lab.close_review(a, outcome="amended", reason="amended: 2 % change", amended_by=b)
    assert (closed.outcome, closed.amended_by, closed.closed_by) == ("amended", b, "qm")
    assert json.loads(_review_updates(engine)[0].changes)["amended_by"] == [None, b]
    assert main(["db", "verify", "--db", url]) == 0, capsys.readouterr().err


def test_register_review_and_reviews_on_the_command_line(
    lab_numbers, capsys: pytest.CaptureFixture[str]
) -> None:
    lab, url, a, c = lab_numbers
    assert main(["register", "reviews", "--db", url]) == 0
    out = capsys.readouterr().out
    assert f"{a}\t" in out and SUBJECT in out and "1 certificate review open" in out
    argv = ["register", "review", a, "--db", url]
    for extra, why in (
        (["--amended-by", c, "--reason", "x"], f"amended by: {c} replaces none, not {a}"),
        (["--confirm", "--reason", " "], "reason: must not be blank"),
        (["--confirm", "--reason", "x"], None),
    ):
        code = main([*argv, *extra])
        captured = capsys.readouterr()
        if why is None:
            assert code == 0 and f"{a}\treview closed: confirmed\t({SUBJECT}; by " in captured.out
        else:
            assert code == 2 and captured.err.strip().splitlines()[-1].endswith(why)
            assert "Traceback" not in captured.err
    assert main(["register", "review", c, "--confirm", "--reason", "x", "--db", url]) == 2
    assert f"number: {c} has no open review" in capsys.readouterr().err
    assert main(["register", "reviews", "--db", url]) == 0
    assert "0 certificate reviews open" in capsys.readouterr().out
    assert lab.reviews()[0].close_reason == "x"


def test_the_register_list_marks_a_certificate_under_review(
    lab_numbers, capsys: pytest.CaptureFixture[str]
) -> None:
    _, url, a, c = lab_numbers
    assert main(["register", "list", "--db", url]) == 0
    lines = {line.split("\t")[0]: line for line in capsys.readouterr().out.splitlines()}
    assert lines[a].endswith(f"UNDER REVIEW ({SUBJECT})") and "UNDER REVIEW" not in lines[c]
