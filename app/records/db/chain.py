"""The records' hash chain: every write to an audited table is one entry chained by SHA-256.

Each entry (table `records_chain`) holds the row's table, primary key, action and full new
content as sorted-key JSON, the actor, the UTC time, the journal row it accounts for and the
schema fingerprint; its hash is sha256(previous hash || canonical JSON of the entry). The
application appends entries from SQLAlchemy mapper events, in the transaction of the change.
Database triggers (migration 0007) note every INSERT/UPDATE/DELETE of an audited table in
`records_journal`, whoever makes it; a journal row no chain entry claims is a change made
outside the application. The last entry of every append (the head it leaves) is signed with the
records key (app.records.db.records_key, Ed25519, a file the database never holds; migration
0011), so a head covers every entry before it. Checks live in app.records.db.chain_check.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from datetime import UTC, date, datetime
from typing import Any

from sqlalchemy import (
    Column,
    Connection,
    MetaData,
    String,
    Table,
    event,
    insert,
    inspect,
    select,
    text,
)
from sqlalchemy import func as sql_func
from sqlalchemy.orm import Mapper, Session, object_session

from app.records.db import records_key
from app.records.db.actor import current_actor
from app.records.db.models import Base, ChainEntry, JournalEntry

CHAIN_TABLE = "records_chain"
JOURNAL_TABLE = "records_journal"
KEYS_TABLE = "records_keys"
GENESIS = "0" * 64
# derived bookkeeping, the chain's own tables and Alembic's: not chained
UNCHAINED = frozenset(
    {"register_counters", CHAIN_TABLE, JOURNAL_TABLE, KEYS_TABLE, "alembic_version"}
)
# the public records keys that signed heads (migration 0011; append-only): not a model, so
# no mapper event chains it
KEYS = Table(
    KEYS_TABLE,
    MetaData(),
    Column("key_id", String(64), primary_key=True),
    Column("public_key", String(64), nullable=False),
    Column("created_utc", String(40), nullable=False),
)
SIGNED_COLUMNS = ("signature", "key_id")  # records_chain's columns since 0011
# stored as their SHA-256 only (the chain must not copy a password hash)
REDACTED = frozenset({("users", "password_hash"), ("customer_accounts", "password_hash")})
ROW_ACTIONS = ("insert", "update", "delete")
_PG_LOCK_KEY = 0x6163_6365_6C63  # the transaction-level advisory lock of the chain's appenders


@dataclass(frozen=True)
class Entry:
    """One chain entry as stored; `row` is the canonical JSON of the row (None: deleted)."""

    seq: int
    at_utc: str
    actor: str
    action: str
    table_name: str
    row_key: str
    row: str | None
    journal_id: int | None
    schema_fingerprint: str
    prev_hash: str
    hash: str
    signature: str | None = None  # hex Ed25519 signature of (seq, hash); not hashed
    key_id: str | None = None  # the records key that made it (hex SHA-256 of the public key)

    def computed_hash(self) -> str:
        """sha256(prev_hash || canonical entry), hex: what `hash` must be."""
        return entry_hash(
            self.prev_hash,
            seq=self.seq,
            at_utc=self.at_utc,
            actor=self.actor,
            action=self.action,
            table_name=self.table_name,
            row_key=self.row_key,
            row=self.row,
            journal_id=self.journal_id,
            schema_fingerprint=self.schema_fingerprint,
        )


def canonical(value: Any) -> str:
    """Sorted-key, compact, ASCII JSON: the one serialisation that is hashed."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True)


def entry_hash(prev_hash: str, **fields: Any) -> str:
    """Hex SHA-256 of the previous hash followed by the canonical JSON of the entry's fields."""
    return hashlib.sha256((prev_hash + canonical(fields)).encode("ascii")).hexdigest()


def _plain(table: str, column: str, value: Any) -> Any:
    if value is not None and (table, column) in REDACTED:
        return "sha256:" + hashlib.sha256(str(value).encode("utf-8")).hexdigest()
    if isinstance(value, datetime):
        moment = value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)
        return moment.isoformat()
    if isinstance(value, date):
        return value.isoformat()
    if isinstance(value, bytes):
        return value.hex()
    return value


def row_json(table: Table, row: Any) -> str:
    """A live row's content as the chain stores it: every column, canonical JSON."""
    return canonical({c.name: _plain(table.name, c.name, row[c.name]) for c in table.columns})


def row_key(table: Table, row: Any) -> str:
    """The row's primary key as the chain names it ('5'; 'a/b' for a composite key)."""
    return "/".join(str(row[c.name]) for c in table.primary_key.columns)


def chained_tables(metadata: MetaData | None = None) -> dict[str, Table]:
    """The audited tables by name (the mapped models' by default)."""
    tables = (metadata or Base.metadata).tables
    return {name: t for name, t in sorted(tables.items()) if name not in UNCHAINED}


