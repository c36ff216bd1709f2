"""Stored runs through the CLI: verified before use, never overwritten, certificates locked and
uniquely numbered, and results of aborted or incomplete recordings never passed for complete."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import re
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import h5py
import pytest
from pypdf import PdfReader

import app.certificate
import app.certificate.issuing
from app.cli import main
from app.io.hdf5 import RecordingWriter, read_recording, write_recording
from app.procedure.run import RunRequest, execute
from app.procedure.simulate import simulate
from app.records.register import REGISTER_NAME
from app.records.run_folder import MANIFEST_NAME, try_lock, unlock
from sim.stand import Fault

REPO = Path(__file__).resolve().parents[3]
INFO_ARGS = [
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
]
INFO = {
    "customer": "ACME Ltd",
    "customer_address": "1 Test Street, 00-001 Testtown",
    "authorised_by": "J. Smith",
    "temperature_c": 23.0,
    "mounting": "stud",
}


@pytest.fixture(scope="module")
def stored(tmp_path_factory, complete_run, aborted_run):
    """Two complete runs and an aborted one, as the procedure leaves them (read-only): the
    session's complete (SN-42) and aborted runs, and one more of SN-2."""
    out = tmp_path_factory.mktemp("stored")
    finished = execute(RunRequest(dut="piezo", dut_id="SN-2", periods=4, seed=2, out=out))
    runs = {"a": complete_run, "b": out / finished.record.run_id, "aborted": aborted_run}
    assert [load(runs[k])["status"] for k in ("a", "b", "aborted")] == [
        "complete",
        "complete",
        "aborted",
    ]
    return runs


def load(path: Path) -> dict:
    return json.loads((path / "results.json").read_text())


@pytest.fixture
def root(tmp_path, stored):
    """A fresh runs root holding copies of the stored runs (copies keep bytes and modes)."""
    runs = tmp_path / "runs"
    runs.mkdir()
    for path in stored.values():
        shutil.copytree(path, runs / path.name)
    return runs


def run_of(root: Path, stored: dict, name: str) -> Path:
    return root / stored[name].name


def cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def writable(path: Path) -> None:
    path.chmod(stat.S_IMODE(path.stat().st_mode) | stat.S_IWUSR)


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def register(root: Path) -> list[dict]:
    path = root / REGISTER_NAME
    return json.loads(path.read_text())["certificates"] if path.exists() else []


# --- point 1: verified before use ------------------------------------------------------------


def test_an_edited_results_json_is_refused_by_show_and_certificate(capsys, root, stored):
    run = run_of(root, stored, "a")
    target = run / "results.json"
    writable(target)
    record = json.loads(target.read_text())
    record["results"]["reference"]["sensitivity_mv_per_ms2"] *= 1.05  # a "better" DUT
    target.write_text(json.dumps(record, indent=2))
    expected = f"{target}: hash mismatch"
    code, _, err = cli(capsys, "show", run)
    assert code == 2 and expected in err and "Traceback" not in err
    code, _, err = cli(capsys, "certificate", run, *INFO_ARGS)
    assert code == 2 and expected in err
    assert not (run / "certificate.pdf").exists() and register(root) == []


def test_a_replaced_recording_is_refused_by_show_certificate_and_analyze(capsys, root, stored):
    run = run_of(root, stored, "a")
    writable(run)
    (run / "recording.h5").unlink()
    shutil.copyfile(run_of(root, stored, "aborted") / "recording.h5", run / "recording.h5")
    expected = f"{run / 'recording.h5'}: hash mismatch"
    for argv in (
        ["show", run],
        ["certificate", run, *INFO_ARGS],
        ["analyze", run],
        ["analyze", run / "recording.h5", "--json"],
    ):
        code, out, err = cli(capsys, *argv)
        assert code == 2 and expected in err, argv
        assert out == ""
    assert not (run / "certificate.pdf").exists()


def test_an_untouched_run_is_analysed_from_its_folder_and_certified(capsys, root, stored):
    run = run_of(root, stored, "a")
    stored_results = load(run)["results"]
    for target in (run, run / "recording.h5"):
        code, out, err = cli(capsys, "analyze", target, "--json")
        assert code == 0, err
        data = json.loads(out)
        assert data["status"] == "complete" and err == ""
        assert not any("never certified" in w for w in data["warnings"])
        # the same recording, the same code: the stored numbers come back
        assert data["reference"]["sensitivity_mv_per_ms2"] == pytest.approx(
            stored_results["reference"]["sensitivity_mv_per_ms2"], rel=1e-12
        )
    code, out, err = cli(capsys, "certificate", run, *INFO_ARGS)
    assert code == 0, err
    assert f"certificate AC-{run.name}: {run / 'certificate.pdf'}" in out
    code, out, _ = cli(capsys, "show", run)  # the certificate is a product, not a change
    assert code == 0 and "complete" in out


