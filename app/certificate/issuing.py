"""Issuing a certificate: the transaction that numbers it, draws the PDF (with its DCC beside
it and inside it) and enters it in a register, all or nothing.

Issued under the run folder's lock, written atomically, never over a file; the read-only run
folder is opened only for the moment a certificate*.pdf is written into it. The register is
the runs root's JSON file (app.records.register) unless the caller brings the number from
another (the records database: app.certificate.register_issue), never both.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from app.certificate.dcc import DccError, DccNotApplicable
from app.certificate.dcc import build as build_dcc
from app.certificate.info import (
    CertificateError,
    CertificateInfo,
    default_info,
    invalid_items,
    missing_items,
)
from app.certificate.load import StoredRun, load_stored_run, load_sweep
from app.certificate.pdf import write_pdf
from app.files import FileExistsRefusal, write_with
from app.records.register import Issued, Register, RegisterError, locked_register
from app.records.run_folder import (
    is_product_name,
    is_run_folder,
    sha256_of,
    try_lock,
    unlock,
    writable_folder,
)
from app.records.sweep_summary import SweepSummary


def build(
    run_path: str | Path,
    info: CertificateInfo,
    out: str | Path,
    sweep_path: str | Path | None = None,
) -> Path:
    """Write the certificate of a stored complete run to `out` (with the sweep it belongs to,
    if given: sensitivity against level and the linearity figure); returns the path. See
    `issue`."""
    issue(run_path, info, out, sweep_path)
    return Path(out)


@dataclass(frozen=True)
class _Prepared:
    """A certificate checked and ready to be numbered and written."""

    run: StoredRun
    info: CertificateInfo
    sweep: SweepSummary | None
    out: Path
    into_run: bool


def _prepare(
    run_path: str | Path, info: CertificateInfo, out: str | Path, sweep_path: str | Path | None
) -> _Prepared:
    """The run loaded and verified, the items merged with their defaults and checked, `out`
    checked; CertificateError names what stands in the way."""
    run = load_stored_run(run_path)
    sweep = load_sweep(sweep_path, run) if sweep_path is not None else None
    info = info.merged(default_info(run.record, run.start))
    missing = missing_items(info)
    if missing:
        raise CertificateError(f"missing mandatory item(s): {', '.join(missing)}")
    invalid = invalid_items(info)
    if invalid:
        raise CertificateError(f"invalid item(s): {'; '.join(invalid)}")
    out = Path(out)
    into_run = _check_out(out, run.path)
    return _Prepared(run, info, sweep, out, into_run)


@contextlib.contextmanager
def _run_locked(run: StoredRun) -> Iterator[None]:
    """The run folder's certificate lock, held until the block ends (refused when held)."""
    lock = try_lock(run.path)
    if lock is None:
        raise CertificateError(
            f"{run.path}: another certificate is being issued for this run; try again when it "
            "is done"
        )
    try:
        yield
    finally:
        unlock(lock)


@contextlib.contextmanager
def _written(p: _Prepared, info: CertificateInfo, signer: Any) -> Iterator[Path]:
    """Write the numbered certificate (its DCC first, validated before anything is written)
    and yield the PDF's path; both files are removed when the block (the register's entry)
    fails."""
    xml = _dcc_of(p.run, info)
    xml_out = dcc_path(p.out)
    wrote_xml = False
    with writable_folder(p.run.path) if p.into_run else contextlib.nullcontext():
        try:
            if xml is not None:
                write_with(xml_out, lambda path: _write_read_only(path, xml))
                wrote_xml = True
            write_with(p.out, lambda path: write_pdf(p.run, info, p.sweep, path, xml, signer))
        except FileExistsRefusal as exc:
            if wrote_xml:
                xml_out.unlink(missing_ok=True)
            raise CertificateError(
                f"{exc}; a certificate is never overwritten (use --out)"
            ) from None
        except BaseException:
            if wrote_xml:
                xml_out.unlink(missing_ok=True)
            raise
        try:
            yield p.out
        except BaseException:
            p.out.unlink(missing_ok=True)  # never a certificate its register lacks
            if wrote_xml:
                xml_out.unlink(missing_ok=True)
            raise


