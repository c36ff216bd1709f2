"""The records commands end to end through `accelcal` (in process, an SQLite file)."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from app.cli import main
from app.records.db.engine import SCHEMA_HEAD


@pytest.fixture
def db(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    url = f"sqlite:///{tmp_path / 'lab.sqlite'}"
    monkeypatch.setenv("ACCELCAL_DB", url)
    assert main(["db", "upgrade"]) == 0
    return url


def _ok(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 0, err
    return out


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2, out + err
    assert "Traceback" not in err and "error" in err.splitlines()[-1]
    return err


def test_a_lab_day_through_the_command_line(
    db: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    assert f"schema already at {SCHEMA_HEAD}" in _ok(["db", "upgrade"], capsys)
    _ok(["customers", "add", "ACME Ltd"], capsys)
    err = _refused(
        [
            "models",
            "add",
            "PCB",
            "352C33",
            "--nominal",
            "10.2",
            "--unit",
            "mV/ms2",
            "--tolerance",
            "5",
            "--fmin",
            "1",
            "--fmax",
            "10000",
        ],
        capsys,
    )
    assert "unit: unknown unit 'mV/ms2'" in err
    _ok(
        [
            "models",
            "add",
            "PCB",
            "352C33",
            "--nominal",
            "100",
            "--unit",
            "mV/g",
            "--tolerance",
            "5",
            "--fmin",
            "1",
            "--fmax",
            "10000",
        ],
        capsys,
    )
    _ok(["sensors", "add", "SN-7", "--model", "352C33", "--owner", "ACME Ltd"], capsys)
    assert "serial: 'SN-7' already exists" in _refused(
        ["sensors", "add", "SN-7", "--model", "352C33", "--owner", "ACME Ltd"], capsys
    )
    assert "--interval: must be in [1, 120] months" in _refused(
        ["sensors", "add", "SN-8", "--model", "352C33", "--owner", "ACME Ltd", "--interval", "0"],
        capsys,
    )
    assert _ok(["sensors", "list"], capsys) == "SN-7\tPCB 352C33\tACME Ltd\n"
    shown = _ok(["sensors", "show", "SN-7"], capsys)
    assert "nominal:    100 mV/g" in shown and "last run:   none on record" in shown
    assert "serial: no sensor 'SN-0'" in _refused(["sensors", "show", "SN-0"], capsys)

    table = tmp_path / "ref.csv"
    table.write_text(  # the uncertainty in percent (issue 24): 0.5 means 0.5 %
        "frequency_hz,sensitivity_mv_per_ms2,relative_expanded_uncertainty_percent\n"
        "160,0.125,0.5\n1000,0.126,0.6\n"
    )
    _ok(
        [
            "refs",
            "add",
            "REF-1",
            "--model",
            "8305",
            "--serial",
            "1",
            "--certificate",
            "PTB-9",
            "--calibrated",
            "2026-01-10",
            "--due",
            "2027-01-10",
            "--table",
            str(table),
        ],
        capsys,
    )
    bad = tmp_path / "bad.csv"
    bad.write_text("160,0.125,0.005\n1000,abc,0.006\n")
    assert f"{bad} line 2: not a number" in _refused(
        [
            "refs",
            "add",
            "REF-2",
            "--model",
            "8305",
            "--serial",
            "2",
            "--certificate",
            "X",
            "--calibrated",
            "2026-01-10",
            "--due",
            "2027-01-10",
            "--table",
            str(bad),
        ],
        capsys,
    )
    assert "PTB-9" in _ok(["refs", "list"], capsys)
    due = _ok(["due", "--days", "30"], capsys)
    assert "sensor    SN-7\tACME Ltd\tnever calibrated here" in due
    assert "REF-1" not in due
    assert "--days: must be in [0, 3650] days" in _refused(["due", "--days", "-1"], capsys)
    assert "drift: needs two calibrations at least 30 days apart" in _ok(
        ["history", "SN-7"], capsys
    )
    assert "no calibrations of SN-7" in _refused(
        ["history", "SN-7", "--plot", str(tmp_path / "d.png")], capsys
    )
    assert _ok(["register", "list"], capsys) == ""
    assert "certificate_pattern" in _refused(
        ["register", "set", "certificate_pattern", "X-{year}"], capsys
    )


def test_a_database_at_an_older_schema_is_refused_with_what_to_do(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "empty.sqlite"
    url = f"sqlite:///{path}"
    err = _refused(["sensors", "list", "--db", url], capsys)
    assert "does not exist; `accelcal db upgrade` creates it" in err and not path.exists()
    sqlite3.connect(path).close()  # an empty database: no schema at all
    err = _refused(["sensors", "list", "--db", url], capsys)
    assert "no accelcal schema; run `accelcal db upgrade`" in err
