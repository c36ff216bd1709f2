"""The records key: an Ed25519 key, kept outside the database, that signs the records chain's
heads (app.records.db.chain), so that an entry appended, or a chain rebuilt, by someone who can
write the database but does not hold the key no longer verifies.

Kept like the lab's signing key (app.certificate.sign): a file the database never sees,
`$ACCELCAL_RECORDS_KEY`, else `records-key.pem` in the user's data directory (PKCS#8 PEM, mode
0600, encrypted when $ACCELCAL_RECORDS_KEY_PASSWORD is set when it is made). `accelcal db
upgrade` makes it when there is none, beside its public half `records-key.pub` (PEM).

What a check trusts is the *configured* public key, never the one the records hold (whoever
writes the database can add a key of his own): $ACCELCAL_RECORDS_PUBLIC_KEY (a PEM file), else
the `.pub` beside the key file, else the key file's own public half. The records hold every
public key used (table `records_keys`) so that a reader sees which one signed; a key id is the
hex SHA-256 of the raw 32-byte public key.

The key also keeps, per database, the newest head it signed (`records-key.heads/`, one small
JSON file per database): a chain cut back to an older signed head, or rebuilt after one, no
longer contains the head this workstation last signed.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.files import data_dir, write_new
from app.records.db.errors import RecordsInputError

log = logging.getLogger(__name__)

KEY_ENV = "ACCELCAL_RECORDS_KEY"
PASSWORD_ENV = "ACCELCAL_RECORDS_KEY_PASSWORD"
PUBLIC_ENV = "ACCELCAL_RECORDS_PUBLIC_KEY"
KEY_NAME = "records-key.pem"
MAX_KEY_BYTES = 16 * 1024
_DOMAIN = b"accelcal records chain head v1\n"  # signatures of nothing else verify as heads


class RecordsKeyError(RecordsInputError):
    """A records key that is missing, unreadable or not Ed25519; the message names the file."""


def key_path() -> Path:
    """Where the records key is: $ACCELCAL_RECORDS_KEY, else records-key.pem in the data
    directory."""
    chosen = os.environ.get(KEY_ENV)
    return Path(chosen).expanduser() if chosen else data_dir() / KEY_NAME


def public_path(private: Path) -> Path:
    """The public half's file beside the key file (records-key.pub)."""
    return private.with_suffix(".pub")


def key_id_of(public: Any) -> str:
    """The hex SHA-256 of an Ed25519 public key's 32 raw bytes: how records and seals name it."""
    from cryptography.hazmat.primitives import serialization

    raw = public.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return hashlib.sha256(raw).hexdigest()


def head_message(first: int, seq: int, head_hash: str) -> bytes:
    """The bytes a head's signature covers: a fixed domain, the first sequence number of the
    append it closes, its own, and its hash. `first` is one after the previous signed head
    (1 for the first signature of a chain), so entries slipped in unsigned between two appends
    make the later head's signature fail."""
    return _DOMAIN + f"{first}..{seq}:{head_hash}".encode("ascii")


@dataclass(frozen=True)
class RecordsKey:
    """The loaded private key, its id and its public half (raw bytes, hex)."""

    path: Path
    private: Any  # Ed25519PrivateKey
    key_id: str
    public_hex: str

    def sign_head(self, first: int, seq: int, head_hash: str) -> str:
        """The hex Ed25519 signature of the head (seq, hash) closing entries first..seq."""
        return str(self.private.sign(head_message(first, seq, head_hash)).hex())


def _password() -> bytes | None:
    secret = os.environ.get(PASSWORD_ENV)
    return secret.encode("utf-8") if secret else None


def _read(path: Path, what: str) -> bytes:
    from app.io.checks import InputFileError, read_regular_bytes

    try:
        return read_regular_bytes(path, MAX_KEY_BYTES, what)
    except InputFileError as exc:
        raise RecordsKeyError(str(exc)) from None


def _as_key(path: Path, private: Any) -> RecordsKey:
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    if not isinstance(private, Ed25519PrivateKey):
        raise RecordsKeyError(f"records key {path}: not an Ed25519 key")
    public = private.public_key()
    raw = public.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return RecordsKey(path, private, key_id_of(public), raw.hex())


@functools.lru_cache(maxsize=8)
def _load_cached(path: str, mtime_ns: int, size: int, password: bytes | None) -> RecordsKey:
    """The key file as it is now (the cache key: its path, time, size and the password)."""
    from cryptography.hazmat.primitives import serialization

    data = _read(Path(path), "records key")
    try:
        private = serialization.load_pem_private_key(data, password=password)
    except (ValueError, TypeError) as exc:
        raise RecordsKeyError(
            f"records key {path}: cannot load it ({exc}; wrong ${PASSWORD_ENV}?)"
        ) from None
    return _as_key(Path(path), private)