def reflected_tables(connection: Connection) -> dict[str, Table]:
    """The audited tables as the database has them (during migrations, when they may differ
    from the models)."""
    metadata = MetaData()
    metadata.reflect(bind=connection)
    return chained_tables(metadata)


def has_chain(connection: Connection) -> bool:
    """Whether the database carries the chain (revision 0007 or later)."""
    return bool(inspect(connection).has_table(CHAIN_TABLE))


def has_signatures(connection: Connection) -> bool:
    """Whether the chain has the signature columns (revision 0011 or later)."""
    columns = {c["name"] for c in inspect(connection).get_columns(CHAIN_TABLE)}
    return set(SIGNED_COLUMNS) <= columns


def schema_fingerprint(connection: Connection) -> str:
    """What changes when the schema or its triggers change, read from their definitions (not
    a counter the writer can put back): on SQLite every table, index and trigger's SQL in
    sqlite_master; on PostgreSQL every user trigger's identity, enabled state and definition
    and the body, owner and security of the function it runs; hashed."""
    if connection.dialect.name == "sqlite":
        rows = connection.execute(
            text(
                "SELECT type, name, tbl_name, sql FROM sqlite_master "
                "WHERE sql IS NOT NULL AND name NOT LIKE 'sqlite_%' ORDER BY type, name"
            )
        ).all()
        return (
            "sqlite-def:" + hashlib.sha256(canonical([list(r) for r in rows]).encode()).hexdigest()
        )
    rows = connection.execute(
        text(
            "SELECT c.relname, t.tgname, t.oid::bigint, t.tgenabled::text, "
            "pg_get_triggerdef(t.oid), p.prosrc, p.prosecdef, p.proowner::regrole::text "
            "FROM pg_trigger t JOIN pg_class c ON c.oid = t.tgrelid "
            "JOIN pg_namespace n ON n.oid = c.relnamespace JOIN pg_proc p ON p.oid = t.tgfoid "
            "WHERE NOT t.tgisinternal AND n.nspname = current_schema() ORDER BY 1, 2"
        )
    ).all()
    return "pg-def:" + hashlib.sha256(canonical([list(r) for r in rows]).encode()).hexdigest()


def legacy_fingerprint(connection: Connection) -> str:
    """The fingerprint before revision 0011 (SQLite's schema cookie; PostgreSQL's trigger
    oids and states): what chains written before then recorded."""
    if connection.dialect.name == "sqlite":
        return f"sqlite:{connection.exec_driver_sql('PRAGMA schema_version').scalar()}"
    rows = connection.execute(
        text(
            "SELECT c.relname, t.tgname, t.oid::bigint, t.tgenabled::text FROM pg_trigger t "
            "JOIN pg_class c ON c.oid = t.tgrelid JOIN pg_namespace n ON n.oid = c.relnamespace "
            "WHERE NOT t.tgisinternal AND n.nspname = current_schema() ORDER BY 1, 2"
        )
    ).all()
    return "pg:" + hashlib.sha256(canonical([list(r) for r in rows]).encode()).hexdigest()


def _entry(row: Any) -> Entry:
    return Entry(**{name: row[name] for name in Entry.__dataclass_fields__ if name in row})


def read_entries(connection: Connection, *, last: int | None = None) -> list[Entry]:
    """The chain's entries in order (only the `last` ones when given)."""
    chain = ChainEntry.__table__
    columns = [c for c in chain.columns if c.name not in SIGNED_COLUMNS]
    if has_signatures(connection):
        columns = list(chain.columns)
    query = select(*columns).order_by(chain.c.seq.desc() if last else chain.c.seq)
    if last:
        query = query.limit(last)
    entries = [_entry(r._mapping) for r in connection.execute(query)]
    return entries[::-1] if last else entries


def head(connection: Connection) -> Entry | None:
    """The newest entry (None: an empty chain)."""
    entries = read_entries(connection, last=1)
    return entries[0] if entries else None


def head_hash(connection: Connection) -> str:
    """The chain head's hash (GENESIS for an empty chain): what seals and certificates carry."""
    latest = head(connection)
    return latest.hash if latest else GENESIS


def _lock(connection: Connection) -> None:
    """One appender at a time (SQLite: BEGIN IMMEDIATE already serialises writers)."""
    if connection.dialect.name == "postgresql":  # needs no privilege on the table
        connection.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": _PG_LOCK_KEY})


@dataclass(frozen=True)
class Change:
    """One change to enter: action, table, primary key, new row JSON (None: gone), journal id."""

    action: str
    table_name: str = ""
    row_key: str = ""
    row: str | None = None
    journal_id: int | None = None


