"""Issue 33 point 2, by the CLI: `accelcal db verify` checks signed certificates fully against
`--trust` (or the lab's trust store, $ACCELCAL_TRUST), and compares every registered
certificate file with the register's SHA-256, signed or not: one certificate's PDF swapped for
another's, an unsigned PDF edited, a DCC swapped, a PDF removed, each is named."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from app.cli import main
from tests.app.certificate.conftest import ROOT, Pki, _cli, _new_run
from tests.app.certificate.throwaway_ca import PASSWORD

# a lab of its own (two runs, two certificates: the first unsigned, the second signed), made
# once for the module: about two simulated runs and two certificates
pytestmark = pytest.mark.slow

ITEMS = ("--authorised-by", "J. Smith", "--prepared-by", "A. Tech", "--temperature", "23",
         "--mounting", "stud")  # fmt: skip


@dataclass(frozen=True)
class Certified:
    """The lab's records URL and its two certificates (number, PDF): unsigned, signed."""

    url: str
    unsigned: tuple[str, Path]
    signed: tuple[str, Path]


@pytest.fixture(scope="module")
def certified(tmp_path_factory: pytest.TempPathFactory, pki: Pki) -> Certified:
    base = tmp_path_factory.mktemp("db-verify-lab")
    url = f"sqlite:///{base / 'records.sqlite'}"
    today = datetime.now(UTC).date()
    _cli("db", "upgrade", "--db", url)
    _cli("customers", "add", "ACME Ltd", "--address", "1 Test Street", "--db", url)
    _cli("models", "add", "PCB", "352C33", "--nominal", "100", "--unit", "mV/g",
         "--tolerance", "5", "--fmin", "1", "--fmax", "10000", "--db", url)  # fmt: skip
    _cli("sensors", "add", "SN-7", "--model", "352C33", "--owner", "ACME Ltd", "--db", url)
    _cli("refs", "add", "REF-8305-SIM", "--model", "B&K 8305", "--serial", "SIM-0001",
         "--certificate", "PTB-1", "--calibrated", str(today - timedelta(days=30)),
         "--due", str(today + timedelta(days=300)), "--table", ROOT / "examples/ref-table.csv",
         "--db", url)  # fmt: skip
    runs = [
        _new_run(base / "runs", "--sensor", "SN-7", "--seed", str(seed), "--db", url)
        for seed in (11, 12)
    ]
    os.environ["ACCELCAL_SIGN_PASSWORD"] = PASSWORD
    try:
        _cli("certificate", runs[0], "--db", url, *ITEMS)
        _cli("certificate", runs[1], "--db", url, "--sign", pki.key, *ITEMS)
    finally:
        del os.environ["ACCELCAL_SIGN_PASSWORD"]
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab

    engine = open_engine(url)
    numbers = [c.number for c in Lab(engine).register()]
    engine.dispose()
    return Certified(
        url, (numbers[0], runs[0] / "certificate.pdf"), (numbers[1], runs[1] / "certificate.pdf")
    )


def _db_verify(capsys: pytest.CaptureFixture[str], *argv: str | Path) -> tuple[int, str]:
    capsys.readouterr()
    code = main(["db", "verify", *map(str, argv)])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return code, captured.out


@pytest.fixture
def restore(certified: Certified) -> Iterator[None]:
    """Whatever a test does to the certificate files is undone after it."""
    files = [
        p
        for _, pdf in (certified.unsigned, certified.signed)
        for p in (pdf, pdf.with_suffix(".xml"))
    ]
    kept = {p: (p.read_bytes(), p.stat().st_mode) for p in files}
    yield
    for path, (data, mode) in kept.items():
        if path.exists():
            path.chmod(0o644)
        path.write_bytes(data)
        path.chmod(mode)


def test_a_signed_certificate_is_verified_against_the_trust_given_or_the_lab_store(
    certified: Certified, pki: Pki, capsys: pytest.CaptureFixture[str], monkeypatch
) -> None:
    number = certified.signed[0]
    code, out = _db_verify(capsys, "--db", certified.url)
    assert code == 2  # a lab that signs: without its CA nothing signed is trusted
    assert f"({number}): {certified.signed[1]}: signer trust" in out
    assert certified.unsigned[0] not in out  # the unsigned one's DCC, run and file hold
    assert _db_verify(capsys, "--db", certified.url, "--trust", pki.ca)[0] == 0
    monkeypatch.setenv("ACCELCAL_TRUST", str(pki.ca))  # the lab's trust store
    code, out = _db_verify(capsys, "--db", certified.url)
    assert code == 0 and "records verified" in out
    monkeypatch.setenv("ACCELCAL_TRUST", str(pki.ca.parent / "missing.pem"))
    assert main(["db", "verify", "--db", certified.url]) == 2
    assert "$ACCELCAL_TRUST: no such file" in capsys.readouterr().err


def _writable(path: Path) -> Path:
    path.chmod(0o644)
    return path


@pytest.mark.parametrize(
    "attack",
    ["signed PDF over the unsigned one", "unsigned PDF over the signed one",
     "unsigned PDF edited", "DCC swapped", "PDF removed"],
)  # fmt: skip
def test_every_certificate_file_is_compared_with_the_register(
    certified: Certified, pki: Pki, capsys: pytest.CaptureFixture[str], restore: None, attack: str
) -> None:
    (first, unsigned), (second, signed) = certified.unsigned, certified.signed
    victim, what = {
        "signed PDF over the unsigned one": (first, "not the certificate PDF registered"),
        "unsigned PDF over the signed one": (second, "not the certificate PDF registered"),
        "unsigned PDF edited": (first, "not the certificate PDF registered"),
        "DCC swapped": (first, "not the certificate DCC registered"),
        "PDF removed": (second, "the registered certificate PDF is missing"),
    }[attack]
    if attack == "signed PDF over the unsigned one":
        shutil.copyfile(signed, _writable(unsigned))
    elif attack == "unsigned PDF over the signed one":
        shutil.copyfile(unsigned, _writable(signed))
    elif attack == "unsigned PDF edited":
        data = unsigned.read_bytes()
        _writable(unsigned).write_bytes(data.replace(b"stud", b"glue", 1))
        assert unsigned.read_bytes() != data
    elif attack == "DCC swapped":
        shutil.copyfile(signed.with_suffix(".xml"), _writable(unsigned.with_suffix(".xml")))
    else:
        signed.chmod(0o644)
        signed.unlink()
    code, out = _db_verify(capsys, "--db", certified.url, "--trust", pki.ca)
    assert code == 2
    broken = [line for line in out.splitlines() if line.startswith("BROKEN certificates")]
    assert any(f"({victim}): " in line and what in line for line in broken), out
