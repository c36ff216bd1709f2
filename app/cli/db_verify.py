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
    """Each registered certificate's PDFs in its run folder (and the `extra` ones) verified
    against the run folder."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from app.certificate.verify import VerifyRefusal, verify
    from app.records.db.chain_check import Problem
    from app.records.db.models import Certificate

    found: list[Problem] = []
    targets: list[tuple[str, Path, Path | None]] = [("certificate", pdf, None) for pdf in extra]
    with Session(engine) as s:
        for cert in s.scalars(select(Certificate)):
            run_folder = Path(cert.run.folder)
            for pdf in sorted(run_folder.glob("*.pdf")) if run_folder.is_dir() else []:
                targets.append((f"{cert.id} ({cert.number})", pdf, run_folder))
    for key, pdf, run in targets:
        try:
            report = verify(pdf, run=run)
        except VerifyRefusal as exc:
            found.append(Problem("certificates", key, f"{pdf}: {exc}"))
            continue
        failed = [f"{name}: {detail}" for name, ok, detail in report.checks if not ok]
        if failed:
            found.append(Problem("certificates", key, f"{pdf}: {failed[0]}"))
    return found
