"""The register of certificate numbers issued under one runs root (the run folders' parent).

`certificate-register.json` in the runs root lists every certificate issued there: its number,
the run it was issued for, the PDF written, when, and the PDF's SHA-256. It is read, checked
and extended only under an exclusive lock on the runs root (flock on the folder), and replaced
in one step (app.files), so two certificates issued at once never share a number and no reader
sees a torn register. Numbers compare without regard to case or repeated spaces. (A database
register replaces this file in a later version.)
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
from collections.abc import Collection, Iterator
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

from app.errors import Refusal
from app.files import write_with
from app.records.run_folder import READ_ONLY_FILE

REGISTER_NAME = "certificate-register.json"
REGISTER_VERSION = 1
DEFAULT_PREFIX = "AC-"


class RegisterError(Refusal):
    """The register cannot be read; the message names its file."""


@dataclass(frozen=True)
class Issued:
    """One certificate issued: number, run id, PDF path, UTC time (ISO 8601), PDF SHA-256."""

    number: str
    run_id: str
    file: str
    issued_utc: str
    sha256: str


def _key(number: str) -> str:
    return " ".join(number.split()).casefold()


class Register:
    """The certificates issued under one runs root; use it inside `locked_register`."""

    def __init__(self, root: Path, entries: list[Issued]):
        self.root = root
        self.entries = entries

    @property
    def path(self) -> Path:
        return self.root / REGISTER_NAME

    def find(self, number: str) -> Issued | None:
        """The certificate issued with `number`, if any."""
        key = _key(number)
        return next((e for e in self.entries if _key(e.number) == key), None)

    def next_number(self, run_id: str, taken: Collection[str] = ()) -> str:
        """The default number of a run's next certificate: AC-<run id>, then AC-<run id>-2, ...,
        the first neither issued here nor in `taken` (casefolded numbers files carry)."""
        base = f"{DEFAULT_PREFIX}{run_id}"
        number, count = base, 1
        while self.find(number) is not None or number.casefold() in taken:
            count += 1
            number = f"{base}-{count}"
        return number

    def add(self, number: str, run_id: str, file: Path, sha256: str) -> Issued:
        """Enter a certificate and write the register (read-only, replaced in one step)."""
        issued = Issued(
            number,
            run_id,
            str(file),
            datetime.now(UTC).isoformat(timespec="seconds"),
            sha256,
        )
        entries = [*self.entries, issued]
        text = json.dumps(
            {"register_version": REGISTER_VERSION, "certificates": [asdict(e) for e in entries]},
            indent=2,
        )

        def write(path: Path) -> None:
            path.write_text(text, encoding="utf-8")
            path.chmod(READ_ONLY_FILE)

        write_with(self.path, write, overwrite=True)
        self.entries = entries
        return issued


def read_register(root: Path) -> list[Issued]:
    """The certificates entered under `root` (none when there is no register yet)."""
    path = root / REGISTER_NAME
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return []
    except (OSError, ValueError) as exc:
        raise RegisterError(f"{path}: unreadable certificate register ({exc})") from None
    try:
        return [Issued(**entry) for entry in data["certificates"]]
    except (KeyError, TypeError) as exc:
        raise RegisterError(f"{path}: malformed certificate register ({exc})") from None


@contextlib.contextmanager
def locked_register(root: str | Path, *, held: bool = False) -> Iterator[Register]:
    """The register of `root`, held exclusively (other issuers under `root` wait) until the
    block ends; `held`: the caller holds the folder's lock already (a second flock on another
    descriptor of the same process would wait for ever)."""
    root = Path(root)
    if held:
        yield Register(root, read_register(root))
        return
    fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield Register(root, read_register(root))
    finally:
        os.close(fd)  # releases the lock
