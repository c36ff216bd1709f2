"""Business rules the database itself enforces, for every role that writes it (migration 0011):

- a certificate that is withdrawn or replaced stays so (no UPDATE of it at all), and none is
  ever deleted;
- an issued certificate is never edited: the only changes are its state to withdrawn or
  replaced (with the reason) and its files (path, SHA-256, DCC's SHA-256) set once;
- on PostgreSQL, a user (staff, or a customer's account: migration 0012) is added, re-enabled
  or given a new name, password or customer only by an administrator: a member of the role
  that owns the table (the owner role of docs/records.md),
  never by the application role. SQLite has no roles: there a user added behind the
  application's back is caught by the chain (an unsigned entry, or a row no entry claims).

The PostgreSQL triggers fire ALWAYS (also under session_replication_role = replica) and are
owned by the owner role, which alone can drop them; the quick check reads their definitions.
"""

from __future__ import annotations

# the certificate columns an issued certificate may change (see the module docstring)
CERTIFICATE_STATE = ("state", "reason")
CERTIFICATE_FILES = ("file", "sha256", "dcc_sha256")
FINAL_MESSAGE = "certificates: a withdrawn or replaced certificate stays so"
FROZEN_MESSAGE = "certificates: an issued certificate is never edited"
FILES_MESSAGE = "certificates: the files of a certificate are set once"
DELETE_MESSAGE = "certificates: a certificate is never deleted"
USERS_MESSAGE = "users: only an administrator adds, re-enables or renames a user or sets a password"
ACCOUNTS_MESSAGE = (
    "customer_accounts: only an administrator adds, re-enables, renames or rebinds an account "
    "or sets a password"
)


def sqlite_rules(certificate_columns: list[str]) -> list[str]:
    """The SQLite triggers of the certificate rules over the table's columns as migrated."""
    frozen = [c for c in certificate_columns if c not in CERTIFICATE_STATE + CERTIFICATE_FILES]
    changed = " OR ".join(f"NEW.{c} IS NOT OLD.{c}" for c in frozen)
    files = " OR ".join(
        f"(OLD.{c} IS NOT NULL AND NEW.{c} IS NOT OLD.{c})" for c in CERTIFICATE_FILES
    )
    return [
        "CREATE TRIGGER records_rule_certificate_final BEFORE UPDATE ON certificates "
        f"WHEN OLD.state <> 'issued' BEGIN SELECT RAISE(ABORT, '{FINAL_MESSAGE}'); END",
        "CREATE TRIGGER records_rule_certificate_frozen BEFORE UPDATE ON certificates "
        f"WHEN OLD.state = 'issued' AND ({changed} OR (NEW.state = 'issued' AND "
        f"NEW.reason IS NOT OLD.reason)) BEGIN SELECT RAISE(ABORT, '{FROZEN_MESSAGE}'); END",
        "CREATE TRIGGER records_rule_certificate_files BEFORE UPDATE ON certificates "
        f"WHEN {files} BEGIN SELECT RAISE(ABORT, '{FILES_MESSAGE}'); END",
        "CREATE TRIGGER records_rule_certificate_delete BEFORE DELETE ON certificates "
        f"BEGIN SELECT RAISE(ABORT, '{DELETE_MESSAGE}'); END",
    ]


CUSTOMER_MESSAGE = "certificates: a certificate is issued to a customer"
SQLITE_CERTIFICATE_RULES = (
    "records_rule_certificate_final",
    "records_rule_certificate_frozen",
    "records_rule_certificate_files",
    "records_rule_certificate_delete",
)


def sqlite_customer_rule() -> str:
    """SQLite's stand-in for the NOT NULL of certificates.customer_id (migration 0014: a
    column added by ALTER TABLE cannot be NOT NULL there): a certificate issued to nobody is
    refused."""
    return (
        "CREATE TRIGGER records_rule_certificate_customer BEFORE INSERT ON certificates "
        f"WHEN NEW.customer_id IS NULL BEGIN SELECT RAISE(ABORT, '{CUSTOMER_MESSAGE}'); END"
    )


