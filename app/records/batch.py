"""A batch folder (issue 36): several DUTs calibrated in one excitation.

`<runs>/<batch_id>/` holds the all-channel `recording.h5` ("reference", "dut.<position>" ...,
"drive"), `batch.json` (the members: position, channel, serial, run_id and the SHA-256 of each
member's seal), its manifest and its own seal (`seal.json`, its own fields: the manifest's and
batch.json's SHA-256). Each member is a complete run folder `<runs>/<run_id>/` of its own
(app.records.run_folder), so every command works on it unchanged.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from app.errors import Refusal
from app.files import write_new
from app.records.run_folder import make_read_only, sha256_of, verify_manifest, write_manifest
from app.records.seal import SEAL_NAME

BATCH_NAME = "batch.json"
BATCH_SEAL_NAME = SEAL_NAME  # seal.json: as a run's, outside the manifest; its own fields
BATCH_VERSION = 1
MAX_BATCH_BYTES = 1_000_000


class BatchError(Refusal):
    """A batch folder that is missing, unreadable or does not match its seal; says which."""


@dataclass(frozen=True)
class BatchMember:
    """One DUT of a batch: its position, channel in the batch recording, serial, run folder's
    id and the SHA-256 of that run's seal ("" when it has none: aborted before sealing)."""

    position: str
    channel: str
    serial: str
    run_id: str
    seal_sha256: str = ""


@dataclass(frozen=True)
class Batch:
    """batch.json: the batch's id, the fixture, when it ran (UTC), its status and members."""

    batch_id: str
    fixture: str
    started_utc: str
    status: str
    members: tuple[BatchMember, ...]
    batch_version: int = BATCH_VERSION

    def to_json(self) -> str:
        data = asdict(self)
        data["members"] = [asdict(m) for m in self.members]
        return json.dumps(data, indent=2)

    @classmethod
    def from_json(cls, text: str, where: str) -> Batch:
        """batch.json's text (BatchError naming `where` and the fault)."""
        try:
            data = json.loads(text)
            if data.get("batch_version") != BATCH_VERSION:
                raise ValueError(f"unknown batch_version {data.get('batch_version')!r}")
            members = tuple(BatchMember(**m) for m in data["members"])
            return cls(
                str(data["batch_id"]),
                str(data["fixture"]),
                str(data["started_utc"]),
                str(data["status"]),
                members,
            )
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise BatchError(f"{where}: not a batch file ({exc})") from None

    def member(self, position: str) -> BatchMember:
        """The member at `position` (BatchError naming the batch's positions)."""
        for m in self.members:
            if m.position == position:
                return m
        names = ", ".join(m.position for m in self.members)
        raise BatchError(f"batch {self.batch_id}: no position {position!r} ({names})")


def is_batch_folder(path: str | Path) -> bool:
    """Whether `path` is a batch folder (it holds batch.json)."""
    return (Path(path) / BATCH_NAME).is_file()


def seal_batch(folder: Path, batch: Batch, software_version: str) -> str:
    """Write batch.json, the manifest of every file and the batch's seal; make the folder
    read-only. The seal's SHA-256 (hex)."""
    write_new(folder / BATCH_NAME, batch.to_json())
    write_manifest(folder)
    seal = {
        "batch_id": batch.batch_id,
        "manifest_sha256": sha256_of(folder / "manifest.json"),
        "batch_sha256": sha256_of(folder / BATCH_NAME),
        "software_version": software_version or "unknown",
        "sealed_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "seal_version": 1,
    }
    text = json.dumps(seal, indent=2, sort_keys=True)
    write_new(folder / BATCH_SEAL_NAME, text)
    make_read_only(folder)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def read_batch(folder: str | Path) -> Batch:
    """The batch of `folder`, its seal and manifest checked (BatchError naming the file)."""
    folder = Path(folder)
    target = folder / BATCH_NAME
    if not target.is_file() or target.is_symlink():
        raise BatchError(f"{folder}: not a batch folder (no {BATCH_NAME})")
    if os.path.getsize(target) > MAX_BATCH_BYTES:
        raise BatchError(f"{target}: larger than {MAX_BATCH_BYTES} bytes")
    text = target.read_text(encoding="utf-8")
    batch = Batch.from_json(text, str(target))
    seal_path = folder / BATCH_SEAL_NAME
    try:
        seal: dict[str, Any] = json.loads(seal_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise BatchError(f"{seal_path}: unreadable batch seal ({exc})") from None
    for name, key in (("manifest.json", "manifest_sha256"), (BATCH_NAME, "batch_sha256")):
        if sha256_of(folder / name) != seal.get(key):
            raise BatchError(f"{folder / name}: hash mismatch with the batch's seal ({seal_path})")
    problems = verify_manifest(folder)
    if problems:
        raise BatchError(f"{folder}: {problems[0]}")
    return batch


def find_batch(root: Path, batch_id: str) -> Path | None:
    """The batch folder `batch_id` under the runs root `root`, None when there is none."""
    path = root / batch_id
    return path if is_batch_folder(path) else None
