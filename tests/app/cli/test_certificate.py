"""The technician who ran a calibration (issue 27): `run --technician` (the GUI's Technician
field) stores it in config.json and results.json; `accelcal certificate` prints it as
"Prepared by" unless --prepared-by says otherwise, and refuses by --prepared-by (exit 2) a run
that records none instead of printing a login name."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.cli import main
from app.records.db.audit import current_actor

pytestmark = pytest.mark.integration

ITEMS = ["--customer", "ACME Ltd",
         "--customer-address", "1 Test Street, 00-001 Testtown",
         "--authorised-by", "J. Smith", "--temperature", "23",
         "--mounting", "stud"]  # fmt: skip


def _run(out: Path, *extra: str) -> Path:
    before = set(out.iterdir()) if out.exists() else set()
    argv = ["run", "--sim", "--dut", "piezo", "--dut-id", "SN-T", "--periods", "3"]
    assert main([*argv, "--out", str(out), *extra]) == 0
    (folder,) = set(out.iterdir()) - before
    return folder


def _prepared_by(pdf: Path) -> str:
    text = "\n".join(page.extract_text() for page in PdfReader(pdf).pages)
    lines = [line.strip() for line in text.splitlines()]
    return lines[lines.index("Prepared by") + 1]  # the sign-off table: label, then name


def test_the_runs_technician_prepares_the_certificate(tmp_path: Path, capsys) -> None:
    run = _run(tmp_path / "runs", "--technician", "  A. Tech ")
    assert json.loads((run / "config.json").read_text())["identity"]["technician"] == "A. Tech"
    assert json.loads((run / "results.json").read_text())["technician"] == "A. Tech"
    assert main(["certificate", str(run), *ITEMS]) == 0
    assert _prepared_by(run / "certificate.pdf") == "A. Tech"
    capsys.readouterr()


def test_a_run_without_technician_needs_prepared_by(tmp_path: Path, capsys) -> None:
    run = _run(tmp_path / "runs")
    capsys.readouterr()
    assert "technician" not in json.loads((run / "results.json").read_text())
    assert main(["certificate", str(run), *ITEMS]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.strip().splitlines()[-1].endswith(
        "--prepared-by: the run records no technician (accelcal run --technician NAME); "
        "name who prepared the certificate"
    )
    assert not list(run.glob("certificate*"))
    assert main(["certificate", str(run), *ITEMS, "--prepared-by", "B. Other"]) == 0
    name = _prepared_by(run / "certificate.pdf")
    assert name == "B. Other" and name != current_actor()


def _file_size_limit(limit_bytes: int):  # type: ignore[no-untyped-def]
    import resource

    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return apply


def test_a_full_disk_while_issuing_exits_2_naming_the_path_and_what_was_kept(
    complete_run: Path, tmp_path: Path
) -> None:
    """Issue 33 point 6: a full disk during `certificate` ended in exit 1 "OSError" (nothing
    torn). Now: exit 2, one line naming the file that could not be written and what was kept;
    no certificate, no staged file, no register entry. The disk is filled as the run's
    disk-full tests do: a file-size limit (RLIMIT_FSIZE) below the PDF's size (EFBIG)."""
    import os
    import shutil
    import subprocess
    import sys

    runs = tmp_path / "runs"
    run = runs / complete_run.name
    shutil.copytree(complete_run, run)
    before = sorted(p.name for p in runs.rglob("*"))
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[3])}
    env["ACCELCAL_DATA_DIR"] = str(tmp_path / "data")  # no records database: the JSON register
    env.pop("ACCELCAL_DB", None)
    process = subprocess.run(
        [sys.executable, "-m", "app", "certificate", str(run), *ITEMS],
        preexec_fn=_file_size_limit(20_000),  # the PDF (over 100 kB) does not fit
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert process.returncode == 2, process.stderr
    line = process.stderr.strip().splitlines()[-1]  # after any warning (no validation report)
    assert "Traceback" not in process.stderr and "OSError" not in process.stderr
    assert "error: disk full: " in line and "File too large" in line
    assert f"certificate {run / 'certificate.pdf'} not issued" in line
    assert "kept: nothing of it was written" in line and "run folder's register" in line
    assert sorted(p.name for p in runs.rglob("*")) == before  # nothing torn, nothing left
