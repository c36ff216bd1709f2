"""What a killed issuance can leave on disk, found and cleared (issue 23 point 4).

A certificate is issued in steps: its PDF and DCC written under staging names
(`.<name>.issuing.tmp`), the register entry committed (with the PDF's path and SHA-256),
then both renamed to their final names. A kill between two steps leaves one of:

- staged files whose number the register does not hold: deleted (the number was never taken);
- staged files the register holds (committed, not yet renamed): renamed into place when their
  SHA-256 is the register's (rolled forward), else deleted;
- half-written temporary files (`.<name>.<random>.tmp`): deleted;
- a final certificate file whose number no register holds (written by an older version before
  its entry): deleted, so that every certificate file on disk is in the register.

`find_issuance_leftovers` only looks; `clear_leftovers` acts and returns one line per file.
Folders are scanned shallowly (the output folder and the run folder of an issue); the caller
holds their locks. `carried_numbers` lists the numbers certificate files in a folder carry
(the allocator never gives one of them again).
"""

from __future__ import annotations

import contextlib
import enum
import io
import logging
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from app.files import _fsync_dir
from app.records.run_folder import sha256_of, writable_folder

log = logging.getLogger(__name__)

STAGING_SUFFIX = ".issuing.tmp"
CERTIFICATE_SUFFIXES = (".pdf", ".xml")


@dataclass(frozen=True)
class Registered:
    """A register entry's files: the PDF's SHA-256 and its DCC's (None: not known)."""

    number: str
    sha256: str | None
    dcc_sha256: str | None = None


class LeftoverKind(enum.StrEnum):
    """What a leftover is and what clearing it does."""

    UNCOMMITTED = "staged, not in the register: deleted"
    COMMITTED = "staged, in the register: renamed into place"
    PARTIAL = "half-written temporary file: deleted"
    UNREGISTERED = "certificate file whose number no register holds: deleted"


@dataclass(frozen=True)
class Leftover:
    """One file left by a killed issuance: where, what, and its final name (COMMITTED)."""

    path: Path
    kind: LeftoverKind
    final: Path | None = None
    number: str | None = None

    def describe(self) -> str:
        number = f" ({self.number})" if self.number else ""
        return f"{self.path}{number}: {self.kind.value}"


def staging_path(final: Path) -> Path:
    """The staging name of a certificate file `final`: `.<name>.issuing.tmp` beside it."""
    return final.with_name(f".{final.name}{STAGING_SUFFIX}")


def final_of(staged: Path) -> Path | None:
    """The final name a staging file stands for (None: not a staging name)."""
    name = staged.name
    if not (name.startswith(".") and name.endswith(STAGING_SUFFIX)):
        return None
    inner = name[1 : -len(STAGING_SUFFIX)]
    return staged.with_name(inner) if inner.endswith(CERTIFICATE_SUFFIXES) else None


def _is_partial(name: str) -> bool:
    """A half-written temporary file of app.files (`.<target>.<random>.tmp`) of a PDF/DCC."""
    return (
        name.startswith(".")
        and name.endswith(".tmp")
        and not name.endswith(STAGING_SUFFIX)
        and any(f"{suffix}." in name for suffix in CERTIFICATE_SUFFIXES)
    )


def dcc_number(xml: bytes) -> str | None:
    """The certificate number a DCC carries (None: not a readable DCC)."""
    from app.certificate.readback import PrintedError, items_from_dcc, parse_inert

    try:
        return items_from_dcc(parse_inert(xml)).number or None
    except (PrintedError, ValueError, TypeError):
        return None


def carried_number(pdf: Path) -> str | None:
    """The number a certificate PDF carries: from its DCC beside it, else the one attached,
    else its marked text layer (app.certificate.pdf_marks), else its document title
    ("Calibration certificate NUMBER", every certificate this program drew); None when it is
    no readable certificate."""
    beside = pdf.with_suffix(".xml")
    with contextlib.suppress(OSError, ValueError):
        if beside.is_file() and not beside.is_symlink():
            number = dcc_number(beside.read_bytes())
            if number:
                return number
    try:
        from pypdf import PdfReader

        from app.certificate.pdf import TITLE_PREFIX
        from app.certificate.pdf_marks import read_marks
        from app.certificate.printed import Item

        data = pdf.read_bytes()
        reader = PdfReader(io.BytesIO(data))
        attached = list(reader.attachments.get("certificate.xml") or [])
        if len(attached) == 1:
            number = dcc_number(attached[0])
            if number:
                return number
        number = read_marks(data).item(Item.NUMBER).replace("\n", " ")
        if number:
            return number
        title = str(reader.metadata.get("/Title") or "") if reader.metadata else ""
        if title.startswith(TITLE_PREFIX):
            return title.removeprefix(TITLE_PREFIX).strip() or None
        return None
    except Exception:  # pypdf fails in many ways on a file that is no certificate
        return None