def database_identity(connection: Connection) -> str:
    """The database as a workstation names it (backend, host, port, database; no user or
    password: the owner and the application role see one database)."""
    url = connection.engine.url
    return f"{url.get_backend_name()}://{url.host or ''}:{url.port or ''}/{url.database or ''}"


def _register_key(connection: Connection, key: records_key.RecordsKey) -> None:
    """Enter the key's public half in records_keys unless it is there."""
    present = connection.execute(select(KEYS.c.key_id).where(KEYS.c.key_id == key.key_id))
    if present.first() is None:
        created = datetime.now(UTC).isoformat(timespec="seconds")
        connection.execute(
            insert(KEYS).values(key_id=key.key_id, public_key=key.public_hex, created_utc=created)
        )


PENDING_HEAD = "records_signed_head"  # connection.info: (database id, seq, hash) to remember


def append(connection: Connection, *, actor: str, changes: list[Change]) -> list[Entry]:
    """Append the changes after the current head, in the caller's transaction, in one
    statement, the last one signed with the records key (RecordsKeyError without it). The
    entries. The head signed is noted in connection.info[PENDING_HEAD] for `remember_head`
    once the transaction commits."""
    if not changes:
        return []
    signed = _signatures_present(connection)  # False only while migrating to before 0011
    key = records_key.require_key() if signed else None
    _lock(connection)
    table = ChainEntry.__table__
    latest = connection.execute(
        select(table.c.seq, table.c.hash).order_by(table.c.seq.desc()).limit(1)
    ).first()
    seq, prev = (latest.seq, latest.hash) if latest else (0, GENESIS)
    at_utc = datetime.now(UTC).isoformat(timespec="microseconds")
    fingerprint = schema_fingerprint(connection)
    entries = []
    for change in changes:
        seq += 1
        fields: dict[str, Any] = {
            "seq": seq,
            "at_utc": at_utc,
            "actor": actor,
            "action": change.action,
            "table_name": change.table_name,
            "row_key": change.row_key,
            "row": change.row,
            "journal_id": change.journal_id,
            "schema_fingerprint": fingerprint,
        }
        entry = Entry(**fields, prev_hash=prev, hash=entry_hash(prev, **fields))
        entries.append(entry)
        prev = entry.hash
    if key is None:
        connection.execute(
            insert(ChainEntry),
            [{k: v for k, v in e.__dict__.items() if k not in SIGNED_COLUMNS} for e in entries],
        )
        return entries
    last = entries[-1]
    signed_before = connection.execute(
        select(sql_func.max(table.c.seq)).where(table.c.signature.is_not(None))
    ).scalar()
    first = entries[0].seq if signed_before is not None else 1  # the first covers all before
    signature = key.sign_head(first, last.seq, last.hash)
    entries[-1] = Entry(**{**last.__dict__, "signature": signature, "key_id": key.key_id})
    _register_key(connection, key)
    connection.execute(insert(ChainEntry), [e.__dict__ for e in entries])
    database = records_key.database_id(database_identity(connection))
    connection.info[PENDING_HEAD] = (database, last.seq, last.hash)
    return entries


def remember_head(connection: Connection) -> None:
    """After a commit: keep the head this workstation signed last (records_key heads)."""
    pending = connection.info.pop(PENDING_HEAD, None)
    if pending is not None:
        records_key.remember_signed(*pending)


def _after_commit(session: Session) -> None:
    pending = session.info.pop(PENDING_HEAD, None)
    if pending is not None:
        records_key.remember_signed(*pending)


def _unclaimed_journal_id(connection: Connection, table: str, key: str, action: str) -> int | None:
    """The newest journal row of this change that no chain entry claims yet (None: the
    statement was not executed, e.g. an ORM update without a net change)."""
    journal, chain = JournalEntry.__table__, ChainEntry.__table__
    claimed = select(chain.c.seq).where(chain.c.journal_id == journal.c.id).exists()
    query = select(sql_func.max(journal.c.id)).where(
        journal.c.table_name == table,
        journal.c.row_key == key,
        journal.c.action == action,
        ~claimed,
    )
    return connection.execute(query).scalar()


def live_row(connection: Connection, table: Table, key: str) -> str | None:
    """The live row of `table` with primary key `key` as the chain stores it (None: absent)."""
    columns = list(table.primary_key.columns)
    parts = key.split("/")
    if len(parts) != len(columns):
        return None
    try:
        condition = [c == c.type.python_type(v) for c, v in zip(columns, parts, strict=True)]
    except (ValueError, NotImplementedError):
        return None
    found = connection.execute(select(table).where(*condition)).first()
    return None if found is None else row_json(table, found._mapping)


