"""Run records (SPEC.md section 9): one folder per run, written as the run goes, immutable after.

    runs/<run-id>/recording.h5   raw channels and drive, flushed every period (app.recording)
                  config.json    stand configuration, plan and run settings as used
                  run.log        what happened, one line per event, flushed as it goes
                  results.json   status, abort reason, identities, timings, SHA-256 of the raw
                                 data, and the results object (null when there are none)
                  results.csv    per-line results (complete runs)

When the run ends, every file is made read-only: a correction is a new run.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import uuid
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from dsp.calibration import Results

STATUS_COMPLETE = "complete"
STATUS_ABORTED = "aborted"


def sha256_of(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def new_run_id(label: str) -> str:
    """'20261122T031500Z-piezo-3f2a9c' style: sortable, unique, readable."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in label)[:32] or "run"
    return f"{stamp}-{safe}-{uuid.uuid4().hex[:6]}"


@dataclass
class RunFolder:
    """A run folder being written."""

    path: Path
    run_id: str

    @classmethod
    def create(cls, root: str | Path, label: str) -> RunFolder:
        root = Path(root)
        root.mkdir(parents=True, exist_ok=True)
        run_id = new_run_id(label)
        path = root / run_id
        path.mkdir()
        return cls(path, run_id)

    @property
    def recording(self) -> Path:
        return self.path / "recording.h5"

    def write_json(self, name: str, data: Any) -> None:
        target = self.path / name
        tmp = target.with_suffix(".tmp")
        tmp.write_text(json.dumps(data, indent=2, default=str), encoding="utf-8")
        os.replace(tmp, target)

    def log(self, line: str) -> None:
        stamp = datetime.now(UTC).isoformat(timespec="milliseconds")
        with (self.path / "run.log").open("a", encoding="utf-8") as handle:
            handle.write(f"{stamp} {line}\n")

    def finish(self, record: dict[str, Any], results: Results | None) -> dict[str, Any]:
        """Write results.json (and results.csv) with the raw data's hash; make it read-only."""
        if self.recording.exists():
            record["raw_data_sha256"] = sha256_of(self.recording)
        record["results"] = results.to_dict() if results is not None else None
        self.write_json("results.json", record)
        if results is not None:
            (self.path / "results.csv").write_text(results.to_csv(), encoding="utf-8")
        for item in self.path.iterdir():
            item.chmod(stat.S_IRUSR | stat.S_IRGRP | stat.S_IROTH)
        return record


def load_run(path: str | Path) -> dict[str, Any]:
    """The record of a stored run (results.json); ValueError naming what is missing."""
    path = Path(path)
    target = path / "results.json"
    if not path.is_dir():
        raise ValueError(f"{path}: no such run folder")
    if not target.exists():
        raise ValueError(f"{path}: no results.json (the run did not finish writing)")
    try:
        return json.loads(target.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{target}: not valid JSON ({exc})") from None
