"""open_engine's check of the schema without Alembic (issue 34): SCHEMA_HEAD is Alembic's head,
a database at head opens without importing Alembic, anything else is still asked of Alembic
(and refused with what to do)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from sqlalchemy import text

from app.records.db.engine import (
    SCHEMA_HEAD,
    DatabaseError,
    head_revision,
    make_engine,
    open_engine,
)

ROOT = Path(__file__).resolve().parents[4]


def test_schema_head_is_alembics_head(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'any.sqlite'}")
    try:
        assert head_revision(engine) == SCHEMA_HEAD
    finally:
        engine.dispose()


def test_a_database_at_head_opens_without_importing_alembic(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    open_engine(url, create=True).dispose()
    code = (
        "import sys\nfrom app.records.db.engine import open_engine\n"
        f"open_engine({url!r}).dispose()\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'alembic', 'numpy', 'scipy'}))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize(
    ("rows", "said"),
    [
        (["0010"], f"schema revision 0010, this program needs {SCHEMA_HEAD}"),
        (["0010", SCHEMA_HEAD], "cannot connect"),  # two heads: Alembic refuses them
    ],
)
def test_a_database_not_at_head_is_still_refused_by_alembic(
    tmp_path: Path, rows: list[str], said: str
) -> None:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    open_engine(url, create=True).dispose()
    engine = make_engine(url)
    with engine.begin() as connection:
        connection.execute(text("DELETE FROM alembic_version"))
        for row in rows:
            connection.execute(text("INSERT INTO alembic_version VALUES (:v)"), {"v": row})
    engine.dispose()
    with pytest.raises(DatabaseError, match=said):
        open_engine(url)


def test_the_alembic_free_check_holds_on_each_engine(migrated_url: str) -> None:
    """On SQLite and PostgreSQL: a database at head is at head for the Core check, and one
    moved back a revision is not (open_engine then refuses it through Alembic)."""
    from app.records.db.engine import _at_head

    engine = make_engine(migrated_url)
    try:
        assert _at_head(engine)
        with engine.begin() as connection:
            connection.execute(text("UPDATE alembic_version SET version_num = '0010'"))
        assert not _at_head(engine)
        with pytest.raises(DatabaseError, match="schema revision 0010"):
            open_engine(migrated_url)
    finally:
        engine.dispose()