def test_a_folder_that_is_no_run_is_not_analysed(capsys, tmp_path):
    code, _, err = cli(capsys, "analyze", tmp_path)
    assert code == 2 and "not a run folder" in err


# --- point 2: nothing stored is overwritten; certificates locked --------------------------


def test_the_run_folder_opens_only_while_its_certificate_is_written(monkeypatch, root, stored):
    run = run_of(root, stored, "a")
    assert stat.S_IMODE(run.stat().st_mode) == 0o555
    seen = []
    real = app.certificate.issuing.write_pdf

    def spy(stored_run, info, sweep, path, *rest):  # rest: the DCC XML to attach
        seen.append((stat.S_IMODE(run.stat().st_mode), path.parent == run, path.name))
        real(stored_run, info, sweep, path, *rest)

    monkeypatch.setattr(app.certificate.issuing, "write_pdf", spy)
    out = app.certificate.build(
        run, app.certificate.CertificateInfo(**INFO), run / "certificate.pdf"
    )
    ((mode, beside, name),) = seen
    # written beside, under a hidden staging name (issue 23: renamed only after the register)
    assert mode & stat.S_IWUSR and beside and name.startswith(".") and name.endswith(".tmp")
    assert "certificate.pdf" in name
    assert stat.S_IMODE(run.stat().st_mode) == 0o555
    assert stat.S_IMODE(out.stat().st_mode) == 0o444
    assert sorted(p.name for p in run.iterdir() if p.name.startswith(".")) == []


