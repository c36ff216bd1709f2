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
import fcntl
import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from app.certificate.dcc import DccError, DccNotApplicable
from app.certificate.dcc import build as build_dcc
from app.certificate.dcc_complete import complete_dcc
from app.certificate.info import (
    CertificateError,
    CertificateInfo,
    default_info,
    invalid_items,
    missing_items,
)
from app.certificate.leftovers import (
    Registered,
    carried_numbers,
    clear_leftovers,
    find_issuance_leftovers,
    staging_path,
)
from app.certificate.load import StoredRun, load_stored_run, load_sweep
from app.certificate.pdf import write_pdf
from app.certificate.triaxial_dcc import with_triaxial
from app.files import FileExistsRefusal, _fsync_dir, write_with
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
    today = datetime.now(UTC).date().isoformat()
    if info.issue_date in (None, ""):
        info = dataclasses.replace(info, issue_date=today)  # issued today, never back-dated
    from app.certificate.complete import complete, with_environment

    info = with_environment(info, run.start)  # the reading at run start, where not typed
    info = info.merged(default_info(run.record, run.start))
    missing = missing_items(info)
    if missing:
        raise CertificateError(f"missing mandatory item(s): {', '.join(missing)}")
    invalid = invalid_items(info)
    if invalid:
        raise CertificateError(f"invalid item(s): {'; '.join(invalid)}")
    info = complete(info, run.record, run.start, run.results)  # address, specification, ...
    _check_issue_date(str(info.issue_date), run, today)
    out = Path(out)
    into_run = _check_out(out, run.path)
    return _Prepared(run, info, sweep, out, into_run)


def _check_issue_date(issued: str, run: StoredRun, today: str) -> None:
    """Refuse an issue date before the calibration (the run's finishing date, UTC) or after
    today (UTC): a certificate is neither back- nor post-dated. ISO dates compare as text."""
    calibrated = (run.record.finished_utc or run.record.started_utc or "")[:10]
    if calibrated and issued < calibrated:
        raise CertificateError(
            f"issue_date (--issue-date): {issued} is before the calibration ({calibrated}); a "
            "certificate is never back-dated"
        )
    if issued > today:
        raise CertificateError(f"issue_date (--issue-date): {issued} is after today ({today}, UTC)")


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


# a test hook: called with each step's name as issuance passes it ("numbered", "staged",
# "committed", "dcc_published", "published"); the crash tests kill the process there
step_hook: Callable[[str], None] | None = None


def _step(name: str) -> None:
    if step_hook is not None:
        step_hook(name)


@dataclass(frozen=True)
class Staged:
    """A numbered certificate written under its staging names, not yet visible: the PDF and
    its DCC (None: no DCC) with their SHA-256."""

    pdf: Path
    xml: Path | None
    sha256: str
    dcc_sha256: str | None


