"""Stored formats written before issue 22 stay readable: a run folder and a records database
written by commit 9ca4a21 (tests/data/legacy/README.md says how) are verified, shown,
certified and opened by today's code."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from app.cli import main
from app.records.run_folder import inspect_run, verify_manifest

LEGACY = Path(__file__).resolve().parents[2] / "data" / "legacy"
RUN_ID = "20261125T061413Z-LEG-1-2d8db0"
# read by hand from tests/data/legacy/runs/<RUN_ID>/results.json ("reference") and the database
REFERENCE_S_MV_PER_MS2 = 10.17138167969165
REFERENCE_U_MV_PER_MS2 = 0.07313746029700306
CERTIFICATE_NUMBER = "ACC-2026-0001"


@pytest.fixture()
def legacy_run(tmp_path: Path) -> Path:
    """A copy of the legacy run folder (the stored fixture is never written to)."""
    target = tmp_path / "runs" / RUN_ID
    shutil.copytree(LEGACY / "runs" / RUN_ID, target)
    return target


@pytest.fixture()
def legacy_db(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """A copy of the legacy records database, the default database of the test."""
    target = tmp_path / "lab.sqlite"
    shutil.copyfile(LEGACY / "lab.sqlite", target)
    url = f"sqlite:///{target}"
    monkeypatch.setenv("ACCELCAL_DB", url)
    return url


def _ok(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 0, err
    return out


def test_the_fixture_is_small_and_unchanged() -> None:
    sizes = sum(p.stat().st_size for p in LEGACY.rglob("*") if p.is_file())
    assert sizes < 500_000
    assert verify_manifest(LEGACY / "runs" / RUN_ID) == []


def test_a_legacy_run_folder_verifies_and_loads(legacy_run: Path) -> None:
    assert verify_manifest(legacy_run) == []
    check = inspect_run(legacy_run)
    assert check.state == "complete" and check.certifiable and check.problems == ()
    assert check.record is not None and check.record.run_id == RUN_ID
    reference = check.record.results_object().reference
    assert reference.sensitivity_mv_per_ms2 == pytest.approx(REFERENCE_S_MV_PER_MS2, rel=1e-12)
    assert reference.expanded_uncertainty_mv_per_ms2 == pytest.approx(
        REFERENCE_U_MV_PER_MS2, rel=1e-12
    )


def test_a_legacy_run_folder_is_shown(legacy_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = _ok(["show", str(legacy_run)], capsys)
    assert f"run {RUN_ID}: complete" in out
    assert "Reference sensitivity at 160 Hz: 10.171 mV/(m/s^2)" in out


def test_a_legacy_run_is_refused_a_certificate_naming_the_missing_annex_a_components(
    legacy_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 25 point 1 (a deliberate change): a budget written before components carried
    their ISO 16063-21 Annex A kind states none of them, so the legacy run still reads, shows
    and verifies but is results for review only: no certificate, the missing kinds named."""
    pdf = tmp_path / "certificate.pdf"
    argv = [
        "certificate",
        str(legacy_run),
        "--customer",
        "ACME Ltd",
        "--customer-address",
        "1 Test Street, 00-001 Testtown",
    ]
    argv += ["--authorised-by", "J. Smith", "--temperature", "23", "--mounting", "stud"]
    assert main([*argv, "--out", str(pdf)]) == 2
    err = capsys.readouterr().err
    assert "does not state the ISO 16063-21 Annex A component(s)" in err
    for kind in ("(reference_calibration)", "(temperature)", "(skew)", "(daq_linearity)"):
        assert kind in err
    assert "Traceback" not in err
    assert not pdf.exists()
    assert verify_manifest(legacy_run) == []  # the stored run was not written to


def test_a_legacy_records_database_opens_and_upgrades(
    legacy_db: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _ok(["db", "upgrade"], capsys)
    assert "schema" in out
    _ok(["db", "upgrade"], capsys)  # idempotent
    shown = _ok(["sensors", "show", "LEG-1"], capsys)
    assert "model:      PCB 353B03" in shown and f"last run:   {RUN_ID}" in shown
    assert "nominal:    10.2 mV/(m/s^2)" in shown
    listed = _ok(["register", "list"], capsys)
    assert listed.startswith(
        f"{CERTIFICATE_NUMBER}\tissued\t2026-11-25\trun {RUN_ID}\tsensor LEG-1"
    )
    history = _ok(["history", "LEG-1"], capsys)
    assert f"{RUN_ID}  10.171 mV/(m/s^2) at 160 Hz" in history
