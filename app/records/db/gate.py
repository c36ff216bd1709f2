"""The records' gate for the commands that use them (`run`, `certificate`, `db import`): the
chain's quick check (app.records.db.chain_check) on the records they are about to use."""

from __future__ import annotations

import logging

from app.records.db.chain_check import quick_check
from app.records.db.engine import DatabaseError, open_engine

log = logging.getLogger(__name__)


def records_quick_check(url: str | None) -> str | None:
    """`quick_check` on the records at `url` (None: $ACCELCAL_DB, else the default file) for
    the commands that use them: the head's hash; None when the records cannot be opened (the
    command itself says so); ChainBroken when they fail the check."""
    try:
        engine = open_engine(url)
    except DatabaseError as exc:
        log.info("records not checked: %s", exc)
        return None
    try:
        return quick_check(engine)
    finally:
        engine.dispose()
