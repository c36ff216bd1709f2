"""`accelcal db verify`: walk the records' hash chain and re-check what the records point to.

Every chain hash is recomputed, every head's signature checked against the configured records
key (`--records-key PUB`, else app.records.db.records_key's configuration; never the key the
records hold alone), each audited table is re-derived from the chain and compared with its live
rows, each indexed run folder's seal is verified against its manifest and the chain head it
names, every registered certificate file (PDF and DCC) is compared with the register's SHA-256,
signed or not, and each certificate PDF is verified (a signed one in full against `--trust CA`,
else $ACCELCAL_TRUST, the lab's trust store). Exit 0 when all holds, else exit 2 with one line
per broken row (table and key)."""

from __future__ import annotations

import argparse
import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING

from app.records.db.errors import RecordsInputError

if TYPE_CHECKING:
    from sqlalchemy import Engine

    from app.records.db.chain_check import Problem

log = logging.getLogger(__name__)

TRUST_ENV = "ACCELCAL_TRUST"  # the lab's trust store: its CA certificate (PEM or DER)


class RecordsBroken(RecordsInputError):
    """The records fail `db verify`; the message counts the broken rows (each is printed)."""


def add_verify(dsub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """The `db verify` subcommand."""
    v = dsub.add_parser("verify", help="check the records' hash chain, run folders, certificates")
    v.add_argument(
        "--db", metavar="URL", help="records database (default $ACCELCAL_DB, else SQLite file)"
    )
    v.add_argument(
        "--certificate",
        type=Path,
        action="append",
        default=[],
        metavar="PDF",
        help="also check this certificate PDF (besides those in the run folders)",
    )
    v.add_argument(
        "--trust",
        type=Path,
        metavar="CA",
        help=f"the laboratory's CA certificate (PEM or DER): signed certificates are verified "
        f"in full against it (default ${TRUST_ENV}, the lab's trust store)",
    )
    v.add_argument(
        "--records-key",
        type=Path,
        metavar="PUB",
        help="the records' public key (PEM) the chain's signatures must verify with (default "
        "$ACCELCAL_RECORDS_PUBLIC_KEY, else records-key.pub beside the records key)",
    )


def cmd_db_verify(args: argparse.Namespace) -> int:
    """Print each problem; 0 when none, else RecordsBroken (exit 2)."""
    from app.records.db.chain_check import verify
    from app.records.db.engine import open_engine
    from app.records.db.records_key import trusted_key

    trust = _trust(args.trust)
    trusted = trusted_key(args.records_key)
    engine = open_engine(args.db)
    try:
        problems = verify(engine, trusted=trusted)
        problems += _certificate_problems(engine, args.certificate, trust)
    finally:
        engine.dispose()
    for problem in problems:
        print(f"BROKEN {problem}")
    if problems:
        raise RecordsBroken(f"records: {len(problems)} broken (first: {problems[0]})")
    print("records verified: chain, rows, run folders and certificates consistent")
    return 0


def _trust(given: Path | None) -> Path | None:
    """The CA certificate signed certificates are checked against: --trust, else
    $ACCELCAL_TRUST (the lab's trust store); None: neither (a signed certificate then fails
    its trust check, naming --trust)."""
    from app.cli.exits import UsageError

    chosen = given or (Path(v) if (v := os.environ.get(TRUST_ENV)) else None)
    if chosen is not None and not chosen.is_file():
        option = "--trust" if given else f"${TRUST_ENV}"
        raise UsageError(f"{option}: no such file {chosen}")
    return chosen


def _file_problems(path: Path, expected: str | None, what: str) -> str | None:
    """Why the registered file at `path` is not the one registered (its SHA-256); None when
    it is (or nothing was registered)."""
    from app.io.checks import InputFileError, sha256_regular

    if not expected:
        return None
    if not os.path.lexists(path):
        return f"{path}: the registered {what} is missing"
    try:
        actual = sha256_regular(path, what)
    except (InputFileError, OSError, ValueError) as exc:
        return f"{path}: the registered {what} cannot be read ({exc})"
    if actual != expected:
        return (
            f"{path}: not the {what} registered (SHA-256 {actual[:16]}..., the register's "
            f"{expected[:16]}...)"
        )
    return None


def _certificate_problems(engine: Engine, extra: list[Path], trust: Path | None) -> list[Problem]:
    """Each registered certificate: its files (PDF, DCC) against the register's SHA-256,
    signed or not; the DCC in its run folder stating its number must name its run and the
    run's seal; every PDF is verified (signature, DCC, run; a signed one against `trust`).
    The `extra` PDFs are verified too."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from app.certificate.issuing import dcc_path
    from app.records.db.chain_check import Problem
    from app.records.db.models import Certificate

    found: list[Problem] = []
    pdfs: dict[Path, tuple[str, Path | None]] = {pdf: ("certificate", None) for pdf in extra}
    with Session(engine) as s:
        for cert in s.scalars(select(Certificate).order_by(Certificate.id)):
            key = f"{cert.id} ({cert.number})"
            folder = Path(cert.run.folder)
            if cert.file:
                registered = Path(cert.file)
                for path, expected, what in (
                    (registered, cert.sha256, "certificate PDF"),
                    (dcc_path(registered), cert.dcc_sha256, "certificate DCC"),
                ):
                    problem = _file_problems(path, expected, what)
                    if problem:
                        found.append(Problem("certificates", key, problem))
                if registered.is_file():
                    pdfs.setdefault(registered, (key, folder if folder.is_dir() else None))
            problem, pdf = _dcc_problem(folder, cert.number, cert.run.run_id)
            if problem:
                found.append(Problem("certificates", key, problem))
            if pdf is not None:
                pdfs.setdefault(pdf, (key, folder))
    for pdf, (key, run) in pdfs.items():
        problem = _pdf_problem(pdf, run, trust)
        if problem:
            found.append(Problem("certificates", key, problem))
    return found


def _pdf_problem(pdf: Path, run: Path | None, trust: Path | None) -> str | None:
    """The first failed check of `accelcal verify` on `pdf` (with its run and the trust
    store). An unsigned PDF of a run is not a problem in itself (nor its DCC unsigned beside
    it, the same lab's policy): its DCC, its run and its SHA-256 against the register are
    checked."""
    from app.certificate import dcc_sign
    from app.certificate.verify import VerifyRefusal, verify

    try:
        report = verify(pdf, run=run, trust=trust)
    except VerifyRefusal as exc:
        return f"{pdf}: {exc}"
    failed = [(name, detail) for name, ok, detail in report.checks if not ok]
    if not failed:
        return None
    unsigned = failed[0][1].startswith("the PDF is not signed")
    if unsigned and run is not None:
        dcc_unsigned = (dcc_sign.CHECK, dcc_sign.UNSIGNED_DETAIL)
        rest = [f for f in failed[1:] if f != dcc_unsigned]  # the DCC and the run were checked
        return f"{pdf}: {rest[0][0]}: {rest[0][1]}" if rest else None
    return f"{pdf}: {failed[0][0]}: {failed[0][1]}"


def _dcc_problem(folder: Path, number: str, run_id: str) -> tuple[str | None, Path | None]:
    """Why the DCC stating `number` in `folder` does not match the register row (None: it
    does, or no certificate file of that number is kept there), and its PDF if one is."""
    from app.certificate.readback import PrintedError, items_from_dcc, parse_inert
    from app.io.checks import InputFileError, read_regular_bytes
    from app.records.seal import SealError, read_seal

    if not folder.is_dir():
        return None, None  # the run folder itself is named by the chain check
    for xml in sorted(folder.glob("*.xml")):
        try:
            items = items_from_dcc(parse_inert(read_regular_bytes(xml, 8 << 20, "DCC")))
        except (InputFileError, PrintedError) as exc:
            log.info("%s: not a DCC (%s)", xml, exc)
            continue
        if items.number != number:
            continue
        pdf = xml.with_suffix(".pdf")
        pdf_found = pdf if pdf.is_file() else None
        if items.run_id != run_id:
            return f"{xml} names run {items.run_id!r}, the register {run_id!r}", pdf_found
        try:
            seal = read_seal(folder)[1]
        except SealError as exc:
            return str(exc), pdf_found
        if items.seal != seal:
            return f"{xml} names seal {items.seal[:16]}..., the run's is {seal[:16]}...", pdf_found
        return None, pdf_found
    return None, None