def load_key(path: Path | None = None) -> RecordsKey | None:
    """The records key at `path` (default: key_path()); None when there is no such file;
    RecordsKeyError when it cannot be read."""
    target = path or key_path()
    try:
        stat = target.stat()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise RecordsKeyError(f"records key {target}: {exc}") from None
    return _load_cached(str(target), stat.st_mtime_ns, stat.st_size, _password())


def require_key(path: Path | None = None) -> RecordsKey:
    """The records key, or RecordsKeyError saying where it was looked for and what to do."""
    key = load_key(path)
    if key is None:
        target = path or key_path()
        raise RecordsKeyError(
            f"records key {target}: missing; every write to the records is signed with it. "
            f"Copy the lab's records key there (or set ${KEY_ENV}); `accelcal db upgrade` "
            "makes one for new records"
        )
    return key


def create_key(path: Path | None = None) -> RecordsKey:
    """Make a new records key at `path` (default: key_path()), never over an existing one,
    with its public half beside it; the key."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    target = path or key_path()
    private = Ed25519PrivateKey.generate()
    secret = _password()
    encryption: Any = (
        serialization.BestAvailableEncryption(secret) if secret else serialization.NoEncryption()
    )
    pem = private.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, encryption
    )
    target.parent.mkdir(parents=True, exist_ok=True)
    write_new(target, pem)
    target.chmod(0o600)
    public_pem = private.public_key().public_bytes(
        serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
    )
    write_new(public_path(target), public_pem, overwrite=True)
    key = _as_key(target, private)
    log.info("records key %s made (id %s)", target, key.key_id[:16])
    return key


def ensure_key(path: Path | None = None) -> RecordsKey:
    """The records key, made first when there is none (`accelcal db upgrade`)."""
    return load_key(path) or create_key(path)


def _load_public(path: Path) -> Any:
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

    data = _read(path, "records public key")
    try:
        public = serialization.load_pem_public_key(data)
    except (ValueError, TypeError) as exc:
        raise RecordsKeyError(f"records public key {path}: not a PEM public key ({exc})") from None
    if not isinstance(public, Ed25519PublicKey):
        raise RecordsKeyError(f"records public key {path}: not an Ed25519 key")
    return public


@dataclass(frozen=True)
class TrustedKey:
    """The public key the checks trust, its id and where it was configured."""

    key_id: str
    public: Any  # Ed25519PublicKey
    source: str

    def verifies(self, first: int, seq: int, head_hash: str, signature_hex: str | None) -> bool:
        """Whether `signature_hex` is this key's signature of the head (seq, hash) closing
        entries first..seq."""
        from cryptography.exceptions import InvalidSignature

        if not signature_hex:
            return False
        try:
            message = head_message(first, seq, head_hash)
            self.public.verify(bytes.fromhex(signature_hex), message)
        except (InvalidSignature, ValueError):
            return False
        return True


def trusted_key(explicit: Path | None = None) -> TrustedKey | None:
    """The configured public key: `explicit`, else $ACCELCAL_RECORDS_PUBLIC_KEY, else the .pub
    beside the key file, else the key file's own public half; None when none is configured."""
    chosen = explicit or (Path(p) if (p := os.environ.get(PUBLIC_ENV)) else None)
    if chosen is not None:
        public = _load_public(chosen)
        return TrustedKey(key_id_of(public), public, str(chosen))
    private = key_path()
    beside = public_path(private)
    if beside.is_file():
        public = _load_public(beside)
        return TrustedKey(key_id_of(public), public, str(beside))
    key = load_key(private)
    if key is None:
        return None
    public = key.private.public_key()
    return TrustedKey(key.key_id, public, str(private))


# -- the newest head this workstation signed, per database -------------------------------


def _heads_folder() -> Path:
    return key_path().with_suffix(".heads")


def database_id(identity: str) -> str:
    """What names one database in the heads folder: its identity (backend, host, port,
    database; app.records.db.chain.database_identity), hashed. Not its content: a chain
    rebuilt from its first entry is the same database."""
    return hashlib.sha256(identity.encode()).hexdigest()[:32]


def last_signed(database: str) -> tuple[int, str] | None:
    """The newest head (seq, hash) this workstation signed in `database` (None: none kept)."""
    path = _heads_folder() / f"{database}.json"
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
        return int(raw["seq"]), str(raw["hash"])
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RecordsKeyError(f"records key's heads {path}: unreadable ({exc})") from None


def remember_signed(database: str, seq: int, head_hash: str) -> None:
    """Keep (seq, hash) as the newest head signed in `database` (an older one is not kept)."""
    before = last_signed(database)
    if before is not None and before[0] >= seq:
        return
    folder = _heads_folder()
    folder.mkdir(parents=True, exist_ok=True)
    write_new(
        folder / f"{database}.json",
        json.dumps({"seq": seq, "hash": head_hash}),
        overwrite=True,
    )


def forget_signed(database: str) -> None:
    """Drop what is kept for `database` (a new database made where an old one was)."""
    (_heads_folder() / f"{database}.json").unlink(missing_ok=True)