_PG_CERTIFICATES = f"""
CREATE FUNCTION records_rule_certificates() RETURNS trigger AS $$
DECLARE
  loose text[] := ARRAY[{", ".join(f"'{c}'" for c in CERTIFICATE_STATE + CERTIFICATE_FILES)}];
BEGIN
  IF TG_OP = 'DELETE' THEN
    RAISE EXCEPTION '{DELETE_MESSAGE} (%)', OLD.number;
  END IF;
  IF OLD.state <> 'issued' THEN
    RAISE EXCEPTION '{FINAL_MESSAGE} (% is %)', OLD.number, OLD.state;
  END IF;
  IF (to_jsonb(NEW) - loose) IS DISTINCT FROM (to_jsonb(OLD) - loose)
     OR (NEW.state = 'issued' AND NEW.reason IS DISTINCT FROM OLD.reason) THEN
    RAISE EXCEPTION '{FROZEN_MESSAGE} (%)', OLD.number;
  END IF;
  IF (OLD.file IS NOT NULL AND NEW.file IS DISTINCT FROM OLD.file)
     OR (OLD.sha256 IS NOT NULL AND NEW.sha256 IS DISTINCT FROM OLD.sha256)
     OR (OLD.dcc_sha256 IS NOT NULL AND NEW.dcc_sha256 IS DISTINCT FROM OLD.dcc_sha256) THEN
    RAISE EXCEPTION '{FILES_MESSAGE} (%)', OLD.number;
  END IF;
  RETURN NEW;
END; $$ LANGUAGE plpgsql
"""

_PG_USERS = f"""
CREATE FUNCTION records_rule_users() RETURNS trigger AS $$
BEGIN
  IF TG_OP = 'UPDATE' AND NEW.username = OLD.username AND NEW.password_hash = OLD.password_hash
     AND NOT (NEW.active AND NOT OLD.active) THEN
    RETURN NEW;
  END IF;
  IF pg_has_role(current_user, (SELECT relowner FROM pg_class WHERE oid = TG_RELID), 'MEMBER')
  THEN
    IF TG_OP = 'DELETE' THEN RETURN OLD; END IF;
    RETURN NEW;
  END IF;
  RAISE EXCEPTION '{USERS_MESSAGE} (role %)', current_user;
END; $$ LANGUAGE plpgsql
"""


def postgresql_rules() -> list[str]:
    """The PostgreSQL functions and ALWAYS triggers of the certificate and user rules."""
    return [
        _PG_CERTIFICATES,
        "CREATE TRIGGER records_rule_certificates BEFORE UPDATE OR DELETE ON certificates "
        "FOR EACH ROW EXECUTE FUNCTION records_rule_certificates()",
        "ALTER TABLE certificates ENABLE ALWAYS TRIGGER records_rule_certificates",
        _PG_USERS,
        "CREATE TRIGGER records_rule_users BEFORE INSERT OR UPDATE OR DELETE ON users "
        "FOR EACH ROW EXECUTE FUNCTION records_rule_users()",
        "ALTER TABLE users ENABLE ALWAYS TRIGGER records_rule_users",
    ]


_PG_ACCOUNTS = f"""
CREATE FUNCTION records_rule_customer_accounts() RETURNS trigger AS $$
BEGIN
  IF TG_OP = 'UPDATE' AND NEW.username = OLD.username AND NEW.password_hash = OLD.password_hash
     AND NEW.customer_id = OLD.customer_id AND NOT (NEW.active AND NOT OLD.active) THEN
    RETURN NEW;
  END IF;
  IF pg_has_role(current_user, (SELECT relowner FROM pg_class WHERE oid = TG_RELID), 'MEMBER')
  THEN
    IF TG_OP = 'DELETE' THEN RETURN OLD; END IF;
    RETURN NEW;
  END IF;
  RAISE EXCEPTION '{ACCOUNTS_MESSAGE} (role %)', current_user;
END; $$ LANGUAGE plpgsql
"""


def postgresql_account_rules() -> list[str]:
    """The PostgreSQL function and ALWAYS trigger of the customer accounts' rule (migration
    0012): as the staff users', and the customer an account is bound to is the
    administrator's to change too (the application role may only disable one)."""
    return [
        _PG_ACCOUNTS,
        "CREATE TRIGGER records_rule_customer_accounts BEFORE INSERT OR UPDATE OR DELETE ON "
        "customer_accounts FOR EACH ROW EXECUTE FUNCTION records_rule_customer_accounts()",
        "ALTER TABLE customer_accounts ENABLE ALWAYS TRIGGER records_rule_customer_accounts",
    ]
