"""Run records (SPEC.md section 9): one folder per run, written as the run goes, immutable after.

    runs/<run-id>/recording.h5   raw channels and drive, flushed every period (app.io.hdf5)
                  config.json    stand configuration, plan and run settings as used
                  stand.toml     the stand file exactly as read
                  run.log        what happened, one line per event, flushed as it goes
                  results.json   status, abort reason, identities, timings, SHA-256 of the raw
                                 data, and the results object (null when there are none)
                  results.csv    per-line results (complete runs)
                  manifest.json  SHA-256 of every file above
                  seal.json      run id, SHA-256 of manifest.json and results.json, software
                                 version, time (app.records.seal): written last, named by
                                 the certificates

While a run writes its folder it holds an exclusive lock on it (flock on the folder), so a
reader can tell a running run from one whose process died (no manifest, no lock: interrupted).
When the run ends every file and the folder itself are made read-only: a correction is a new
run. Everything that reads a run verifies the manifest first (`inspect_run`, `load_run`); an
edited, replaced, missing or added file is refused by name with "hash mismatch" or the reason.
Certificates issued later (certificate*.pdf / certificate*.xml) are products of the run, not
part of its record, and carry their own hashes. Every file of a folder is read as a regular
file only (app.io.checks.open_regular): a link, FIFO or device is refused by name, never read.
"""

from __future__ import annotations

import contextlib
import fcntl
import fnmatch
import json
import os
import stat
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.errors import Refusal
from app.files import write_new
from app.io.checks import InputFileError, read_regular_bytes, sha256_regular
from app.io.csv_cells import neutralised
from app.io.vocabulary import RunStatus
from app.records.run_record import RunRecord, RunRecordError, UnsupportedSchemaError
from app.records.seal import SEAL_NAME, write_seal

if TYPE_CHECKING:  # a type only: the records commands that read folders import no numpy
    from dsp.calibration import Results


class FolderState(StrEnum):
    """What a run folder is when read: a finished run (its RunStatus) or why it is none."""

    COMPLETE = RunStatus.COMPLETE.value
    ABORTED = RunStatus.ABORTED.value
    RUNNING = "running"  # a live process holds the folder's lock
    INTERRUPTED = "interrupted"  # no manifest and nobody writing: the process died
    MODIFIED = "modified"  # a stored file does not match the manifest
    UNSUPPORTED = "unsupported"  # results.json of a newer schema version than this code


# the old names of the states, kept for one release
STATUS_COMPLETE = FolderState.COMPLETE
STATUS_ABORTED = FolderState.ABORTED
STATUS_RUNNING = FolderState.RUNNING
STATUS_INTERRUPTED = FolderState.INTERRUPTED
STATUS_MODIFIED = FolderState.MODIFIED
STATUS_UNSUPPORTED = FolderState.UNSUPPORTED

MANIFEST_NAME = "manifest.json"
MANIFEST_VERSION = 1
# products made from a finished run later, each with hashes of its own: not part of the record
PRODUCT_PATTERNS = ("certificate*.pdf", "certificate*.xml")
MAX_MANIFEST_BYTES = 1 << 20  # a few hundred bytes per file listed
MAX_RESULTS_BYTES = 64 << 20  # results of many thousand lines with their budgets
READ_ONLY_FILE = stat.S_IRUSR | stat.S_IRGRP | stat.S_IROTH
READ_ONLY_FOLDER = READ_ONLY_FILE | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH


class RunIntegrityError(Refusal):
    """A stored run that does not verify; the message names the file and the reason."""


def sha256_of(path: Path) -> str:
    """Hex SHA-256 of a regular file's bytes; InputFileError (a ValueError) naming the file
    for a link, FIFO, device or folder."""
    return sha256_regular(path, "run file")


