"""Issuing through the records (issue 24 points 1 and 5, issue 23 point 4), on SQLite and
PostgreSQL: identity, issue date, one certificate per run, same-sensor amendments, the
homoglyph signatory, and a SIGKILL at each step of issuance leaving every certificate file in
the register and the next number unused."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import pytest
from sqlalchemy import Engine

from app.certificate.leftovers import LeftoverKind, carried_number
from app.certificate.register_issue import leftovers_in_records
from app.cli import main
from app.records.db.engine import DatabaseError, open_engine, records_url
from app.records.db.lab import Lab, RecordsError
from tests.records_db import add_staff, seed_lab

BASE = [
    "--prepared-by",
    "A. Tech",
    "--authorised-by",
    "J. Smith",
    "--temperature",
    "23",
    "--mounting",
    "stud",
]


def _lab(url: str) -> Lab:
    lab = Lab(open_engine(url), actor="t")
    return seed_lab(lab, {"SN-42": "ACME Ltd", "SN-43": "Other GmbH"}, nominal_sensitivity=10.0)


@pytest.fixture
def url(engine: Engine) -> str:
    """A migrated database on each engine holding sensors SN-42 (ACME) and SN-43 (Other)."""
    resolved = engine.url.render_as_string(hide_password=False)
    _lab(resolved)
    return resolved


def _copy(run: Path, to: Path) -> Path:
    target = to / run.name
    shutil.copytree(run, target)
    return target


def _other_run(root: Path) -> Path:
    from app.procedure.run import RunRequest, execute

    finished = execute(RunRequest(dut="piezo", dut_id="SN-43", periods=3, out=root))
    return root / str(finished.record.run_id)


def _cert(folder: Path, url: str, *extra: str) -> list[str]:
    return ["certificate", str(folder), "--db", url, *BASE, *extra]


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def test_identity_date_one_per_run_and_same_sensor_amendments(
    url: str, complete_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(complete_run, tmp_path)
    err = _refused(_cert(run, url, "--dut-serial", "OTHER-123"), capsys)
    assert "--dut-serial: 'OTHER-123' is not the run's 'SN-42'" in err
    err = _refused(
        _cert(
            run,
            url,
            "--customer",
            "Other GmbH",
            "--customer-address",
            "1 Test Street, 00-001 Testtown",
        ),
        capsys,
    )
    assert "--customer: 'Other GmbH' is not the run's 'ACME Ltd'" in err
    err = _refused(_cert(run, url, "--issue-date", "2020-01-01"), capsys)
    assert "issue_date (--issue-date): 2020-01-01 is before the calibration" in err
    assert not list(run.glob("certificate*")) and Lab(open_engine(url)).register() == []
    assert main(_cert(run, url)) == 0
    (first,) = Lab(open_engine(url)).register()
    assert first.issued_utc.date() == datetime.now(UTC).date()
    assert first.file == str((run / "certificate.pdf").resolve())
    err = _refused(_cert(run, url, "--out", str(tmp_path / "again.pdf")), capsys)
    assert f"already has certificate {first.number}" in err and "--replaces" in err
    with pytest.raises(RecordsError, match=f"already has certificate {first.number}"):
        Lab(open_engine(url)).issue_certificate(  # the records' own rule, whoever calls
            run_id=first.run.run_id, prepared_by="A", approved_by="B"
        )
    other = _copy(_other_run(tmp_path / "o"), tmp_path)
    argv = _cert(other, url, "--replaces", first.number, "--reason", "x")
    err = _refused(argv, capsys)
    assert f"replaces: {first.number} is a certificate of sensor SN-42, not of SN-43" in err
    assert not (other / "certificate.pdf").exists() and not (tmp_path / "again.pdf").exists()
    amended = tmp_path / "amended.pdf"
    argv = _cert(run, url, "--replaces", first.number, "--reason", "address", "--out", str(amended))
    assert main(argv) == 0
    states = [(c.number, c.state) for c in Lab(open_engine(url)).register()]
    assert [s for _, s in states] == ["replaced", "issued"]
    assert carried_number(amended) == states[1][0]


def test_with_the_default_records_file_no_certificate_is_unregistered(
    complete_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch
) -> None:
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    assert records_url() is None  # no file yet: per-folder numbering
    with pytest.raises(DatabaseError, match="does not exist"):  # opening never creates it
        open_engine(None)
    assert records_url() is None
    Lab(open_engine(None, create=True)).add_customer(
        "ACME Ltd", "1 Test Street"
    )  # as `db upgrade`; no SN-42
    assert records_url() is not None
    run = _copy(complete_run, tmp_path)
    argv = [
        "certificate",
        str(run),
        *BASE,
        "--customer",
        "ACME Ltd",
        "--customer-address",
        "1 Test Street, 00-001 Testtown",
        "--dut-model",
        "m",
    ]
    err = _refused(argv, capsys)
    assert "no sensor 'SN-42'" in err
    assert not list(run.glob("certificate*"))


def test_without_records_the_certificate_says_where_its_number_comes_from(
    complete_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch
) -> None:
    from pypdf import PdfReader

    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    run = _copy(complete_run, tmp_path)
    argv = [
        "certificate",
        str(run),
        *BASE,
        "--customer",
        "ACME Ltd",
        "--customer-address",
        "1 Test Street, 00-001 Testtown",
    ]
    assert main(argv) == 0
    text = " ".join(p.extract_text() for p in PdfReader(run / "certificate.pdf").pages)
    assert "no records database" in " ".join(text.split())


@pytest.mark.parametrize(
    ("prepared", "approved", "message"),
    [
        ("Alice", "Alice\u200b", "two-person rule"),
        ("Alice", " alice ", "two-person rule"),
        ("Alice", "ALICE", "two-person rule"),
        ("Alice", "\u0410lice", "approved by: 'Аlice' mixes scripts (Cyrillic, Latin)"),
        ("\u0410lice", "Bob", "prepared by: 'Аlice' mixes scripts"),
        ("Alice", "\u0410\u0421\u0415", "approved by: 'АСЕ' is written in Cyrillic letters"),
    ],
)
def test_signatories_are_one_person_whatever_the_spelling(
    engine: Engine, prepared: str, approved: str, message: str
) -> None:
    lab = Lab(engine, actor="t")
    add_staff(engine, ("alice", "Alice"), ("bob", "Bob"), ("alisa", "Алиса"))
    lab.set_setting("two_person_rule", "on")
    with pytest.raises(RecordsError, match=re.escape(message)):
        lab.check_signatories(prepared, approved)
    assert lab.check_signatories("Alice", "Bob\u200b") == ("Alice", "Bob")
    assert lab.check_signatories("Алиса", "Bob")[0] == "Алиса"  # one script: a name


KILLER = """
import os, signal, sys
from app.certificate import issuing
def hook(name):
    if name == sys.argv[1]:
        os.kill(os.getpid(), signal.SIGKILL)