def _record(action: str, mapper: Mapper[Any], connection: Connection, target: Any) -> None:
    """A mapper event: chain the row `target` just written by the ORM."""
    table = mapper.local_table
    if not isinstance(table, Table) or table.name in UNCHAINED or not _chain_present(connection):
        return
    key_values = mapper.primary_key_from_instance(target)
    key = "/".join(str(v) for v in key_values)
    journal_id = _unclaimed_journal_id(connection, table.name, key, action)
    if journal_id is None:  # no statement reached the table (nothing changed)
        return
    row = None if action == "delete" else live_row(connection, table, key)
    session = object_session(target)
    actor = str((session.info.get("actor") if session else None) or current_actor())
    append(connection, actor=actor, changes=[Change(action, table.name, key, row, journal_id)])
    pending = connection.info.pop(PENDING_HEAD, None)
    if session is not None and pending is not None:  # kept once the session commits
        session.info[PENDING_HEAD] = pending


_PRESENT: dict[str, bool] = {}
_SIGNED: dict[str, bool] = {}


def _signatures_present(connection: Connection) -> bool:
    """Whether this engine's chain has the signature columns (cached per URL once true)."""
    url = connection.engine.url.render_as_string(hide_password=True)
    if not _SIGNED.get(url):
        _SIGNED[url] = has_signatures(connection)
    return _SIGNED[url]


def _chain_present(connection: Connection) -> bool:
    """Whether this engine's database has the chain (cached per URL once true)."""
    url = connection.engine.url.render_as_string(hide_password=True)
    if not _PRESENT.get(url):
        _PRESENT[url] = has_chain(connection)
    return _PRESENT[url]


for _action in ROW_ACTIONS:

    def _listener(
        mapper: Mapper[Any], connection: Connection, target: Any, a: str = _action
    ) -> None:
        _record(a, mapper, connection, target)

    event.listen(Base, f"after_{_action}", _listener, propagate=True)

event.listen(Session, "after_commit", _after_commit)
event.listen(Session, "after_rollback", lambda session: session.info.pop(PENDING_HEAD, None))


# -- DDL used by migration 0007 (and by any later migration adding an audited table) --------


def journal_trigger_sql(dialect: str, table: str, key_column: str) -> list[str]:
    """The statements that make `table` note every row change in records_journal. On
    PostgreSQL the trigger fires ALWAYS, also under session_replication_role=replica."""
    if dialect == "postgresql":
        name = "records_journal_note"
        return [
            f"CREATE TRIGGER {name} AFTER INSERT OR UPDATE OR DELETE ON {table} "
            f"FOR EACH ROW EXECUTE FUNCTION {name}()",
            f"ALTER TABLE {table} ENABLE ALWAYS TRIGGER {name}",
        ]
    statements = []
    for action in ROW_ACTIONS:
        ref = "OLD" if action == "delete" else "NEW"
        statements.append(
            f"CREATE TRIGGER records_journal_{table}_{action} AFTER {action.upper()} ON {table} "
            f"BEGIN INSERT INTO {JOURNAL_TABLE} (table_name, row_key, action) "
            f"VALUES ('{table}', CAST({ref}.{key_column} AS TEXT), '{action}'); END"
        )
    return statements


PG_JOURNAL_FUNCTION = f"""
CREATE FUNCTION records_journal_note() RETURNS trigger AS $$
DECLARE r jsonb;
BEGIN
  IF TG_OP = 'DELETE' THEN r := to_jsonb(OLD); ELSE r := to_jsonb(NEW); END IF;
  INSERT INTO {JOURNAL_TABLE} (table_name, row_key, action)
  VALUES (TG_TABLE_NAME, coalesce(r->>'id', r->>'key'), lower(TG_OP));
  RETURN NULL;
END; $$ LANGUAGE plpgsql
"""


def append_only_sql(dialect: str, table: str) -> list[str]:
    """The statements that make `table` refuse UPDATE and DELETE (always, on PostgreSQL)."""
    message = f"{table} is append-only"
    if dialect == "postgresql":
        function = f"{table}_append_only"
        return [
            f"CREATE FUNCTION {function}() RETURNS trigger AS $$ BEGIN "
            f"RAISE EXCEPTION '{message}'; END; $$ LANGUAGE plpgsql",
            f"CREATE TRIGGER {function} BEFORE UPDATE OR DELETE ON {table} "
            f"FOR EACH ROW EXECUTE FUNCTION {function}()",
            f"ALTER TABLE {table} ENABLE ALWAYS TRIGGER {function}",
        ]
    return [
        f"CREATE TRIGGER {table}_no_{event_name.lower()} BEFORE {event_name} ON {table} "
        f"BEGIN SELECT RAISE(ABORT, '{message}'); END"
        for event_name in ("UPDATE", "DELETE")
    ]
