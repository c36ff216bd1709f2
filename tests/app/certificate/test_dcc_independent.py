"""The DCC of every issuing path passes an independent validator, offline, and an independent
reader reads back the run's numbers (issue 35 point 3's acceptance): the CLI's certificate
(signed), an amendment through the records' register, the GUI's certificate dialog, and the
demo (`make demo`'s own commands, read from the Makefile). The validator and reader are
dcclib's (tests/app/certificate/independent_dcc.py): PTB's XSD through libxml2, the DCC
Schematron through Saxon, dcc-json-toolkit's decoding; none of them is this program's code."""

from __future__ import annotations

import os
import re
import shlex
from collections.abc import Iterator
from pathlib import Path

import pytest
from pypdf import PdfReader

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from app.cli import main
from tests.app.certificate.conftest import SENSOR, Lab, Pki, _new_run, copy_run
from tests.app.certificate.independent_dcc import (
    Independent,
    assert_reads_back_as_the_run,
    read_back,
)

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parents[3]
ITEMS = ("--authorised-by", "J. Smith", "--prepared-by", "A. Tech", "--temperature", "23",
         "--mounting", "stud, 2 N m",
         "--customer-address", "1 Test Street, 00-001 Testtown")  # fmt: skip


@pytest.fixture(scope="module")
def independent(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Independent]:
    with Independent.offline(tmp_path_factory.mktemp("dcc-cache")) as tools:
        yield tools


def check(independent: Independent, pdf: Path, run: Path) -> dict[str, object]:
    """The DCC beside `pdf` (the one attached to it, byte for byte) valid to the independent
    validator, read back equal to `run`; what was read back."""
    xml = pdf.with_suffix(".xml").read_bytes()
    (attached,) = PdfReader(pdf).attachments["certificate.xml"]
    assert attached == xml
    assert independent.problems(xml) == []
    found = read_back(independent.read(xml))
    assert_reads_back_as_the_run(found, run)
    assert re.fullmatch(r"v\d+(\.\d+){0,3}", str(found["release"])), found["release"]
    return found


def test_the_validator_is_independent_and_refuses_a_broken_dcc(
    independent: Independent, complete_run: Path, tmp_path: Path
) -> None:
    """The validator is not blind: a DCC with a status outside DCC's list, or a release the
    Schematron refuses, is named; the reader's numbers follow the file, not the run."""
    run = copy_run(complete_run, tmp_path / "runs")
    assert main(["certificate", str(run), "--customer", "ACME Ltd", *ITEMS]) == 0
    xml = (run / "certificate.xml").read_bytes()
    assert independent.problems(xml) == []
    bad_status = xml.replace(b"<dcc:conformityXMLList>pass", b"<dcc:conformityXMLList>ok", 1)
    assert any("conformityXMLList" in p for p in independent.problems(bad_status))
    bad_release = re.sub(rb"<dcc:release>[^<]*<", b"<dcc:release>0.1.dev1+g1<", xml)
    assert any("release" in p for p in independent.problems(bad_release))
    moved = re.sub(rb"(<dcc:conformityXMLList>)pass", rb"\1fail", xml, count=1)
    with pytest.raises(AssertionError):
        assert_reads_back_as_the_run(read_back(independent.read(moved)), run)