issuing.step_hook = hook
from app.cli import main
sys.exit(main(sys.argv[2:]))
"""
STEPS = ("numbered", "staged", "committed", "dcc_published", "published")


@pytest.mark.parametrize("step", STEPS)
def test_a_kill_at_any_step_leaves_every_certificate_file_in_the_register(
    url: str, complete_run: Path, tmp_path: Path, step: str, capsys
) -> None:
    run = _copy(complete_run, tmp_path)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[4])}
    killed = subprocess.run(
        [sys.executable, "-c", KILLER, step, *_cert(run, url)], env=env, capture_output=True
    )
    assert killed.returncode == -9, killed.stderr.decode()
    lab = Lab(open_engine(url))
    crashed = lab.register()
    committed = step in ("committed", "dcc_published", "published")
    assert len(crashed) == (1 if committed else 0)
    pending = {(x.path.suffix, x.kind) for x in leftovers_in_records(lab)}  # db verify's view
    if step in ("committed", "dcc_published"):
        assert (".tmp", LeftoverKind.COMMITTED) in pending
    else:
        assert not pending
    extra = ("--replaces", crashed[0].number, "--reason", "re-issued") if committed else ()
    out = run / "certificate-2.pdf"
    assert main(_cert(run, url, "--out", str(out), *extra)) == 0, capsys.readouterr().err
    rows = {c.file: c for c in lab.register()}
    files = sorted(run.glob("certificate*.pdf"))
    assert len(files) == (2 if committed else 1)
    for pdf in files:  # every certificate file is in the register, with its own number
        row = rows[str(pdf.resolve())]
        assert carried_number(pdf) == row.number
        from app.records.run_folder import sha256_of

        assert sha256_of(pdf) == row.sha256
        assert (
            carried_number(pdf.with_suffix(".xml")) == row.number
            or not pdf.with_suffix(".xml").exists()
        )
    assert len({c.number for c in rows.values()}) == len(rows)
    assert not [p for p in run.iterdir() if p.name.endswith(".tmp")]


def test_a_certificate_file_no_register_holds_is_cleared_and_its_number_not_reused(
    url: str, complete_run: Path, tmp_path: Path, capsys, monkeypatch
) -> None:
    """As an older version killed between its PDF and its register entry left it."""
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    run = _copy(complete_run, tmp_path)
    argv = [
        "certificate",
        str(run),
        *BASE,
        "--customer",
        "ACME Ltd",
        "--customer-address",
        "1 Test Street, 00-001 Testtown",
        "--dut-model",
        "PCB 352C33",
    ]
    assert main(argv) == 0  # without records: AC-<run id> in the root's JSON register
    orphan = run / "certificate.pdf"
    number = carried_number(orphan)
    assert number is not None and number.startswith("AC-")
    (tmp_path / "certificate-register.json").unlink()  # the entry never made
    assert main(_cert(run, url, "--out", str(run / "certificate-2.pdf"))) == 0
    assert not orphan.exists() and not orphan.with_suffix(".xml").exists()
    (row,) = Lab(open_engine(url)).register()
    assert carried_number(run / "certificate-2.pdf") == row.number != number
