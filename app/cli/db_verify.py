"""`accelcal db verify`: walk the records' hash chain and re-check what the records point to.

Every chain hash is recomputed, each audited table is re-derived from the chain and compared
with its live rows, each indexed run folder's seal is verified against its manifest and the
chain head it names, and each registered certificate's PDFs in its run folder are verified.
Exit 0 when all holds, else exit 2 with one line per broken row (table and key)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import TYPE_CHECKING

from app.records.db.errors import RecordsInputError

if TYPE_CHECKING:
    from sqlalchemy import Engine

    from app.records.db.chain_check import Problem

log = logging.getLogger(__name__)


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


def cmd_db_verify(args: argparse.Namespace) -> int:
    """Print each problem; 0 when none, else RecordsBroken (exit 2)."""
    from app.records.db.chain_check import verify
    from app.records.db.engine import open_engine

    engine = open_engine(args.db)
    try:
        problems = verify(engine)
        problems += _certificate_problems(engine, args.certificate)
    finally:
        engine.dispose()
    for problem in problems:
        print(f"BROKEN {problem}")
    if problems:
        raise RecordsBroken(f"records: {len(problems)} broken (first: {problems[0]})")
    print("records verified: chain, rows, run folders and certificates consistent")
    return 0


def _certificate_problems(engine: Engine, extra: list[Path]) -> list[Problem]:
    """Each registered certificate against the DCCs (certificate files, .xml) in its run
    folder: the one stating its number must name its run and the run's seal; a signed PDF
    beside it is verified in full (signature, DCC, run). The `extra` PDFs are verified too."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from app.certificate.verify import VerifyRefusal, verify
    from app.records.db.chain_check import Problem
    from app.records.db.models import Certificate

    found: list[Problem] = []
    pdfs: list[tuple[str, Path, Path | None]] = [("certificate", pdf, None) for pdf in extra]
    with Session(engine) as s:
        for cert in s.scalars(select(Certificate)):
            key = f"{cert.id} ({cert.number})"
            folder = Path(cert.run.folder)
            problem, pdf = _dcc_problem(folder, cert.number, cert.run.run_id)
            if problem:
                found.append(Problem("certificates", key, problem))
            if pdf is not None:
                pdfs.append((key, pdf, folder))
    for key, pdf, run in pdfs:
        try:
            report = verify(pdf, run=run)
        except VerifyRefusal as exc:
            found.append(Problem("certificates", key, f"{pdf}: {exc}"))
            continue
        failed = [(name, detail) for name, ok, detail in report.checks if not ok]
        unsigned = failed and failed[0][1].startswith("the PDF is not signed")
        if failed and not (unsigned and run is not None):  # unsigned: the DCC was checked
            found.append(Problem("certificates", key, f"{pdf}: {failed[0][0]}: {failed[0][1]}"))
    return found


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
