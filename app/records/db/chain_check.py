"""Checks of the records' hash chain (app.records.db.chain): the full walk behind
`accelcal db verify`, the quick check `run`, `certificate` and `db import` make first, and the
re-entry of rows a schema migration changed.

The full walk recomputes every hash, checks every head's signature against the configured
records key (app.records.db.records_key: never the key the records hold alone), re-derives each
audited table from the chain and compares it with the live rows, looks for journal rows no
entry claims, compares the schema fingerprint (the triggers' definitions), checks that the head
this workstation signed last is still in the chain, and checks the run folders the records
index (seal, manifest) and the chain heads their seals name. Each problem names the table and
the primary key.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, Engine, Table, select
from sqlalchemy import func as sql_func

from app.records.db import chain, records_key
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
    if head is None:
        return []
    recorded = head.schema_fingerprint
    legacy = recorded.startswith(("sqlite:", "pg:"))  # written before revision 0011
    now = chain.legacy_fingerprint(connection) if legacy else chain.schema_fingerprint(connection)
    if recorded == now:
        return []
    why = (
        "the schema or its triggers changed since the last recorded write (a trigger dropped, "
        "altered or recreated?)"
    )
    return [Problem(_SCHEMA, "", why)]


_NOT_CONFIGURED = (
    f"no records public key configured (${records_key.PUBLIC_ENV}, or records-key.pub beside "
    "the records key): the heads' signatures cannot be checked"
)


def _signature_problems(
    connection: Connection,
    entries: list[chain.Entry],
    trusted: records_key.TrustedKey | None,
) -> list[Problem]:
    """Each signed entry's signature against the configured key, and the newest entry signed
    (an unsigned tail was appended without the key). Chains before revision 0011: none."""
    if not entries or not chain.has_signatures(connection):
        return []
    if trusted is None:
        return [Problem("records_key", "", _NOT_CONFIGURED)]
    problems: list[Problem] = []
    signed_before = _signed_before(connection, entries[0].seq)
    for entry in entries:
        if entry.signature is None and entry.key_id is None:
            continue
        name = str(entry.seq)
        first = 1 if signed_before is None else signed_before + 1
        signed_before = entry.seq
        if entry.key_id != trusted.key_id:
            why = (
                f"signed by key {str(entry.key_id)[:16]}..., not the configured records key "
                f"{trusted.key_id[:16]}... ({trusted.source})"
            )
            problems.append(Problem(chain.CHAIN_TABLE, name, why))
        elif not trusted.verifies(first, entry.seq, entry.hash, entry.signature):
            why = (
                f"its head signature (entries {first}..{entry.seq}) does not verify (an entry "
                "forged, edited or slipped in unsigned before it)"
            )
            problems.append(Problem(chain.CHAIN_TABLE, name, why))
    last_signed = max((e.seq for e in entries if e.signature), default=None)
    tail = [e for e in entries if last_signed is None or e.seq > last_signed]
    if tail:
        oldest, newest = tail[0], tail[-1]
        why = (
            f"entries {oldest.seq}..{newest.seq} are not covered by a signed head (appended "
            f"without the records key; first: {oldest.action} {oldest.table_name} "
            f"{oldest.row_key})"
        )
        problems.append(Problem(chain.CHAIN_TABLE, str(newest.seq), why))
    return problems


def _signed_before(connection: Connection, seq: int) -> int | None:
    """The newest signed entry before `seq` (None: none)."""
    entries = ChainEntry.__table__
    query = select(sql_func.max(entries.c.seq)).where(
        entries.c.seq < seq, entries.c.signature.is_not(None)
    )
    found = connection.execute(query).scalar()
    return None if found is None else int(found)


def _high_water_problem(connection: Connection) -> list[Problem]:
    """The head this workstation signed last must still be in the chain: a chain cut back to
    an older signed head, or rebuilt after one, no longer has it."""
    entries = ChainEntry.__table__
    database = records_key.database_id(chain.database_identity(connection))
    kept = records_key.last_signed(database)
    if kept is None:
        return []
    seq, head = kept
    found = connection.execute(select(entries.c.hash).where(entries.c.seq == seq)).scalar()
    if found == head:
        return []
    why = (
        f"the head this workstation signed last (hash {head[:16]}...) is not in the chain "
        "(records cut back or rebuilt)"
    )
    return [Problem(chain.CHAIN_TABLE, str(seq), why)]


_CONFIGURED = object()  # the default of `trusted`: the configured key (records_key.trusted_key)
Trusted = records_key.TrustedKey | None | object  # a key, None (none configured), _CONFIGURED


def _trusted(trusted: Trusted) -> records_key.TrustedKey | None:
    if trusted is _CONFIGURED:
        return records_key.trusted_key()
    assert trusted is None or isinstance(trusted, records_key.TrustedKey)
    return trusted


def verify_connection(
    connection: Connection,
    tables: Mapping[str, Table] | None = None,
    anchors: Iterable[tuple[str, str]] = (),
    trusted: Trusted = _CONFIGURED,
) -> list[Problem]:
    """Every problem of the records on `connection`: chain links and hashes, the heads'
    signatures against `trusted` (default: the configured records key), live rows against the
    chain, unclaimed journal rows, the schema fingerprint, the head this workstation signed
    last, and each anchored head ((where, hash) pairs from seals and certificates) present in
    the chain."""
    entries = chain.read_entries(connection)
    walk = _walk(entries)
    problems = list(walk.problems)
    problems += _signature_problems(connection, entries, _trusted(trusted))
    problems += _high_water_problem(connection)
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


def verify(
    engine: Engine, anchors: Iterable[tuple[str, str]] = (), trusted: Trusted = _CONFIGURED
) -> list[Problem]:
    """The full walk of `accelcal db verify` over the records and their run folders (the
    heads' signatures against `trusted`, default the configured records key)."""
    with engine.connect() as connection:
        if not chain.has_chain(connection):
            return [Problem(chain.CHAIN_TABLE, "", "missing (run accelcal db upgrade)")]
        folder_problems, seal_anchors = run_folder_anchors(connection)
        problems = verify_connection(connection, anchors=[*seal_anchors, *anchors], trusted=trusted)
    return problems + folder_problems


def quick_check(engine: Engine, trusted: Trusted = _CONFIGURED) -> str:
    """The check before a run, a certificate or an import: the last entries link and hash,
    the head is signed by the configured records key and is not older than the one this
    workstation signed last, every live row is the one its newest chain entry wrote (whatever
    happened to the triggers), no journal row is unclaimed and the triggers' definitions are
    those last recorded. The chain head's hash; ChainBroken naming the first problem."""
    with engine.connect() as connection:
        if not chain.has_chain(connection):
            raise ChainBroken("records: no hash chain; run `accelcal db upgrade`")
        entries = chain.read_entries(connection, last=QUICK_WINDOW)
        problems: list[Problem] = []
        if entries:
            first = entries[0]
            walk = _walk(entries, first_seq=first.seq, prev=first.prev_hash)
            problems += walk.problems
            problems += _signature_problems(connection, entries, _trusted(trusted))
            problems += _high_water_problem(connection)
            problems += _schema_problem(connection, walk.head)
            problems += _unclaimed_journal(connection, limit=1)
            problems += _latest_rows(connection)
        else:
            problems += _unclaimed_journal(connection, limit=1)
    if problems:
        raise ChainBroken(f"records: {problems[0]}; see `accelcal db verify`")
    return entries[-1].hash if entries else chain.GENESIS


def _latest_rows(connection: Connection) -> list[Problem]:
    """Every live row of the audited tables against the newest chain entry of its key (one
    query for the chain, one per table): an edit made with the triggers dropped and put back
    is seen here, however old the row."""
    tables = chain.chained_tables()
    entries = ChainEntry.__table__
    newest = (
        select(sql_func.max(entries.c.seq).label("seq"))
        .where(entries.c.table_name != "")
        .group_by(entries.c.table_name, entries.c.row_key)
        .subquery()
    )
    query = select(entries.c.table_name, entries.c.row_key, entries.c.row).join(
        newest, entries.c.seq == newest.c.seq
    )
    expected = {
        (r.table_name, r.row_key): r.row for r in connection.execute(query) if r.row is not None
    }
    return _compare(expected, _live_state(connection, tables), tables)


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