class Issuance:
    """One certificate being issued, under the run folder's lock and the output folder's:
    `clear` the leftovers of killed issues, `stage` the numbered files under temporary names,
    then (after the register's entry is committed) `publish` them, or `discard` them."""

    def __init__(self, p: _Prepared, signer: Any):
        self.p = p
        self.signer = signer

    @property
    def info(self) -> CertificateInfo:
        return self.p.info

    @property
    def out(self) -> Path:
        return self.p.out

    @property
    def folders(self) -> tuple[Path, ...]:
        """The folders this issue writes to (the output folder; the run folder)."""
        return (self.p.out.parent, self.p.run.path)

    def _writable(self) -> contextlib.AbstractContextManager[None]:
        return writable_folder(self.p.run.path) if self.p.into_run else contextlib.nullcontext()

    def clear(self, register: Mapping[str, Registered], numbers: Iterable[str]) -> set[str]:
        """Clear the leftovers of killed issues in this issue's folders (rolled forward or
        deleted, each logged); then the numbers files there carry (never to be given again).
        CertificateError when `out` is taken after that."""
        clear_leftovers(
            find_issuance_leftovers(
                (self.p.out.parent,), register, numbers, run_folders=(self.p.run.path,)
            )
        )
        if self.p.out.exists():
            raise CertificateError(_exists(self.p.out))
        return carried_numbers(self.folders)

    def stage(self, info: CertificateInfo) -> Staged:
        """Write the numbered PDF (and its DCC, validated first, then signed with the PDF's
        key when there is one: app.certificate.dcc_sign) under staging names."""
        xml = _dcc_of(self.p.run, info)
        if xml is not None and self.signer is not None:
            xml = _signed_dcc(xml, self.signer)
        pdf_tmp = staging_path(self.p.out)
        xml_out = dcc_path(self.p.out)
        if xml is not None and xml_out.exists():
            raise CertificateError(f"{xml_out}: exists; a certificate is never overwritten")
        xml_tmp = staging_path(xml_out) if xml is not None else None
        with self._writable():
            try:
                if xml is not None and xml_tmp is not None:
                    write_with(xml_tmp, lambda path: _write_read_only(path, xml))
                p, signer = self.p, self.signer
                write_with(pdf_tmp, lambda path: write_pdf(p.run, info, p.sweep, path, xml, signer))
            except FileExistsRefusal as exc:
                self._unlink(xml_tmp)
                raise CertificateError(
                    f"{exc}; an issue of this certificate is under way"
                ) from None
            except BaseException:
                self._unlink(xml_tmp, pdf_tmp)
                raise
        return Staged(
            self.p.out,
            xml_out if xml is not None else None,
            sha256_of(pdf_tmp),
            sha256_of(xml_tmp) if xml_tmp is not None else None,
        )

    def discard(self, staged: Staged | None) -> None:
        """Remove the staged files (the register's entry failed: nothing becomes visible)."""
        if staged is None:
            self._unlink(staging_path(self.p.out), staging_path(dcc_path(self.p.out)))
            return
        self._unlink(staging_path(staged.pdf), staging_path(staged.xml) if staged.xml else None)

    def publish(self, staged: Staged) -> None:
        """Give the staged files their final names (the register's entry is committed): the DCC
        first, then the PDF, each by a link that never replaces a file."""
        with self._writable():
            if staged.xml is not None:
                os.link(staging_path(staged.xml), staged.xml)
                os.unlink(staging_path(staged.xml))
                _step("dcc_published")
            os.link(staging_path(staged.pdf), staged.pdf)
            os.unlink(staging_path(staged.pdf))
            _fsync_dir(staged.pdf.parent)
        _step("published")

    def _unlink(self, *paths: Path | None) -> None:
        with self._writable():
            for path in paths:
                if path is not None:
                    path.unlink(missing_ok=True)


@contextlib.contextmanager
def issuance(
    run_path: str | Path,
    info: CertificateInfo,
    out: str | Path,
    sweep_path: str | Path | None = None,
    signer: Any = None,
) -> Iterator[Issuance]:
    """The run checked (CertificateError as `issue`), its folder and the output folder locked
    for the block: an `Issuance` to clear, stage and publish with."""
    p = _prepare(run_path, info, out, sweep_path)
    with _run_locked(p.run), _folder_locked(p.out.parent, p.into_run):
        yield Issuance(p, signer)


