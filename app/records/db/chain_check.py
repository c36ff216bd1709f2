"""Checks of the records' hash chain (app.records.db.chain): the full walk behind
`accelcal db verify`, the quick check `run`, `certificate` and `db import` make first, and the
re-entry of rows a schema migration changed.

The full walk recomputes every hash, re-derives each audited table from the chain and compares
it with the live rows, looks for journal rows no entry claims, compares the schema fingerprint
and checks the run folders the records index (seal, manifest) and the chain heads their seals
name. Each problem names the table and the primary key.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, Engine, Table, select

from app.records.db import chain
from app.records.db.chain import Change
from app.records.db.errors import RecordsInputError
from app.records.db.models import ChainEntry, JournalEntry, Run

log = logging.getLogger(__name__)

QUICK_WINDOW = 64  # entries whose hashes and rows the quick check re-checks
_SCHEMA = "schema"


class ChainBroken(RecordsInputError):
    """The records fail the chain check; the message names the first broken row."""


@dataclass(frozen=True)
class Problem:
    """One broken row: the table (or 'records_chain', 'schema', a run folder), its key, why."""

    table: str
    key: str
    why: str

    def __str__(self) -> str:
        return f"{self.table} {self.key}: {self.why}" if self.key else f"{self.table}: {self.why}"


@dataclass
class Walk:
    """What a walk of the chain found: the problems, the rows derived, the hashes seen."""

    problems: list[Problem] = field(default_factory=list)
    state: dict[tuple[str, str], str] = field(default_factory=dict)
    hashes: set[str] = field(default_factory=set)
    claims: set[int] = field(default_factory=set)
    head: chain.Entry | None = None


def _walk(entries: Iterable[chain.Entry], *, first_seq: int = 1, prev: str = chain.GENESIS) -> Walk:
    walk = Walk()
    expected_seq = first_seq
    for entry in entries:
        name = str(entry.seq)
        if entry.seq != expected_seq:
            walk.problems.append(
                Problem(chain.CHAIN_TABLE, name, f"sequence gap (expected {expected_seq})")
            )
        if entry.prev_hash != prev:
            walk.problems.append(
                Problem(chain.CHAIN_TABLE, name, "does not link to the entry before it")
            )
        if entry.computed_hash() != entry.hash:
            walk.problems.append(
                Problem(
                    chain.CHAIN_TABLE,
                    name,
                    f"hash does not match its content (entry of {entry.table_name} "
                    f"{entry.row_key} edited)",
                )
            )
        expected_seq, prev = entry.seq + 1, entry.hash
        walk.hashes.add(entry.hash)
        if entry.journal_id is not None:
            walk.claims.add(entry.journal_id)
        if entry.table_name:
            if entry.row is None:
                walk.state.pop((entry.table_name, entry.row_key), None)
            else:
                walk.state[(entry.table_name, entry.row_key)] = entry.row
        walk.head = entry
    return walk


def _diff(expected: str, live: str) -> str:
    old, new = json.loads(expected), json.loads(live)
    names = sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k))
    return ", ".join(names)


def _live_state(connection: Connection, tables: Mapping[str, Table]) -> dict[tuple[str, str], str]:
    """Every live row of the audited tables as the chain would store it."""
    live: dict[tuple[str, str], str] = {}
    for name, table in tables.items():
        for found in connection.execute(select(table)):
            row = found._mapping
            live[(name, chain.row_key(table, row))] = chain.row_json(table, row)
    return live


def _compare(
    expected: Mapping[tuple[str, str], str],
    live: Mapping[tuple[str, str], str],
    tables: Mapping[str, Table],
) -> list[Problem]:
    """Live rows against the rows the chain derives, in table and key order."""
    problems: list[Problem] = []
    for name, key in sorted(expected.keys() | live.keys()):
        if name not in tables:
            continue
        want, have = expected.get((name, key)), live.get((name, key))
        if want is None:
            problems.append(Problem(name, key, "not in the chain (written outside the app)"))
        elif have is None:
            problems.append(Problem(name, key, "deleted outside the application"))
        elif want != have:
            why = f"changed outside the application ({_diff(want, have)})"
            problems.append(Problem(name, key, why))
    return problems


def _unclaimed_rows(connection: Connection, *, limit: int | None = None) -> list[Any]:
    """Journal rows (id, table_name, row_key, action) no chain entry claims, oldest first."""
    journal, entries = JournalEntry.__table__, ChainEntry.__table__
    claimed = select(entries.c.seq).where(entries.c.journal_id == journal.c.id).exists()
    query = select(journal).where(~claimed).order_by(journal.c.id)
    if limit:
        query = query.limit(limit)
    return list(connection.execute(query))


def _unclaimed_journal(connection: Connection, *, limit: int | None = None) -> list[Problem]:
    return [
        Problem(r.table_name, r.row_key, f"{r.action} outside the application (journal {r.id})")
        for r in _unclaimed_rows(connection, limit=limit)
    ]


def _schema_problem(connection: Connection, head: chain.Entry | None) -> list[Problem]:
    if head is None or head.schema_fingerprint == chain.schema_fingerprint(connection):
        return []
    why = "the schema or its triggers changed since the last recorded write (triggers dropped?)"
    return [Problem(_SCHEMA, "", why)]


def verify_connection(
    connection: Connection,
    tables: Mapping[str, Table] | None = None,
    anchors: Iterable[tuple[str, str]] = (),
) -> list[Problem]:
    """Every problem of the records on `connection`: chain links and hashes, live rows
    against the chain, unclaimed journal rows, the schema fingerprint, and each anchored head
    ((where, hash) pairs from seals and certificates) present in the chain."""
    walk = _walk(chain.read_entries(connection))
    problems = list(walk.problems)
    tables = tables or chain.chained_tables()
    problems += _compare(walk.state, _live_state(connection, tables), tables)
    problems += [p for p in _unclaimed_journal(connection) if p not in problems]
    problems += _schema_problem(connection, walk.head)
    known = walk.hashes | {chain.GENESIS}
    for where, anchored in anchors:
        if anchored not in known:
            why = f"names chain head {anchored[:16]}..., not in the chain (records rewritten?)"
            problems.append(Problem(where, "", why))
    return problems


def run_folder_anchors(connection: Connection) -> tuple[list[Problem], list[tuple[str, str]]]:
    """Each indexed run's folder against the records: the seal must verify (manifest and
    results hashes) and name the manifest the records index. The problems, and the chain
    heads the seals name as (seal path, head)."""
    from app.records.seal import SealError, read_seal

    problems: list[Problem] = []
    anchors: list[tuple[str, str]] = []
    runs = Run.__table__
    for row in connection.execute(
        select(runs.c.id, runs.c.run_id, runs.c.folder, runs.c.manifest_sha256)
    ):
        folder = Path(row.folder)
        key = f"{row.id} ({row.run_id})"
        if not folder.is_dir():
            problems.append(Problem("runs", key, f"run folder {folder} is missing"))
            continue
        try:
            seal, _ = read_seal(folder)
        except SealError as exc:
            problems.append(Problem("runs", key, str(exc)))
            continue
        if seal.manifest_sha256 != row.manifest_sha256:
            problems.append(Problem("runs", key, "the folder's manifest is not the one indexed"))
        if seal.records_chain_head:
            anchors.append((str(folder / "seal.json"), seal.records_chain_head))
    return problems, anchors


def verify(engine: Engine, anchors: Iterable[tuple[str, str]] = ()) -> list[Problem]:
    """The full walk of `accelcal db verify` over the records and their run folders."""
    with engine.connect() as connection:
        if not chain.has_chain(connection):
            return [Problem(chain.CHAIN_TABLE, "", "missing (run accelcal db upgrade)")]
        folder_problems, seal_anchors = run_folder_anchors(connection)
        problems = verify_connection(connection, anchors=[*seal_anchors, *anchors])
    return problems + folder_problems


def quick_check(engine: Engine) -> str:
    """The fast check before a run, a certificate or an import: the last entries link and
    hash, their rows are as the chain says, no journal row is unclaimed and the schema is the
    one last recorded. The chain head's hash; ChainBroken naming the first problem."""
    with engine.connect() as connection:
        if not chain.has_chain(connection):
            raise ChainBroken("records: no hash chain; run `accelcal db upgrade`")
        entries = chain.read_entries(connection, last=QUICK_WINDOW)
        problems: list[Problem] = []
        if entries:
            first = entries[0]
            walk = _walk(entries, first_seq=first.seq, prev=first.prev_hash)
            problems += walk.problems
            problems += _window_rows(connection, entries)
            problems += _unclaimed_journal(connection, limit=1)
            problems += _schema_problem(connection, walk.head)
        else:
            problems += _unclaimed_journal(connection, limit=1)
    if problems:
        raise ChainBroken(f"records: {problems[0]}; see `accelcal db verify`")
    return entries[-1].hash if entries else chain.GENESIS


