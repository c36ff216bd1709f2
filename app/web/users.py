"""Staff users of the web view: argon2id password hashes (argon2-cffi, its default RFC 9106
low-memory parameters), adding a user and checking a password.

`add_user` is the one writer (`list_users` reads them): it audits the new row like every
records write, but with the hash left out of the audit trail (which is append-only and must
not keep password material).
"""

from __future__ import annotations

import json
import re
from datetime import UTC, datetime
from typing import Protocol, TypeVar

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from app.records.db.audit import current_actor
from app.records.db.lab import RecordsError
from app.records.db.models import AuditEntry, User

MIN_PASSWORD_LENGTH = 12
USERNAME = re.compile(r"^[A-Za-z0-9._-]{2,100}$")


def _hasher():  # argon2's PasswordHasher, imported when needed
    from argon2 import PasswordHasher

    return PasswordHasher()


def hash_password(password: str) -> str:
    """The argon2id hash of `password` (salted, PHC string format)."""
    return str(_hasher().hash(password))


def password_matches(password_hash: str, password: str) -> bool:
    """Whether `password` is the one `password_hash` was made from (False for a malformed
    hash too)."""
    from argon2.exceptions import InvalidHashError, VerificationError

    try:
        return bool(_hasher().verify(password_hash, password))
    except (VerificationError, InvalidHashError):
        return False


_DUMMY_HASH: list[str] = []


def dummy_check(password: str) -> None:
    """Spend the time of one password check (for unknown users: no timing tells them apart)."""
    if not _DUMMY_HASH:
        _DUMMY_HASH.append(hash_password("not a password of anyone"))
    password_matches(_DUMMY_HASH[0], password)


class _SignIn(Protocol):
    @property
    def active(self) -> bool: ...
    @property
    def password_hash(self) -> str: ...


Account = TypeVar("Account", bound=_SignIn)


def signed_in(account: Account | None, password: str) -> Account | None:
    """`account` when it is active and `password` is its own, else None; a missing account
    (an unknown name) costs the time of a password check too. Staff and customers alike."""
    if account is None:
        dummy_check(password)
        return None
    if account.active and password_matches(account.password_hash, password):
        return account
    return None


def checked_new_account(username: str, password: str, display_name: str) -> tuple[str, str]:
    """`username` and `display_name` stripped, when they and `password` may make an account
    (staff or customer): RecordsError naming the field otherwise."""
    username = username.strip()
    if not USERNAME.match(username):
        raise RecordsError(
            f"username: {username!r} must be 2 to 100 letters, digits, '.', '_' or '-'"
        )
    if len(password) < MIN_PASSWORD_LENGTH:
        raise RecordsError(f"password: shorter than {MIN_PASSWORD_LENGTH} characters")
    display_name = display_name.strip()
    if not display_name or len(display_name) > 200:
        raise RecordsError("display name: must be 1 to 200 characters")
    return username, display_name


def list_users(engine: Engine) -> list[User]:
    """Every staff user, by user name (the rows carry their hash: show only the other
    columns)."""
    with Session(engine) as s:
        return list(s.scalars(select(User).order_by(User.username)).all())


def add_user(
    engine: Engine,
    username: str,
    password: str,
    *,
    display_name: str,
    actor: str | None = None,
) -> None:
    """Add staff user `username` (letters, digits, . _ -; 2 to 100) with `password` (at least
    MIN_PASSWORD_LENGTH characters) and a display name; RecordsError naming the field when
    refused. Audited by `actor` (default: the operating-system user), without the hash."""
    username, display_name = checked_new_account(username, password, display_name)
    now = datetime.now(UTC)
    with Session(engine) as s, s.begin():
        if s.scalar(select(User).where(User.username == username)):
            raise RecordsError(f"username: {username!r} already exists")
        s.add(
            User(
                username=username,
                display_name=display_name,
                password_hash=hash_password(password),
                active=True,
                created_utc=now,
            )
        )
        changes = {"username": username, "display_name": display_name, "active": True}
        changes["password_hash"] = "(not recorded)"
        s.add(
            AuditEntry(
                at_utc=now,
                actor=actor or current_actor(),
                action="insert",
                table_name="users",
                row_key=username,
                changes=json.dumps(changes, sort_keys=True),
            )
        )


def set_password(engine: Engine, username: str, password: str, *, actor: str | None = None) -> None:
    """Give staff user `username` a new `password` (at least MIN_PASSWORD_LENGTH characters);
    RecordsError naming the field when refused. Every web session the user had ends at its
    next request (a session is bound to the hash it was opened with: app.web.guard). Audited
    by `actor` (default: the operating-system user), without the hash."""
    if len(password) < MIN_PASSWORD_LENGTH:
        raise RecordsError(f"password: shorter than {MIN_PASSWORD_LENGTH} characters")
    now = datetime.now(UTC)
    with Session(engine) as s, s.begin():
        user = s.scalar(select(User).where(User.username == username.strip()))
        if user is None:
            raise RecordsError(f"username: no staff user {username.strip()!r}")
        user.password_hash = hash_password(password)
        s.add(
            AuditEntry(
                at_utc=now,
                actor=actor or current_actor(),
                action="update",
                table_name="users",
                row_key=user.username,
                changes=json.dumps({"password_hash": "(not recorded)"}, sort_keys=True),
            )
        )
