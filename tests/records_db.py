"""Records databases for tests, migrated once per test process and copied per test.

Migrating a new database through every Alembic revision takes 0.5-1 s (more under load); a
test gets a copy of one already migrated instead: for SQLite a copy of a file migrated to head
once per process (`new_records`), for PostgreSQL a database created from a template database
migrated to head once per server (`postgres_database(..., template=...)`). The fixtures over
these are in tests/conftest.py (`records_url`, `engine`, `empty_url`, `postgres_server`).
"""

from __future__ import annotations

import atexit
import functools
import itertools
import os
import shutil
import tempfile
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from sqlalchemy import text

if TYPE_CHECKING:
    from app.records.db.lab import Lab

_counter = itertools.count()
_lock = threading.Lock()


@functools.cache
def migrated_sqlite() -> Path:
    """An SQLite records file at the newest schema, migrated once per test process; the
    template of every copy (no test opens it)."""
    from app.records.db.engine import make_engine, resolve_url, upgrade

    folder = Path(tempfile.mkdtemp(prefix="accelcal-tests-records-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    path = folder / "records.sqlite"
    engine = make_engine(resolve_url(f"sqlite:///{path}"))
    upgrade(engine)
    engine.dispose()  # the last connection closed: the WAL is checkpointed into the file
    leftovers = [p.name for p in folder.iterdir() if p != path]
    assert not leftovers, f"the migrated template left {leftovers} beside it"
    return path


def new_records(path: Path) -> str:
    """A new SQLite records database at `path`, at the newest schema (a copy of the migrated
    template); its URL."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists():
        raise FileExistsError(f"{path}: a records database is there already")
    shutil.copyfile(migrated_sqlite(), path)
    return f"sqlite:///{path}"


def postgres_database(server_url: str, template: str | None = None) -> str:
    """A new database on the session's server: empty, or a copy of the database `template`
    (CREATE DATABASE ... TEMPLATE); its URL."""
    from app.records.db.engine import make_engine, resolve_url

    name = f"accelcal_test_{os.getpid()}_{next(_counter)}"
    copy = f' TEMPLATE "{template}"' if template else ""
    admin = make_engine(resolve_url(server_url))
    with admin.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"{copy}'))
    admin.dispose()
    return _with_database(server_url, name)


def migrated_postgres_template(server_url: str) -> str:
    """The name of a database on the server migrated to head once per process (cached per
    server); a template for `postgres_database`, never connected to after its migration."""
    with _lock:
        return _migrated_postgres_template(server_url)


@functools.cache
def _migrated_postgres_template(server_url: str) -> str:
    from app.records.db.engine import make_engine, resolve_url, upgrade

    url = postgres_database(server_url)
    engine = make_engine(resolve_url(url))
    upgrade(engine)
    engine.dispose()  # CREATE DATABASE ... TEMPLATE needs no other session on the template
    return url.partition("?")[0].rsplit("/", 1)[1]  # the query holds the socket's folder


def _with_database(server_url: str, name: str) -> str:
    base, _, query = server_url.partition("?")
    return f"{base.rsplit('/', 1)[0]}/{name}?{query}"


# The lab most records tests start from: the sensors' owners as customers (in order of first
# appearance), the model PCB 352C33 (5 %, up to 10 kHz) and the sensors of it.
SEED_MODEL = ("PCB", "352C33")


def seed_lab(
    lab: Lab,
    sensors: Mapping[str, str],
    *,
    nominal_sensitivity: float = 10.2,
    frequency_min_hz: float = 1.0,
    addresses: Mapping[str, str] | None = None,
) -> Lab:
    """Add to `lab` the customers owning `sensors` (serial -> owner; an address from
    `addresses` where given, else "1 <owner> Street": a certificate needs one, issue 35), the
    model PCB 352C33 (`nominal_sensitivity` in mV/(m/s^2),
    tolerance 5 %, `frequency_min_hz` to 10 kHz) and the sensors; returns `lab`."""
    for owner in dict.fromkeys(sensors.values()):
        lab.add_customer(owner, (addresses or {}).get(owner, f"1 {owner} Street"))
    lab.add_model(
        *SEED_MODEL,
        nominal_sensitivity=nominal_sensitivity,
        unit="mV/(m/s^2)",
        tolerance_percent=5,
        frequency_min_hz=frequency_min_hz,
        frequency_max_hz=10000,
    )
    for serial, owner in sensors.items():
        lab.add_sensor(serial, model=SEED_MODEL[1], owner=owner)
    return lab


STAFF_PASSWORD = "a long staff password"


def add_staff(engine_or_url: object, *people: tuple[str, str]) -> None:
    """Users of the records (user name, recorded name), as `accelcal records user add` adds
    them (app.web.users.add_user): the persons the two-person rule resolves signatories to
    (issue 33). Their password is hashed once per process (argon2 takes 64 MiB and a good part
    of a second per hash on a loaded machine; the hash is not what these users are for)."""
    from unittest import mock

    from sqlalchemy import Engine

    from app.records.db.engine import open_engine
    from app.web import users

    engine = engine_or_url if isinstance(engine_or_url, Engine) else open_engine(str(engine_or_url))
    known = _staff_hash()
    with mock.patch.object(users, "hash_password", lambda password: known):
        for username, name in people:
            users.add_user(engine, username, STAFF_PASSWORD, display_name=name, actor="test")


@functools.cache
def _staff_hash() -> str:
    from app.web.users import hash_password

    return hash_password(STAFF_PASSWORD)