def _certificate_pdfs(folder: Path) -> list[Path]:
    """The certificate PDFs of a folder: *.pdf regular files with a DCC beside them, and
    certificate*.pdf (a run folder's products, DCC or not)."""
    found = []
    for path in sorted(folder.iterdir()):
        if path.name.startswith(".") or path.suffix != ".pdf" or path.is_symlink():
            continue
        if not path.is_file():
            continue
        if path.name.startswith("certificate") or path.with_suffix(".xml").is_file():
            found.append(path)
    return found


def carried_numbers(folders: Iterable[Path]) -> set[str]:
    """The numbers the certificate files (and staged files) of `folders` carry."""
    numbers: set[str] = set()
    for folder in _existing(folders):
        for pdf in _certificate_pdfs(folder):
            number = carried_number(pdf)
            if number:
                numbers.add(number)
        for path in folder.iterdir():
            final = final_of(path)
            if final is not None and path.suffix == ".tmp" and path.is_file():
                number = (
                    dcc_number(path.read_bytes())
                    if final.suffix == ".xml"
                    else carried_number(path)
                )
                if number:
                    numbers.add(number)
    return numbers


def _existing(folders: Iterable[Path]) -> list[Path]:
    seen: dict[Path, None] = {}
    for folder in folders:
        with contextlib.suppress(OSError):
            if folder.is_dir():
                seen.setdefault(folder.resolve(), None)
    return list(seen)


def _registered_by_sha(
    register: Mapping[str, Registered], final: Path, staged: Path
) -> tuple[bool, str | None]:
    """Whether the staged file is the one the register names for `final` (by SHA-256)."""
    pdf = final if final.suffix == ".pdf" else final.with_suffix(".pdf")
    entry = register.get(str(pdf.resolve()))
    if entry is None:
        return False, None
    try:
        digest = sha256_of(staged)
    except (OSError, ValueError):
        return False, entry.number
    wanted = entry.sha256 if final.suffix == ".pdf" else entry.dcc_sha256
    if wanted is None and final.suffix == ".xml":  # a register that keeps no DCC hash
        try:
            return dcc_number(staged.read_bytes()) == entry.number, entry.number
        except OSError:
            return False, entry.number
    return wanted is not None and digest == wanted, entry.number


def find_issuance_leftovers(
    folders: Iterable[Path],
    register: Mapping[str, Registered],
    numbers: Iterable[str] = (),
    run_folders: Iterable[Path] = (),
) -> list[Leftover]:
    """The leftovers of killed issuances in `folders` and `run_folders` (shallow). `register`
    maps each registered PDF's absolute path to its entry; `numbers` are every number the
    registers hold. Only in `run_folders` (a run's own certificates, whose registers the
    caller holds) is a final file carrying another number UNREGISTERED; elsewhere (an output
    folder other registers may write to) final files are left alone."""
    known = {n.casefold() for n in numbers} | {e.number.casefold() for e in register.values()}
    found: list[Leftover] = []
    run_folders = _existing(run_folders)
    for folder in _existing([*folders, *run_folders]):
        for path in sorted(folder.iterdir()):
            if path.is_symlink() or not path.is_file():
                continue
            final = final_of(path)
            if final is not None:
                committed, number = _registered_by_sha(register, final, path)
                kind = LeftoverKind.COMMITTED if committed else LeftoverKind.UNCOMMITTED
                if committed and final.exists():
                    kind = LeftoverKind.UNCOMMITTED  # already in place: the copy goes
                found.append(Leftover(path, kind, final, number))
            elif _is_partial(path.name):
                found.append(Leftover(path, LeftoverKind.PARTIAL))
        if folder not in run_folders:
            continue
        for pdf in _certificate_pdfs(folder):
            if str(pdf.resolve()) in register:
                continue
            number = carried_number(pdf)
            if number is not None and number.casefold() not in known:
                found.append(Leftover(pdf, LeftoverKind.UNREGISTERED, None, number))
        for xml in sorted(folder.glob("certificate*.xml")):  # a DCC before its PDF (older code)
            if xml.is_symlink() or not xml.is_file() or xml.with_suffix(".pdf").exists():
                continue
            with contextlib.suppress(OSError):
                number = dcc_number(xml.read_bytes())
                if number is not None and number.casefold() not in known:
                    found.append(Leftover(xml, LeftoverKind.UNREGISTERED, None, number))
    return found


def clear_leftovers(leftovers: Iterable[Leftover]) -> list[str]:
    """Delete or roll forward each leftover (see LeftoverKind); one line per file done. A
    read-only folder (a run's) is opened only for the moment; a file gone meanwhile is
    skipped."""
    done: list[str] = []
    for item in leftovers:
        folder = item.path.parent
        with writable_folder(folder):
            try:
                if item.kind is LeftoverKind.COMMITTED and item.final is not None:
                    os.link(item.path, item.final)  # fails if the final name exists
                    os.unlink(item.path)
                else:
                    os.unlink(item.path)
                    if item.kind is LeftoverKind.UNREGISTERED:
                        beside = item.path.with_suffix(".xml")
                        if beside.is_file() and dcc_number(beside.read_bytes()) == item.number:
                            os.unlink(beside)
            except FileNotFoundError:
                continue
            _fsync_dir(folder)
        line = item.describe()
        log.warning("issuance leftover cleared: %s", line)
        done.append(line)
    return done
