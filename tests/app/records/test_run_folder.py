"""Run records: the manifest, read-only folders, locks, and refusal of anything changed."""

from __future__ import annotations

import hashlib
import json
import stat
import threading

import pytest

from app.files import FileExistsRefusal, write_new, write_with
from app.records.run_folder import (
    MANIFEST_NAME,
    STATUS_ABORTED,
    STATUS_INTERRUPTED,
    STATUS_MODIFIED,
    STATUS_RUNNING,
    RunFolder,
    RunIntegrityError,
    inspect_run,
    load_run,
)
from app.records.run_record import RunRecord


def finished_folder(tmp_path, status=STATUS_ABORTED):
    """A run folder written the way a run writes it, ended without results (no procedure)."""
    folder = RunFolder.create(tmp_path, "SN-1")
    folder.write_json("config.json", {"plan": "p"})
    folder.write_text("stand.toml", 'backend = "sim"\n')
    folder.recording.write_bytes(b"raw samples")
    folder.log("state: preflight")
    folder.finish(RunRecord(run_id=folder.run_id, status=status), None)
    return folder.path


def writable(path):
    path.chmod(path.stat().st_mode | stat.S_IWUSR)


def test_manifest_holds_the_sha256_of_every_stored_file(tmp_path):
    path = finished_folder(tmp_path)
    manifest = json.loads((path / MANIFEST_NAME).read_text())
    assert sorted(manifest["files"]) == [
        "config.json",
        "recording.h5",
        "results.json",
        "run.log",
        "stand.toml",
    ]
    raw = hashlib.sha256(b"raw samples").hexdigest()  # computed here, not by the code
    assert manifest["files"]["recording.h5"] == {"sha256": raw, "bytes": 11}
    record = load_run(path)
    assert record.raw_data_sha256 == raw and record.status == STATUS_ABORTED


def test_files_and_folder_are_read_only_after_the_run(tmp_path):
    path = finished_folder(tmp_path)
    assert stat.S_IMODE(path.stat().st_mode) & 0o222 == 0
    for item in path.iterdir():
        assert stat.S_IMODE(item.stat().st_mode) == 0o444, item.name


@pytest.mark.parametrize("name", ["results.json", "recording.h5", "run.log", "stand.toml"])
def test_an_edited_file_is_refused_naming_it(tmp_path, name):
    path = finished_folder(tmp_path)
    writable(path / name)
    with (path / name).open("ab") as handle:
        handle.write(b" ")
    check = inspect_run(path)
    assert check.state == STATUS_MODIFIED and not check.certifiable
    assert check.problems == (f"{path / name}: hash mismatch (changed since the run ended)",)
    with pytest.raises(RunIntegrityError, match=rf"{name}: hash mismatch"):
        load_run(path)


def test_a_replaced_results_json_with_the_same_size_is_refused(tmp_path):
    path = finished_folder(tmp_path)
    target = path / "results.json"
    forged = target.read_text().replace('"aborted"', '"complete"'.ljust(9))
    writable(path)
    target.unlink()
    target.write_text(forged)
    assert inspect_run(path).state == STATUS_MODIFIED


def test_a_removed_or_added_file_is_refused(tmp_path):
    path = finished_folder(tmp_path)
    writable(path)
    (path / "run.log").unlink()
    (path / "extra.json").write_text("{}")
    problems = inspect_run(path).problems
    assert problems == (
        f"{path / 'run.log'}: missing (listed in the manifest)",
        f"{path / 'extra.json'}: not in the manifest (added after the run ended)",
    )


def test_certificates_added_later_are_not_part_of_the_record(tmp_path):
    path = finished_folder(tmp_path)
    writable(path)
    (path / "certificate.pdf").write_bytes(b"%PDF")
    assert inspect_run(path).state == STATUS_ABORTED


def test_a_missing_manifest_is_refused(tmp_path):
    path = finished_folder(tmp_path)
    writable(path)
    (path / MANIFEST_NAME).unlink()
    assert inspect_run(path).state == STATUS_INTERRUPTED
    with pytest.raises(ValueError, match="no manifest"):
        load_run(path)


def test_running_while_the_lock_is_held_then_interrupted_when_the_process_is_gone(tmp_path):
    folder = RunFolder.create(tmp_path, "SN-2")
    folder.recording.write_bytes(b"first period")
    assert inspect_run(folder.path).state == STATUS_RUNNING
    folder.release()  # what the kernel does when the run's process dies
    check = inspect_run(folder.path)
    assert check.state == STATUS_INTERRUPTED and check.record is None
    assert "interrupted" in check.problems[0]


def test_a_changed_manifest_is_refused(tmp_path):
    path = finished_folder(tmp_path)
    writable(path / MANIFEST_NAME)
    (path / MANIFEST_NAME).write_text("{not json")
    with pytest.raises(RunIntegrityError, match="unreadable manifest"):
        inspect_run(path)


def test_write_new_never_overwrites_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "a.txt"
    write_new(target, "first")
    with pytest.raises(FileExistsRefusal, match="never overwritten"):
        write_new(target, "second")
    assert target.read_text() == "first"
    write_new(target, "third", overwrite=True)
    assert target.read_text() == "third"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_a_failed_write_leaves_nothing_behind(tmp_path):
    def broken(path):
        path.write_bytes(b"half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space"):
        write_with(tmp_path / "b.pdf", broken)
    assert list(tmp_path.iterdir()) == []


def test_two_writers_of_one_new_file_one_wins_whole(tmp_path):
    target = tmp_path / "c.bin"
    barrier = threading.Barrier(2)
    outcomes: list[str] = []

    def writer(payload: bytes) -> None:
        def slow(path):
            path.write_bytes(payload)
            barrier.wait(timeout=5)  # both have written their temporary file

        try:
            write_with(target, slow)
            outcomes.append("won")
        except FileExistsRefusal:
            outcomes.append("refused")

    threads = [threading.Thread(target=writer, args=(bytes([b]) * 100_000,)) for b in (1, 2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(outcomes) == ["refused", "won"]
    data = target.read_bytes()
    assert data in (b"\x01" * 100_000, b"\x02" * 100_000)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.bin"]