def _window_rows(connection: Connection, entries: list[chain.Entry]) -> list[Problem]:
    """The rows the last entries wrote, against the live rows (one query per table)."""
    tables = chain.chained_tables()
    latest: dict[tuple[str, str], str | None] = {}
    for entry in entries:
        if entry.table_name in tables:
            latest[(entry.table_name, entry.row_key)] = entry.row
    live: dict[tuple[str, str], str] = {}
    for name in sorted({name for name, _ in latest}):
        table = tables[name]
        (column,) = table.primary_key.columns  # every audited table has a one-column key
        keys = [column.type.python_type(key) for table_name, key in latest if table_name == name]
        for found in connection.execute(select(table).where(column.in_(keys))):
            row = found._mapping
            live[(name, chain.row_key(table, row))] = chain.row_json(table, row)
    problems: list[Problem] = []
    for where, expected in latest.items():
        have = live.get(where)
        if have != expected:
            why = "deleted outside the application" if have is None else "changed outside the app"
            problems.append(Problem(*where, why))
    return problems


def before_migration(connection: Connection) -> None:
    """Refuse to migrate records whose chain is broken (a migration re-enters rows)."""
    if not chain.has_chain(connection):
        return
    problems = verify_connection(connection, chain.reflected_tables(connection))
    if problems:
        raise ChainBroken(
            f"records: {problems[0]} ({len(problems)} problems); not migrated, see "
            "`accelcal db verify`"
        )


def after_migration(connection: Connection) -> int:
    """Enter into the chain every row a migration created or changed (all rows, the first
    time), claiming the journal rows it made, then the new schema. Entries appended."""
    if not chain.has_chain(connection):
        return 0
    actor = f"accelcal db upgrade ({chain.current_actor()})"
    tables = chain.reflected_tables(connection)
    state = _walk(chain.read_entries(connection)).state
    live = _live_state(connection, tables)
    changes = []
    for journal in _unclaimed_rows(connection):
        where = (journal.table_name, journal.row_key)
        row = live.get(where)
        changes.append(Change("migrate", *where, row=row, journal_id=journal.id))
        if row is None:
            state.pop(where, None)
        else:
            state[where] = row
    for problem in _compare(state, live, tables):
        where = (problem.table, problem.key)
        changes.append(Change("migrate", *where, row=live.get(where)))
    changes.append(Change(_SCHEMA))
    chain.append(connection, actor=actor, changes=changes)
    appended = len(changes) - 1
    log.info("records chain: %d rows entered after the migration", appended)
    return len(changes)