@contextlib.contextmanager
def _folder_locked(folder: Path, is_run_folder: bool) -> Iterator[None]:
    """The output folder's lock (issuers there wait their turn; a run folder's is held
    already by `_run_locked`)."""
    if is_run_folder:
        yield
        return
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def issue(
    run_path: str | Path,
    info: CertificateInfo,
    out: str | Path,
    sweep_path: str | Path | None = None,
    signer: Any = None,
) -> Issued:
    """Issue the certificate of a stored, verified, complete run without records: a number
    unique under the runs root (the run folder's parent; default AC-<run id>, then
    AC-<run id>-2, ..., never one a file there carries), the certificate stating that it is
    numbered by the run folder's register. The PDF and DCC are written under staging names,
    entered in the root's JSON register, then renamed: a kill at any step leaves nothing a
    register lacks (`app.certificate.leftovers` clears what is left at the next issue).
    Refused (CertificateError, nothing written) when the run does not verify or did not
    complete, an item is missing, `out` exists or would change a run's record, the number was
    issued before, or another certificate of the run is being issued."""
    with issuance(run_path, _without_records(info), out, sweep_path, signer) as job:
        root = job.p.run.path.resolve().parent
        held = not job.p.into_run and job.out.parent.resolve() == root  # by `issuance`
        try:
            with locked_register(root, held=held) as register:
                registered = {
                    str(Path(e.file).resolve()): Registered(e.number, e.sha256)
                    for e in register.entries
                }
                taken = job.clear(registered, [e.number for e in register.entries])
                numbered = _numbered(job.info, job.p.run, register, taken)
                _step("numbered")
                staged = job.stage(numbered)
                _step("staged")
                try:
                    issued = register.add(
                        str(numbered.certificate_number),
                        _run_id(job.p.run),
                        job.out.resolve(),
                        staged.sha256,
                    )
                except BaseException:
                    job.discard(staged)
                    raise
                _step("committed")
                job.publish(staged)
                return issued
        except RegisterError as exc:
            raise CertificateError(str(exc)) from None


NO_RECORDS_NOTE = "Number from the run folder's register; no records database."


def _without_records(info: CertificateInfo) -> CertificateInfo:
    """`info` with the statement that no records database numbered it, under Notes."""
    notes = f"{info.notes.strip()}\n{NO_RECORDS_NOTE}" if info.notes.strip() else NO_RECORDS_NOTE
    return dataclasses.replace(info, notes=notes)


def dcc_path(pdf: Path) -> Path:
    """Where the digital calibration certificate of `pdf` goes: beside it, .xml."""
    return pdf.with_suffix(".xml")


def _dcc_of(run: StoredRun, info: CertificateInfo) -> bytes | None:
    """The run's DCC XML (validated), or None when the stand file names no laboratory country
    (the PDF is still issued; the CLI says why there is no DCC). CertificateError otherwise."""
    try:
        return build_dcc(run, info, with_triaxial(complete_dcc, info))  # issue 35's items
    except DccNotApplicable:
        return None
    except DccError as exc:
        raise CertificateError(str(exc)) from None


def _signed_dcc(xml: bytes, signer: Any) -> bytes:
    """The DCC with the laboratory's enveloped XAdES signature, still valid against the
    schema (the signature is the root's last child, where DCC 3.3.0 allows it)."""
    from app.certificate.dcc import validation_error
    from app.certificate.dcc_sign import DccSigningError, sign_dcc

    try:
        signed = sign_dcc(xml, signer)
    except DccSigningError as exc:
        raise CertificateError(str(exc)) from None
    problem = validation_error(signed)
    if problem is not None:
        raise CertificateError(f"the signed DCC does not validate: {problem}")
    return signed


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


def _numbered(
    info: CertificateInfo, run: StoredRun, register: Register, taken: set[str]
) -> CertificateInfo:
    """`info` with its certificate number: the one given if never issued under the register's
    root and carried by no file, else the run's next default number no file carries."""
    number = info.certificate_number
    folded = {n.casefold() for n in taken}
    if number in (None, ""):
        return dataclasses.replace(
            info, certificate_number=register.next_number(_run_id(run), folded)
        )
    issued = register.find(str(number))
    if issued is not None:
        raise CertificateError(
            f"--certificate-number: {number} is already used: it was issued on "
            f"{issued.issued_utc} for run {issued.run_id} ({issued.file}); a certificate "
            "number is never reused"
        )
    if str(number).casefold() in folded:
        raise CertificateError(
            f"--certificate-number: {number} is carried by a certificate file on disk; a "
            "certificate number is never reused"
        )
    return info
