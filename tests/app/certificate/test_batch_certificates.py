"""Issue 36's acceptance on the simulated stand: a run of 4 DUTs at the 4 positions of
sim/stand-fixture4.toml gives 4 results, 4 verdicts and 4 signed certificates (one per member,
each its own number, through issue_certificate), each verifying against its own run; every
DUT's stated lines within U of its sensor model's truth (the rigid fixture)."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.cli import main
from app.io.hdf5 import read_recording
from app.records.batch import read_batch

pytestmark = pytest.mark.integration

NS = {"dcc": "https://ptb.de/dcc"}
STAND = Path(__file__).parents[3] / "sim" / "stand-fixture4.toml"
ITEMS = ["--customer", "ACME Ltd",
         "--customer-address", "1 Test Street, 00-001 Testtown",
         "--authorised-by", "J. Smith", "--temperature", "23",
         "--mounting", "stud"]  # fmt: skip


def test_four_duts_give_four_verdicts_and_four_certificates_each_verifying(
    tmp_path: Path, pki, sign_password, monkeypatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    duts = ["--dut", "A=SN-1", "--dut", "B=SN-2", "--dut", "C=SN-3", "--dut", "D=SN-4"]
    argv = ["run", "--stand", str(STAND), *duts, "--dut-model", "C=piezo"]
    assert main([*argv, "--technician", "A. Tech", "--periods", "3", "--seed", "5"]) == 0
    out = capsys.readouterr().out
    assert out.count("VERDICT: PASS") == 4 and "batch " in out
    (batch_folder,) = [p for p in (tmp_path / "runs").iterdir() if (p / "batch.json").exists()]
    batch = read_batch(batch_folder)
    assert [m.serial for m in batch.members] == ["SN-1", "SN-2", "SN-3", "SN-4"]
    runs = [tmp_path / "runs" / m.run_id for m in batch.members]
    for run in runs:
        results = json.loads((run / "results.json").read_text())
        assert results["status"] == "complete" and results["verdict"] == "PASS"
        truth = read_recording(run / "recording.h5").truth
        assert truth is not None
        for line, value in zip(
            results["results"]["lines"], truth.sensitivity_mv_per_ms2, strict=True
        ):
            assert (
                abs(line["sensitivity_mv_per_ms2"] - value)
                <= line["expanded_uncertainty_mv_per_ms2"]
            )

    assert main(["certificate", "--batch", batch.batch_id, *ITEMS, "--sign", str(pki.key)]) == 0
    issued = capsys.readouterr().out
    numbers = {
        line.split()[1].rstrip(":")
        for line in issued.splitlines()
        if line.startswith("certificate ")
    }
    assert len(numbers) == 4  # each its own number
    for member, run in zip(batch.members, runs, strict=True):
        pdf = run / "certificate.pdf"
        assert pdf.exists() and (run / "certificate.xml").exists()
        # the customer reads where on the fixture the DUT was and that the run was shared
        said = f"position {member.position} of the fixture"
        text = " ".join(page.extract_text() for page in PdfReader(pdf).pages)
        assert said in " ".join(text.split()) and batch.batch_id in text.replace("\n", "")
        dcc = ET.parse(run / "certificate.xml").getroot()
        (statement,) = dcc.iterfind(".//dcc:statement[@refType='vib_fixturePosition']", NS)
        declared = statement.find("dcc:declaration/dcc:content", NS)
        assert declared is not None and said in str(declared.text)
        assert "with 3 other DUTs" in str(declared.text)
        assert main(["verify", str(pdf), "--run", str(run), "--trust", str(pki.ca)]) == 0
        verified = capsys.readouterr().out
        assert "certificate verified" in verified
    # a member's certificate does not verify against another member's run
    assert main(["verify", str(runs[0] / "certificate.pdf"), "--run", str(runs[1]),
                 "--trust", str(pki.ca)]) != 0  # fmt: skip
    capsys.readouterr()
    assert main(["show", batch.batch_id]) == 0
    shown = capsys.readouterr().out
    assert all(m.run_id in shown for m in batch.members) and shown.count("PASS") == 4


def test_batch_certificates_refuse_options_naming_one_certificate(
    tmp_path, capsys, monkeypatch
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["certificate", "--batch", "nothing", *ITEMS]) == 2
    assert "--batch: 'nothing' is not a batch folder" in capsys.readouterr().err
    assert main(["certificate", "--batch", "x", "--certificate-number", "N-1", *ITEMS]) == 2
    assert "--certificate-number: names one certificate" in capsys.readouterr().err