def new_run_id(label: str) -> str:
    """'20261122T031500Z-piezo-3f2a9c' style: sortable, unique, readable."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in label)[:32] or "run"
    return f"{stamp}-{safe}-{uuid.uuid4().hex[:6]}"


def _is_product(name: str) -> bool:
    return any(fnmatch.fnmatch(name, pattern) for pattern in PRODUCT_PATTERNS)


def is_product_name(name: str) -> bool:
    """Whether a file named `name` may be added to a finished run folder (a certificate)."""
    return _is_product(name)


def is_run_folder(path: str | Path) -> bool:
    """Whether `path` is a run folder, finished (manifest) or not (run log being written)."""
    path = Path(path)
    return (path / MANIFEST_NAME).exists() or (path / "run.log").exists()


def refuse_in_run_folder(target: str | Path) -> None:
    """ValueError when writing `target` would add to or replace a file of a run folder (a run's
    record is never changed after the run)."""
    folder = Path(target).resolve().parent
    if is_run_folder(folder):
        raise ValueError(
            f"{target}: inside the run folder {folder}; a run's record is never changed, write "
            "it elsewhere"
        )


@contextlib.contextmanager
def writable_folder(path: Path) -> Iterator[None]:
    """Let the owner add a file to the read-only folder `path` for the block (a certificate),
    then give the folder its mode back, whatever happens."""
    mode = stat.S_IMODE(path.stat().st_mode)
    if mode & stat.S_IWUSR:
        yield
        return
    path.chmod(mode | stat.S_IWUSR)
    try:
        yield
    finally:
        path.chmod(mode)


def _record_files(path: Path) -> list[Path]:
    """The files a manifest covers: everything in the folder but the manifest, the seal,
    products and temporary files of an interrupted write (dot files)."""
    return sorted(
        p
        for p in path.iterdir()
        if p.name not in (MANIFEST_NAME, SEAL_NAME)
        and not p.name.startswith(".")
        and not _is_product(p.name)
    )


def try_lock(path: Path) -> int | None:
    """An exclusive lock on the folder `path` (an open descriptor to keep), or None when
    another holder has it (a run writing it, or a certificate being issued)."""
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


def unlock(fd: int | None) -> None:
    """Release a lock from `try_lock` (safe with None)."""
    if fd is not None:
        with contextlib.suppress(OSError):
            os.close(fd)


@dataclass
class RunFolder:
    """A run folder being written; it holds the folder's lock until `finish` or `release`."""

    path: Path
    run_id: str
    _lock: int | None = field(default=None, repr=False)
    records_chain_head: str | None = None  # the records chain head the seal names (hex)

    @classmethod
    def create(cls, root: str | Path, label: str) -> RunFolder:
        root = Path(root)
        root.mkdir(parents=True, exist_ok=True)
        run_id = new_run_id(label)
        path = root / run_id
        path.mkdir()
        return cls(path, run_id, try_lock(path))

    @property
    def recording(self) -> Path:
        return self.path / "recording.h5"

    def write_json(self, name: str, data: Any) -> None:
        """A new JSON file in the folder, written atomically; never replaces one."""
        write_new(self.path / name, json.dumps(data, indent=2, default=str))

    def write_text(self, name: str, text: str) -> None:
        """A new text file in the folder, written atomically; never replaces one."""
        write_new(self.path / name, text)

    def log(self, line: str) -> None:
        stamp = datetime.now(UTC).isoformat(timespec="milliseconds")
        with (self.path / "run.log").open("a", encoding="utf-8") as handle:
            handle.write(f"{stamp} {line}\n")

    def finish(self, record: RunRecord, results: Results | None) -> RunRecord:
        """Write results.json (and results.csv) with the raw data's hash, then the manifest of
        every file; make files and folder read-only and release the lock. The record as
        written."""
        try:
            sha = sha256_of(self.recording) if self.recording.exists() else None
            record = record.with_results(results, sha)
            self.write_text("results.json", record.to_json())
            if results is not None:
                self.write_text("results.csv", neutralised(results.to_csv()))
            write_manifest(self.path)
            write_seal(
                self.path,
                record.run_id or self.run_id,
                record.software_version,
                self.records_chain_head,
            )
            make_read_only(self.path)
        finally:
            self.release()
        return record

    def release(self) -> None:
        """Give up the folder's lock (the run's process is done with it)."""
        unlock(self._lock)
        self._lock = None


def write_manifest(path: Path) -> dict[str, Any]:
    """manifest.json: SHA-256 and size of every record file of the folder `path`."""
    files = {
        p.name: {"sha256": sha256_of(p), "bytes": p.stat().st_size} for p in _record_files(path)
    }
    manifest = {"manifest_version": MANIFEST_VERSION, "algorithm": "sha256", "files": files}
    write_new(path / MANIFEST_NAME, json.dumps(manifest, indent=2, sort_keys=True))
    return manifest


def make_read_only(path: Path) -> None:
    """Make every file of the folder and the folder itself read-only."""
    for item in path.iterdir():
        if not item.is_symlink() and item.is_file():
            item.chmod(READ_ONLY_FILE)
    path.chmod(READ_ONLY_FOLDER)


