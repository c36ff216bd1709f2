"""Customer accounts of the web view's portal (issue 35 point 5): created, disabled, given a
new password and removed by staff (`accelcal records account ...`), each bound to one records
customer. Passwords are hashed as the staff's are (argon2id, app.web.users); every write is
audited like every records write, with the hash left out of the audit trail (append-only: it
must not keep password material; the chain keeps only the hash's SHA-256).

A customer account and a staff user are different rows of different tables: the portal's
sign-in reads only `customer_accounts`, the staff sign-in only `users`, so no customer
password ever opens a staff session. A user name is refused when a staff user has it (one
name, one person, in the logs and the audit trail).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from app.records.db.audit import current_actor
from app.records.db.lab import RecordsError
from app.records.db.models import AuditEntry, Customer, CustomerAccount, User
from app.web.users import MIN_PASSWORD_LENGTH, checked_new_account, hash_password

TABLE = "customer_accounts"


@dataclass(frozen=True)
class AccountRow:
    """A customer account as listed (no hash): user name, display name, the customer's name,
    whether it may sign in, and when it was created (UTC)."""

    username: str
    display_name: str
    customer: str
    active: bool
    created_utc: datetime


def _audit(
    s: Session, action: str, username: str, changes: dict[str, Any], actor: str | None
) -> None:
    s.add(
        AuditEntry(
            at_utc=datetime.now(UTC),
            actor=actor or current_actor(),
            action=action,
            table_name=TABLE,
            row_key=username,
            changes=json.dumps(changes, sort_keys=True),
        )
    )


def _account(s: Session, username: str) -> CustomerAccount:
    account = s.scalar(select(CustomerAccount).where(CustomerAccount.username == username.strip()))
    if account is None:
        raise RecordsError(f"username: no customer account {username.strip()!r}")
    return account


def add_account(
    engine: Engine,
    username: str,
    password: str,
    *,
    customer: str,
    display_name: str,
    actor: str | None = None,
) -> None:
    """Add customer account `username` (letters, digits, . _ -; 2 to 100), bound to the
    records customer named `customer`, with `password` (at least MIN_PASSWORD_LENGTH
    characters) and a display name; RecordsError naming the field when refused (also when a
    staff user or another account has the name). Audited by `actor` (default: the
    operating-system user), without the hash."""
    username, display_name = checked_new_account(username, password, display_name)
    with Session(engine) as s, s.begin():
        owner = s.scalar(select(Customer).where(Customer.name == customer.strip()))
        if owner is None:
            raise RecordsError(f"customer: no customer {customer.strip()!r} in the records")
        if s.scalar(select(CustomerAccount).where(CustomerAccount.username == username)):
            raise RecordsError(f"username: {username!r} already exists")
        if s.scalar(select(User).where(User.username == username)):
            raise RecordsError(f"username: {username!r} is a staff user's name")
        s.add(
            CustomerAccount(
                username=username,
                display_name=display_name,
                customer_id=owner.id,
                password_hash=hash_password(password),
                active=True,
                created_utc=datetime.now(UTC),
            )
        )
        changes = {
            "username": username,
            "display_name": display_name,
            "customer": owner.name,
            "active": True,
            "password_hash": "(not recorded)",
        }
        _audit(s, "insert", username, changes, actor)


def list_accounts(engine: Engine) -> list[AccountRow]:
    """Every customer account, by user name."""
    with Session(engine) as s:
        rows = s.execute(
            select(CustomerAccount, Customer.name)
            .join(Customer, CustomerAccount.customer_id == Customer.id)
            .order_by(CustomerAccount.username)
        ).all()
        return [
            AccountRow(a.username, a.display_name, name, a.active, a.created_utc)
            for a, name in rows
        ]


def set_account_active(
    engine: Engine, username: str, active: bool, *, actor: str | None = None
) -> None:
    """Disable (active False: every portal session of it ends at its next request) or
    re-enable customer account `username`; RecordsError naming the field when unknown.
    Audited by `actor`."""
    with Session(engine) as s, s.begin():
        account = _account(s, username)
        if account.active != active:
            _audit(s, "update", account.username, {"active": [account.active, active]}, actor)
            account.active = active


def set_account_password(
    engine: Engine, username: str, password: str, *, actor: str | None = None
) -> None:
    """Give customer account `username` a new `password` (at least MIN_PASSWORD_LENGTH
    characters; its portal sessions end at their next request); RecordsError naming the field
    when refused. Audited by `actor`, without the hash."""
    if len(password) < MIN_PASSWORD_LENGTH:
        raise RecordsError(f"password: shorter than {MIN_PASSWORD_LENGTH} characters")
    with Session(engine) as s, s.begin():
        account = _account(s, username)
        account.password_hash = hash_password(password)
        _audit(s, "update", account.username, {"password_hash": "(not recorded)"}, actor)


def remove_account(engine: Engine, username: str, *, actor: str | None = None) -> None:
    """Remove customer account `username` (its row goes; the audit trail and the chain keep
    that it existed and who removed it); RecordsError naming the field when unknown."""
    with Session(engine) as s, s.begin():
        account = _account(s, username)
        customer = s.get(Customer, account.customer_id)
        changes = {"username": account.username, "customer": customer.name if customer else None}
        _audit(s, "delete", account.username, changes, actor)
        s.delete(account)