def test_the_cli_certificate_signed(
    independent: Independent, complete_run: Path, pki: Pki, sign_password: str, tmp_path: Path
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "signed.pdf"
    argv = ["certificate", str(run), "--customer", "ACME Ltd", "--sign", str(pki.key), *ITEMS]
    assert main([*argv, "--out", str(pdf)]) == 0
    check(independent, pdf, run)
    assert b"<ds:Signature" in pdf.with_suffix(".xml").read_bytes()


def test_an_amendment_through_the_records_register(
    independent: Independent, lab: Lab, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _new_run(lab.runs, "--sensor", SENSOR, "--seed", "11", "--tolerance", "5",
                   "--db", lab.url)  # fmt: skip
    capsys.readouterr()
    assert main(["certificate", str(run), "--db", lab.url, *ITEMS]) == 0
    original = re.search(r"^certificate (\S+): ", capsys.readouterr().out, re.M)
    assert original is not None
    argv = ["certificate", str(run), "--db", lab.url, "--replaces", original.group(1),
            "--reason", "mounting corrected", *ITEMS]  # fmt: skip
    assert main(argv) == 0
    check(independent, run / "certificate.pdf", run)
    amended = run / "certificate-2.pdf"
    check(independent, amended, run)
    core = independent.read(amended.with_suffix(".xml").read_bytes())["dcc:administrativeData"]
    previous = core["dcc:coreData"]["dcc:previousReport"]
    assert previous["dcc:referralID"] == original.group(1)
    assert previous["dcc:description"]["dcc:content"][0]["$"] == "mounting corrected"


def test_the_gui_certificate_dialog(
    independent: Independent,
    complete_run: Path,
    tmp_path: Path,
    qtbot: object,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from tests.app.certificate.test_issue_matrix import GUI_FIELDS, Person, _window

    monkeypatch.setenv("ACCELCAL_DB", f"sqlite:///{tmp_path / 'none.sqlite'}")  # no records
    run = copy_run(complete_run, tmp_path / "runs")
    window = _window(qtbot, run.parent, None)
    assert window.open_run(run)
    person = Person(monkeypatch, {**GUI_FIELDS, "customer": "ACME Ltd"})
    pdf = window.certificate_action()
    assert pdf == run / "certificate.pdf" and not person.refusals, person.refusals
    check(independent, pdf, run)


def _demo_commands(demo: Path) -> list[list[str]]:
    """`make demo`'s accelcal commands (`run` and `certificate`), as the Makefile states them,
    with DEMO_DIR set to `demo`."""
    text = (ROOT / "Makefile").read_text(encoding="utf-8").replace("\\\n", " ")
    recipe = re.search(r"^demo: \$\(RUNTIME_STAMP\)\n((?:\t.*\n)+)", text, re.M)
    assert recipe is not None, "the Makefile has no demo recipe"
    commands = []
    for line in recipe.group(1).splitlines():
        line = line.strip().replace("$(DEMO_DIR)", str(demo))
        if not line.startswith("$(BIN)/accelcal "):
            continue
        newest = "$$(ls -dt " + str(demo) + "/runs/*/ | head -n 1)"
        line = line.replace(newest, "NEWEST_RUN")
        argv = shlex.split(line)[1:]
        if argv[0] in ("run", "certificate"):
            commands.append(argv)
    assert [c[0] for c in commands] == ["run", "run", "certificate"], commands
    return commands


def test_the_demo(
    independent: Independent, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    demo = tmp_path / "demo-output"
    monkeypatch.setenv("ACCELCAL_DATA_DIR", str(demo / "data"))
    monkeypatch.delenv("ACCELCAL_DB", raising=False)  # as `make demo` runs: its own data dir
    for argv in _demo_commands(demo):
        if "NEWEST_RUN" in argv:
            newest = max((demo / "runs").iterdir(), key=lambda p: p.stat().st_mtime_ns)
            argv = [str(newest) if a == "NEWEST_RUN" else a for a in argv]
        assert main(argv) == 0, argv
    (pdf,) = (demo / "runs").glob("*/certificate.pdf")
    check(independent, pdf, pdf.parent)


def test_the_certificates_of_a_several_dut_run(
    independent: Independent, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 36: each member's certificate of a run of several DUTs (`certificate --batch`),
    with its statement of the fixture position, passes the independent validator and reads
    back as its own run."""
    monkeypatch.chdir(tmp_path)
    stand = ROOT / "sim" / "stand-fixture4.toml"
    duts = ["--dut", "A=SN-1", "--dut", "B=SN-2"]
    argv = ["run", "--stand", str(stand), *duts, "--technician", "A. Tech", "--tolerance", "5"]
    assert main(argv) == 0
    (batch,) = [p for p in (tmp_path / "runs").iterdir() if (p / "batch.json").exists()]
    assert main(["certificate", "--batch", batch.name, "--customer", "ACME Ltd", *ITEMS]) == 0
    members = [p for p in (tmp_path / "runs").iterdir() if (p / "certificate.pdf").exists()]
    assert len(members) == 2
    for run in members:
        check(independent, run / "certificate.pdf", run)
        assert b'refType="vib_fixturePosition"' in (run / "certificate.xml").read_bytes()
