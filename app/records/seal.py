"""The seal of a run (SPEC.md section 9): the record that closes a run folder and that a
certificate names.

seal.json holds the run id, the SHA-256 of manifest.json and of results.json, the software
version and the UTC time it was written; it is written after the manifest (which therefore does
not list it). The seal hash, the SHA-256 of seal.json's bytes, is what the certificate's PDF and
DCC carry; `verify --run` recomputes every hash from the folder and compares, so an edited
results.json with a regenerated manifest no longer matches a certificate.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

from app.errors import Refusal
from app.files import write_new
from app.io.checks import InputFileError, read_regular_bytes, sha256_regular

_HEX64 = re.compile(r"[0-9a-f]{64}")
SEAL_NAME = "seal.json"
SEAL_VERSION = 1
MAX_SEAL_BYTES = 64 * 1024
_FIELDS = (
    "seal_version",
    "run_id",
    "manifest_sha256",
    "results_sha256",
    "software_version",
    "sealed_utc",
)
_OPTIONAL = ("records_chain_head",)  # absent from seals written before the records chain


class SealError(Refusal):
    """A seal that is missing, unreadable or does not match its run folder; says which."""


@dataclass(frozen=True)
class Seal:
    """A run's seal: what it binds (hex SHA-256 values) and when it was made (UTC, ISO 8601)."""

    run_id: str
    manifest_sha256: str
    results_sha256: str
    software_version: str
    sealed_utc: str
    seal_version: int = SEAL_VERSION
    records_chain_head: str | None = None  # hex hash of the records chain head when sealed

    def to_json(self) -> str:
        """The seal as stored: sorted keys, two-space indent (no chain head: not written)."""
        fields = asdict(self)
        if fields["records_chain_head"] is None:
            del fields["records_chain_head"]
        return json.dumps(fields, indent=2, sort_keys=True)


def _sha256_file(path: Path) -> str:
    """Hex SHA-256 of a regular file's bytes (no links, FIFOs or devices)."""
    return sha256_regular(path, "run file")


def write_seal(
    folder: Path, run_id: str, software_version: str, records_chain_head: str | None = None
) -> Seal:
    """Seal the finished run in `folder` (manifest.json and results.json written): seal.json,
    never over an existing one, naming the records chain head when records are in use. The
    seal."""
    seal = Seal(
        run_id=run_id,
        manifest_sha256=_sha256_file(folder / "manifest.json"),
        results_sha256=_sha256_file(folder / "results.json"),
        software_version=software_version or "unknown",
        sealed_utc=datetime.now(UTC).isoformat(timespec="seconds"),
        records_chain_head=records_chain_head,
    )
    write_new(folder / SEAL_NAME, seal.to_json())
    return seal


def named_seal(folder: Path) -> str | None:
    """The hash of the run's checked seal, the one a certificate names; None for a run
    finished before seals existed (no seal.json at all). SealError when it does not match."""
    if not os.path.lexists(folder / SEAL_NAME):
        return None
    return read_seal(folder)[1]


def named_chain_head(folder: Path) -> str | None:
    """The records chain head (hex) the run's checked seal names; None without one."""
    if not os.path.lexists(folder / SEAL_NAME):
        return None
    return read_seal(folder)[0].records_chain_head


def read_seal(folder: Path) -> tuple[Seal, str]:
    """The seal of the run in `folder`, checked against the folder's manifest.json and
    results.json as they are now, and its hash (hex SHA-256 of seal.json). SealError naming
    the file and the reason when it is missing, unreadable or does not match."""
    target = folder / SEAL_NAME
    try:
        data = read_regular_bytes(target, MAX_SEAL_BYTES, "run seal")
    except InputFileError as exc:
        raise SealError(f"{exc} (a run finished before seals existed has none)") from None
    try:
        raw = json.loads(data.decode("utf-8"))
        if not isinstance(raw, dict) or sorted(set(raw) - set(_OPTIONAL)) != sorted(_FIELDS):
            raise ValueError(f"its fields are not {', '.join(_FIELDS)}")
        head = raw.get("records_chain_head")
        if head is not None and not (isinstance(head, str) and _HEX64.fullmatch(head)):
            raise ValueError("records_chain_head is not a hex SHA-256")
        seal = Seal(**raw)
        if seal.seal_version != SEAL_VERSION:
            raise ValueError(f"unknown seal_version {seal.seal_version!r}")
    except (ValueError, TypeError) as exc:
        raise SealError(f"{target}: unreadable seal ({exc})") from None
    for name, expected in (
        ("manifest.json", seal.manifest_sha256),
        ("results.json", seal.results_sha256),
    ):
        try:
            actual = _sha256_file(folder / name)
        except (OSError, ValueError) as exc:
            raise SealError(f"{folder / name}: cannot be read ({exc})") from None
        if actual != expected:
            raise SealError(f"{folder / name}: hash mismatch with the run's seal ({target})")
    return seal, hashlib.sha256(data).hexdigest()
