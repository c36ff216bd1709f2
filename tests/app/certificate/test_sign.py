"""Signed certificates: a throwaway CA and lab key (cryptography), `certificate --sign`, and
`accelcal verify` failing on a changed byte, a foreign CA, and a changed run."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from app.cli import main
from tests.app.certificate.throwaway_ca import PASSWORD, make_ca, make_signer


@pytest.fixture(scope="module")
def keys(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The lab's CA, another CA, and the lab's signer key issued by the lab's CA."""
    tmp = tmp_path_factory.mktemp("keys")
    lab = make_ca(tmp, "Test Lab CA")
    other = make_ca(tmp, "Some Other CA")
    return {"p12": make_signer(tmp, "lab.p12", lab), "ca": lab.pem, "other": other.pem}


@pytest.fixture(scope="module")
def signed(keys: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    out = tmp_path_factory.mktemp("runs")
    argv = ["run", "--sim", "--dut", "piezo", "--dut-id", "SN-9", "--periods", "3", "--seed", "4"]
    assert main([*argv, "--out", str(out)]) == 0
    (run,) = out.iterdir()
    pdf = out / "signed.pdf"
    mp = pytest.MonkeyPatch()
    mp.setenv("ACCELCAL_SIGN_PASSWORD", PASSWORD)
    try:
        assert (
            main(
                [
                    "certificate",
                    str(run),
                    "--out",
                    str(pdf),
                    "--customer",
                    "ACME Ltd",
                    "--customer-address",
                    "1 Test Street, 00-001 Testtown",
                    "--prepared-by",
                    "A. Tech",
                    "--authorised-by",
                    "J. Smith",
                    "--temperature",
                    "23",
                    "--mounting",
                    "stud",
                    "--sign",
                    str(keys["p12"]),
                ]
            )
            == 0
        )
    finally:
        mp.undo()
    return run, pdf


def test_a_signed_certificate_verifies_with_its_run_and_ca(
    signed: tuple[Path, Path], keys: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    run, pdf = signed
    capsys.readouterr()
    assert main(["verify", str(pdf), "--run", str(run), "--trust", str(keys["ca"])]) == 0
    out = capsys.readouterr().out
    for check in (
        "ok   signature intact, covering the whole file",
        "ok   signer trusted by the given CA",
        "ok   embedded DCC valid (DCC 3.3.0)",
        "ok   DCC numbers printed in the PDF",
        "ok   run manifest verified",
        "ok   DCC numbers equal the run's results",
    ):
        assert check in out
    assert main(["verify", str(pdf), "--trust", str(keys["other"])]) == 2
    assert "FAIL signer trusted by the given CA" in capsys.readouterr().out


def test_a_changed_byte_fails_verification(
    signed: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, pdf = signed
    data = bytearray(pdf.read_bytes())
    at = data.index(b"/Producer")  # inside the signed byte range, in the document's metadata
    data[at + 2] ^= 0x01
    changed = tmp_path / "changed.pdf"
    changed.write_bytes(bytes(data))
    assert main(["verify", str(changed)]) == 2
    out = capsys.readouterr().out
    assert "FAIL signature intact, covering the whole file" in out
    assert "certificate NOT verified" in out


def test_a_changed_run_fails_verification(
    signed: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run, pdf = signed
    copy = tmp_path / run.name
    shutil.copytree(run, copy)
    results = copy / "results.json"
    results.chmod(0o644)
    results.write_text(results.read_text().replace('"complete"', '"complete" ', 1))
    assert main(["verify", str(pdf), "--run", str(copy)]) == 2
    assert "FAIL run manifest verified" in capsys.readouterr().out


def test_a_wrong_password_is_refused_by_name(
    keys: dict[str, Path],
    signed: tuple[Path, Path],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    run, _ = signed
    monkeypatch.setenv("ACCELCAL_SIGN_PASSWORD", "wrong")
    code = main(
        [
            "certificate",
            str(run),
            "--out",
            str(run.parent / "x.pdf"),
            "--customer",
            "A",
            "--customer-address",
            "1 Test Street, 00-001 Testtown",
            "--prepared-by",
            "A. Tech",
            "--authorised-by",
            "B",
            "--temperature",
            "23",
            "--mounting",
            "stud",
            "--sign",
            str(keys["p12"]),
        ]
    )
    assert code == 2
    assert "--sign:" in capsys.readouterr().err
    assert not (run.parent / "x.pdf").exists()