def verify_manifest(path: Path) -> list[str]:
    """What does not match the folder's manifest, one line per file naming it (empty: all
    verified). Raises RunIntegrityError when the manifest itself is missing or unreadable."""
    target = path / MANIFEST_NAME
    try:
        manifest = json.loads(read_regular_bytes(target, MAX_MANIFEST_BYTES, "manifest"))
        files = manifest["files"]
        if manifest.get("algorithm") != "sha256" or not isinstance(files, dict):
            raise ValueError("unknown manifest format")
    except InputFileError as exc:
        if not os.path.lexists(target):
            raise RunIntegrityError(f"{target}: no manifest (the run did not finish)") from None
        raise RunIntegrityError(str(exc)) from None
    except (ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
        raise RunIntegrityError(f"{target}: unreadable manifest ({exc})") from None
    problems = []
    present = {p.name: p for p in _record_files(path)}
    for name, entry in sorted(files.items()):
        file = present.pop(name, None)
        if file is None:
            problems.append(f"{path / name}: missing (listed in the manifest)")
            continue
        try:
            digest = sha256_of(file)
        except InputFileError as exc:
            problems.append(str(exc))
            continue
        if not isinstance(entry, dict) or digest != entry.get("sha256"):
            problems.append(f"{path / name}: hash mismatch (changed since the run ended)")
    for name in sorted(present):
        problems.append(f"{path / name}: not in the manifest (added after the run ended)")
    return problems


@dataclass(frozen=True)
class RunCheck:
    """What a run folder is: its state (complete, aborted, running, interrupted, modified), the
    problems found (each naming a file) and its record (None unless it verified)."""

    path: Path
    state: FolderState
    problems: tuple[str, ...] = ()
    record: RunRecord | None = None

    @property
    def certifiable(self) -> bool:
        return self.state == FolderState.COMPLETE


def inspect_run(path: str | Path) -> RunCheck:
    """Verify a run folder before any use. ValueError when `path` is no run folder."""
    path = Path(path)
    if not path.is_dir():
        raise ValueError(f"{path}: no such run folder")
    if not os.path.lexists(path / MANIFEST_NAME):
        lock = try_lock(path)
        if lock is None:
            return RunCheck(path, FolderState.RUNNING, ("the run is still being written",))
        unlock(lock)
        if not any(path.iterdir()):
            raise ValueError(f"{path}: empty folder, not a run folder")
        return RunCheck(
            path,
            FolderState.INTERRUPTED,
            (
                f"{path}: no manifest: the run was interrupted before it finished (its "
                "recording is readable up to the last period written)",
            ),
        )
    problems = verify_manifest(path)
    if problems:
        return RunCheck(path, FolderState.MODIFIED, tuple(problems))
    target = path / "results.json"
    try:
        data = json.loads(read_regular_bytes(target, MAX_RESULTS_BYTES, "run's results"))
    except (OSError, ValueError) as exc:  # verified bytes: written broken
        return RunCheck(path, FolderState.MODIFIED, (f"{target}: not readable ({exc})",))
    state = data.get("status") if isinstance(data, dict) else None
    try:
        record = RunRecord.from_dict(data)
    except UnsupportedSchemaError as exc:
        return RunCheck(path, FolderState.UNSUPPORTED, (f"{path}: {exc}",))
    except RunRecordError as exc:
        return RunCheck(path, FolderState.MODIFIED, (f"{path}: {exc}",))
    if state not in (FolderState.COMPLETE, FolderState.ABORTED):
        return RunCheck(path, FolderState.MODIFIED, (f"{target}: unknown status {state!r}",))
    return RunCheck(path, FolderState(state), (), record)


def load_run(path: str | Path) -> RunRecord:
    """The record of a stored, verified run (results.json). RunIntegrityError naming the file
    when it does not verify; UnsupportedSchemaError (a ValueError) for a newer schema version;
    ValueError when it is no finished run."""
    check = inspect_run(path)
    if check.state == FolderState.MODIFIED:
        raise RunIntegrityError("; ".join(check.problems))
    if check.state == FolderState.UNSUPPORTED:
        raise UnsupportedSchemaError("; ".join(check.problems))
    if check.record is None:
        raise ValueError(check.problems[0] if check.problems else f"{path}: not a finished run")
    return check.record