def issue(
    run_path: str | Path,
    info: CertificateInfo,
    out: str | Path,
    sweep_path: str | Path | None = None,
    signer: Any = None,
) -> Issued:
    """Issue the certificate of a stored, verified, complete run without records: a number
    unique under the runs root (the run folder's parent; default AC-<run id>, then
    AC-<run id>-2, ...), the PDF written atomically to `out` and entered in the root's JSON
    certificate register. Refused (CertificateError, nothing written) when the run does not
    verify or did not complete, an item is missing, `out` exists or would change a run's
    record, the number was issued before, or another certificate of the run is being issued."""
    p = _prepare(run_path, info, out, sweep_path)
    with _run_locked(p.run):
        try:
            with locked_register(p.run.path.resolve().parent) as register:
                numbered = _numbered(p.info, p.run, register)
                with _written(p, numbered, signer) as pdf:
                    return register.add(
                        str(numbered.certificate_number),
                        _run_id(p.run),
                        pdf.resolve(),
                        sha256_of(pdf),
                    )
        except RegisterError as exc:
            raise CertificateError(str(exc)) from None


@contextlib.contextmanager
def issue_numbered(
    run_path: str | Path,
    info: CertificateInfo,
    out: str | Path,
    sweep_path: str | Path | None = None,
    signer: Any = None,
) -> Iterator[Issued]:
    """Write the certificate numbered by another register (the records database: its number in
    `info`) and yield it; the runs root's JSON register is not touched. The files are removed
    when the block (the other register's entry) fails. Refused as `issue` is."""
    if info.certificate_number in (None, ""):
        raise CertificateError("--certificate-number: the register gives no number")
    p = _prepare(run_path, info, out, sweep_path)
    with _run_locked(p.run), _written(p, p.info, signer) as pdf:
        yield Issued(
            str(p.info.certificate_number),
            _run_id(p.run),
            str(pdf.resolve()),
            datetime.now(UTC).isoformat(timespec="seconds"),
            sha256_of(pdf),
        )


def dcc_path(pdf: Path) -> Path:
    """Where the digital calibration certificate of `pdf` goes: beside it, .xml."""
    return pdf.with_suffix(".xml")


def _dcc_of(run: StoredRun, info: CertificateInfo) -> bytes | None:
    """The run's DCC XML (validated), or None when the stand file names no laboratory country
    (the PDF is still issued; the CLI says why there is no DCC). CertificateError otherwise."""
    try:
        return build_dcc(run, info)
    except DccNotApplicable:
        return None
    except DccError as exc:
        raise CertificateError(str(exc)) from None


def _write_read_only(path: Path, data: bytes) -> None:
    path.write_bytes(data)
    path.chmod(0o444)


def _run_id(run: StoredRun) -> str:
    return str(run.record.run_id or run.path.name)


def _exists(out: Path) -> str:
    return f"{out}: exists; a certificate is never overwritten (use --out)"


def _check_out(out: Path, run_path: Path) -> bool:
    """Whether `out` goes into the run's own folder (as a certificate*.pdf product); refuses an
    existing file and any other place in a run folder (that would change a run's record)."""
    folder = out.resolve().parent
    if folder == run_path.resolve():
        if not is_product_name(out.name):
            raise CertificateError(
                f"--out: {out}: in the run folder only certificate*.pdf may be added (anything "
                "else would change the run's record)"
            )
    elif is_run_folder(folder):
        raise CertificateError(
            f"--out: {out}: inside the folder of another run ({folder}); a run's record is "
            "never changed"
        )
    if out.exists():
        raise CertificateError(_exists(out))
    if folder != run_path.resolve():
        out.parent.mkdir(parents=True, exist_ok=True)
        return False
    return True


def _numbered(info: CertificateInfo, run: StoredRun, register: Register) -> CertificateInfo:
    """`info` with its certificate number: the one given if never issued under the register's
    root, else the run's next default number."""
    number = info.certificate_number
    if number in (None, ""):
        return dataclasses.replace(info, certificate_number=register.next_number(_run_id(run)))
    issued = register.find(str(number))
    if issued is not None:
        raise CertificateError(
            f"--certificate-number: {number} is already used: it was issued on "
            f"{issued.issued_utc} for run {issued.run_id} ({issued.file}); a certificate "
            "number is never reused"
        )
    return info