def test_a_failed_certificate_leaves_the_folder_read_only_and_nothing_behind(
    monkeypatch, root, stored
):
    run = run_of(root, stored, "a")
    before = sorted(p.name for p in run.iterdir())

    def broken(stored_run, info, sweep, path, *rest):
        path.write_bytes(b"%PDF-1.4 half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(app.certificate.issuing, "write_pdf", broken)
    with pytest.raises(OSError, match="No space"):
        app.certificate.build(run, app.certificate.CertificateInfo(**INFO), run / "certificate.pdf")
    assert stat.S_IMODE(run.stat().st_mode) == 0o555
    assert sorted(p.name for p in run.iterdir()) == before
    assert register(root) == []


def test_a_certificate_is_refused_while_another_is_being_issued(capsys, root, stored):
    run = run_of(root, stored, "a")
    held = try_lock(run)  # what a certificate being issued holds
    assert held is not None
    try:
        code, _, err = cli(capsys, "certificate", run, *INFO_ARGS)
    finally:
        unlock(held)
    assert code == 2 and "another certificate is being issued for this run" in err
    assert not (run / "certificate.pdf").exists()
    code, _, err = cli(capsys, "certificate", run, *INFO_ARGS)
    assert code == 0, err


def test_two_certificate_processes_at_once_two_numbers_or_one_refusal(root, stored):
    run = run_of(root, stored, "a")
    outs = [run / "certificate.pdf", root.parent / "copy" / "certificate.pdf"]
    processes = [
        subprocess.Popen(
            [sys.executable, "-m", "app", "certificate", str(run), *INFO_ARGS, "--out", str(out)],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for out in outs
    ]
    results = [(p.returncode, *p.communicate(timeout=120)) for p in processes]
    results = [
        (p.returncode, out, err) for p, (_, out, err) in zip(processes, results, strict=True)
    ]
    codes = sorted(code for code, _, _ in results)
    assert codes in ([0, 0], [0, 2]), results
    if codes == [0, 2]:
        assert any("another certificate is being issued" in err for _, _, err in results)
    written = [out for out in outs if out.exists()]
    assert len(written) == codes.count(0)
    texts = ["".join(page.extract_text() for page in PdfReader(out).pages) for out in written]
    printed = {re.search(r"Calibration certificate (\S+)", text).group(1) for text in texts}
    assert len(printed) == len(written)  # two certificates: two numbers
    entries = register(root)
    assert len(entries) == len(written)
    numbers = {e["number"] for e in entries}
    assert len(numbers) == len(entries)  # never one number twice
    for entry in entries:
        path = Path(entry["file"])
        assert entry["sha256"] == sha256(path)  # the whole PDF that was registered
        text = "".join(page.extract_text() for page in PdfReader(path).pages)
        assert entry["number"] in text and entry["run_id"] == run.name
    assert stat.S_IMODE(run.stat().st_mode) == 0o555
    assert not [p for p in run.iterdir() if p.name.startswith(".")]


def test_a_certificate_never_lands_elsewhere_in_a_run_folder(capsys, root, stored):
    run, other = run_of(root, stored, "a"), run_of(root, stored, "b")
    code, _, err = cli(capsys, "certificate", run, *INFO_ARGS, "--out", run / "results-2.pdf")
    assert code == 2 and "only certificate*.pdf may be added" in err
    code, _, err = cli(capsys, "certificate", run, *INFO_ARGS, "--out", other / "certificate.pdf")
    assert code == 2 and "inside the folder of another run" in err
    assert not (run / "results-2.pdf").exists() and not (other / "certificate.pdf").exists()
    code, _, err = cli(capsys, "certificate", run, *INFO_ARGS)
    assert code == 0, err
    code, _, err = cli(capsys, "certificate", run, *INFO_ARGS)  # the place is taken
    assert code == 2 and f"{run / 'certificate.pdf'}: exists" in err


@pytest.fixture(scope="module")
def small_recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("sim") / "v.h5"
    simulate(path, periods=2, seed=3)
    return path


def test_simulate_never_replaces_a_file_unless_asked(capsys, tmp_path, root, stored):
    target = tmp_path / "x.h5"
    target.write_bytes(b"keep me")
    code, _, err = cli(capsys, "simulate", "--periods", "1", "--out", target)
    assert code == 2 and f"--out: {target}: exists" in err and "--overwrite" in err
    assert target.read_bytes() == b"keep me"
    code, _, err = cli(capsys, "simulate", "--periods", "1", "--out", target, "--overwrite")
    assert code == 0, err
    assert read_recording(target).status == "complete"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs", "x.h5"]  # no temporary
    stored_recording = run_of(root, stored, "a") / "recording.h5"
    before = sha256(stored_recording)
    code, _, err = cli(
        capsys, "simulate", "--periods", "1", "--out", stored_recording, "--overwrite"
    )
    assert code == 2 and "a run's record is never changed" in err
    assert sha256(stored_recording) == before


def test_analyze_never_writes_onto_an_input_a_run_or_an_existing_file(
    capsys, tmp_path, small_recording, root, stored
):
    recording = tmp_path / "v.h5"
    shutil.copyfile(small_recording, recording)
    before = sha256(recording)
    alias = tmp_path / "alias.csv"
    os.link(recording, alias)  # the input under another name
    for target in (recording, alias):
        code, _, err = cli(capsys, "analyze", recording, "--csv", target, "--overwrite")
        assert code == 2 and f"--csv: {target}: is an input of this command" in err
    assert sha256(recording) == before
    run = run_of(root, stored, "a")
    code, _, err = cli(capsys, "analyze", run, "--csv", run / "again.csv")
    assert code == 2 and "--csv" in err and "a run's record is never changed" in err
    assert not (run / "again.csv").exists()
    existing = tmp_path / "out.csv"
    existing.write_text("mine\n")
    code, _, err = cli(capsys, "analyze", recording, "--csv", existing)
    assert code == 2 and f"--csv: {existing}: exists" in err
    assert existing.read_text() == "mine\n"
    code, _, err = cli(capsys, "analyze", recording, "--csv", existing, "--overwrite")
    assert code == 0, err
    rows = list(csv.DictReader(io.StringIO(existing.read_text())))
    assert len(rows) == 25 and {r["recording_status"] for r in rows} == {"complete"}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


# --- point 10: the status of a recording travels with its results ----------------------------


def test_recording_status_marks(tmp_path, small_recording):
    recording = read_recording(small_recording)
    assert recording.status == "complete"  # simulate marks a whole recording
    path = tmp_path / "cut.h5"
    writer = RecordingWriter(path, recording.plan, recording.chain, recording.budget)
    writer.append(recording.reference_v, recording.dut_v)
    writer.close()  # what a run cut off (or written before statuses) leaves: no mark
    assert read_recording(path).status == "incomplete"
    writer = RecordingWriter(tmp_path / "a.h5", recording.plan, recording.chain, recording.budget)
    writer.append(recording.reference_v, recording.dut_v)
    assert writer.set_status("aborted", "emergency stop")
    writer.close()
    assert not writer.set_status("complete")  # closed: refused quietly, the mark stays
    with h5py.File(tmp_path / "a.h5") as f:
        assert f.attrs["status"] == "aborted" and f.attrs["status_reason"] == "emergency stop"
    assert read_recording(tmp_path / "a.h5").status == "aborted"
    with pytest.raises(ValueError, match="recording status"):
        writer.set_status("fine")
    # rewriting an aborted recording whole does not make it complete
    write_recording(tmp_path / "b.h5", read_recording(tmp_path / "a.h5"))
    assert read_recording(tmp_path / "b.h5").status == "aborted"


def test_analyze_of_an_aborted_simulation_says_so_everywhere(capsys, tmp_path):
    target = tmp_path / "f.h5"
    code, _, err = cli(capsys, "simulate", "--fault", "device-lost@13", "--out", target)
    assert code == 3 and "DeviceLostError" in err  # an aborted recording: exit 3 (README)
    assert f"the recording so far, marked aborted: {target}" in err
    assert read_recording(target).status == "aborted"
    code, out, err = cli(capsys, "analyze", target, "--json", "--csv", tmp_path / "f.csv")
    assert code == 0, err
    data = json.loads(out)
    assert data["status"] == "aborted"
    assert "recording of an aborted run" in data["warnings"][0]
    assert "warning: recording of an aborted run" in err
    rows = list(csv.DictReader(io.StringIO((tmp_path / "f.csv").read_text())))
    assert {r["recording_status"] for r in rows} == {"aborted"}
    code, out, _ = cli(capsys, "analyze", target)
    assert code == 0
    assert f"{target} (aborted recording):" in out.splitlines()[0]
    assert "warning: recording of an aborted run" in out


def test_a_recording_without_an_end_mark_is_incomplete(capsys, tmp_path, small_recording):
    recording = read_recording(small_recording)
    path = tmp_path / "old.h5"
    with RecordingWriter(
        path, recording.plan, recording.chain, recording.budget, settle_periods=3
    ) as writer:
        writer.append(recording.reference_v, recording.dut_v)
    code, out, _ = cli(capsys, "analyze", path, "--json")
    assert code == 0
    data = json.loads(out)
    assert data["status"] == "incomplete" and "incomplete recording" in data["warnings"][0]


def test_aborted_and_interrupted_runs_analysed_with_their_status_never_certified(
    capsys, root, stored
):
    aborted = run_of(root, stored, "aborted")
    code, out, _ = cli(capsys, "analyze", aborted, "--json")
    assert code == 0 and json.loads(out)["status"] == "aborted"
    code, _, err = cli(capsys, "certificate", aborted, *INFO_ARGS)
    assert code == 2 and "the run is aborted" in err
    interrupted = run_of(root, stored, "b")  # as if its process died before the manifest
    writable(interrupted)
    (interrupted / MANIFEST_NAME).unlink()
    code, out, _ = cli(capsys, "analyze", interrupted / "recording.h5", "--json")
    assert code == 0 and json.loads(out)["status"] == "incomplete"
    code, _, err = cli(capsys, "certificate", interrupted, *INFO_ARGS)
    assert code == 2 and "interrupted" in err
    assert not (interrupted / "certificate.pdf").exists() and register(root) == []


# --- certificate numbers: unique under a runs root ------------------------------------------


def test_certificate_numbers_are_never_reused_under_a_runs_root(capsys, root, stored, tmp_path):
    a, b = run_of(root, stored, "a"), run_of(root, stored, "b")
    code, _, err = cli(capsys, "certificate", a, *INFO_ARGS, "--certificate-number", "LAB-7")
    assert code == 0, err
    out_b = tmp_path / "b.pdf"
    code, _, err = cli(
        capsys, "certificate", b, *INFO_ARGS, "--certificate-number", "lab-7", "--out", out_b
    )
    assert code == 2
    assert "--certificate-number: lab-7 is already used" in err and f"run {a.name}" in err
    assert not out_b.exists()
    # default numbers: AC-<run id>, then AC-<run id>-2 for the run's next certificate
    code, out, err = cli(capsys, "certificate", b, *INFO_ARGS)
    assert code == 0 and f"certificate AC-{b.name}:" in out, err
    code, out, err = cli(capsys, "certificate", b, *INFO_ARGS, "--out", out_b)
    assert code == 0 and f"certificate AC-{b.name}-2:" in out, err
    entries = register(root)
    assert [(e["number"], e["run_id"]) for e in entries] == [
        ("LAB-7", a.name),
        (f"AC-{b.name}", b.name),
        (f"AC-{b.name}-2", b.name),
    ]
    assert entries[2]["file"] == str(out_b) and entries[2]["sha256"] == sha256(out_b)
    assert stat.S_IMODE((root / REGISTER_NAME).stat().st_mode) == 0o444


def test_the_procedure_marks_its_recording_complete_or_aborted(tmp_path):
    from app.io.hdf5 import read_recording
    from app.procedure.run import RunRequest, execute

    done = execute(RunRequest(dut="piezo", periods=3, out=tmp_path / "ok"))
    cut = execute(
        RunRequest(
            dut="piezo", periods=3, faults=(Fault("daq-timeout", 6.0),), out=tmp_path / "cut"
        )
    )
    assert (done.status, cut.status) == ("complete", "aborted")
    ok_rec = read_recording(tmp_path / "ok" / done.record.run_id / "recording.h5")
    cut_rec = read_recording(tmp_path / "cut" / cut.record.run_id / "recording.h5")
    assert (ok_rec.status, cut_rec.status) == ("complete", "aborted")
