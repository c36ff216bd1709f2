"""What keeps the web view's sign-in standing under attack (issue 33 point 5).

- `Throttle`: every sign-in attempt is counted, atomically, *before* its password is checked;
  after `free` attempts of one key (a user name, a client address) each further attempt must
  wait a delay that doubles (2 s, 4 s, 8 s, ... up to the key's cap: 5 min for a user name,
  15 min for a client): a growing back-off, not a
  hard lock. A user's key is cleared when they sign in. Its memory is bounded (an LRU of at
  most `max_keys` keys per kind).
- `CheckSlots`: at most a few argon2 checks at once (64 MiB each); an attempt finding none free
  is answered 429 without hashing.
- `SessionStore`: sessions kept on the server (the cookie carries only a random id), revoked at
  sign-out, bound to the password hash they were opened with (a password change ends them),
  bounded in number and 8 h long.
- `client_address`: the client of a request; X-Forwarded-For is read only from a configured
  proxy address.
"""

from __future__ import annotations

import hashlib
import ipaddress
import math
import secrets
import threading
import time
from collections import Counter, OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from enum import StrEnum

FREE_ATTEMPTS = 5  # sign-in attempts of one key before the back-off starts
BACKOFF_BASE_S = 2.0  # the first delay; it doubles with every further attempt
USER_DELAY_CAP_S = 5 * 60.0  # a user name waits at most this long (no lasting lock-out)
CLIENT_DELAY_CAP_S = 15 * 60.0  # a client address at most this long
FORGET_AFTER_S = 15 * 60.0  # a key idle this long past its delay starts afresh
MAX_KEYS = 4096  # keys kept per kind (user names, clients): about 1 MB in all
PASSWORD_CHECKS_AT_ONCE = 2  # argon2id checks at once (64 MiB each)
SESSION_MAX_AGE_S = 8 * 3600  # a working day; then sign in again
MAX_SESSIONS = 2048  # server-side sessions kept (the least recently used goes first)


class KeyKind(StrEnum):
    """What a throttle key names."""

    USER = "user"
    CLIENT = "client"


@dataclass(slots=True)
class _Attempts:
    """One key's attempts: how many since it was last cleared, and when the latest was (s)."""

    count: int
    last: float


@dataclass(frozen=True)
class Verdict:
    """A throttle's answer: allowed, or how long to wait (s)."""

    allowed: bool
    wait_s: float = 0.0


@dataclass
class Throttle:
    """Sign-in attempts per user name and per client address, with a growing back-off."""

    free: int = FREE_ATTEMPTS
    base_s: float = BACKOFF_BASE_S
    caps_s: dict[KeyKind, float] = field(
        default_factory=lambda: {KeyKind.USER: USER_DELAY_CAP_S, KeyKind.CLIENT: CLIENT_DELAY_CAP_S}
    )
    forget_after_s: float = FORGET_AFTER_S
    max_keys: int = MAX_KEYS
    clock: Callable[[], float] = time.monotonic
    _keys: dict[KeyKind, OrderedDict[str, _Attempts]] = field(
        default_factory=lambda: {kind: OrderedDict() for kind in KeyKind}
    )
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def delay_s(self, kind: KeyKind, count: int) -> float:
        """The wait (s) before the attempt after `count` attempts of a key of `kind`."""
        if count < self.free:
            return 0.0
        return min(self.caps_s[kind], self.base_s * 2.0 ** min(count - self.free, 60))

    def _current(self, kind: KeyKind, key: str, now: float) -> _Attempts | None:
        attempts = self._keys[kind].get(key)
        if attempts is None:
            return None
        if now - attempts.last > self.delay_s(kind, attempts.count) + self.forget_after_s:
            del self._keys[kind][key]  # idle long enough: forgotten
            return None
        return attempts

    def attempt(self, user: str, client: str) -> Verdict:
        """Count one attempt of `user` from `client` if neither must wait (atomic: checked and
        counted under one lock, before any password is looked at); else how long to wait."""
        now = self.clock()
        keys = ((KeyKind.USER, user.casefold()), (KeyKind.CLIENT, client))
        with self._lock:
            wait = 0.0
            for kind, key in keys:
                attempts = self._current(kind, key, now)
                if attempts is not None:
                    due = attempts.last + self.delay_s(kind, attempts.count)
                    wait = max(wait, due - now)
            if wait > 0:
                return Verdict(False, wait)
            for kind, key in keys:
                table = self._keys[kind]
                attempts = self._current(kind, key, now)
                if attempts is None:
                    table[key] = _Attempts(1, now)
                else:
                    attempts.count += 1
                    attempts.last = now
                    table.move_to_end(key)
                while len(table) > self.max_keys:
                    table.popitem(last=False)  # the least recently tried goes
            return Verdict(True)

    def failed(self, user: str, client: str) -> None:
        """The check of an attempt counted by `attempt` failed: the keys' delays run from now
        (the answer), not from when the check began (an argon2 check of a second or more on a
        loaded server would otherwise eat the first delay)."""
        now = self.clock()
        with self._lock:
            for kind, key in ((KeyKind.USER, user.casefold()), (KeyKind.CLIENT, client)):
                attempts = self._keys[kind].get(key)
                if attempts is not None:
                    attempts.last = max(attempts.last, now)

    def succeeded(self, user: str, client: str) -> None:
        """`user` signed in from `client`: their name starts afresh, and the client's count
        gives back this attempt (its failures stay)."""
        with self._lock:
            self._keys[KeyKind.USER].pop(user.casefold(), None)
            attempts = self._keys[KeyKind.CLIENT].get(client)
            if attempts is not None and attempts.count > 0:
                attempts.count -= 1

    def size(self) -> int:
        """Keys held now (all kinds)."""
        with self._lock:
            return sum(len(table) for table in self._keys.values())


class CheckSlots:
    """At most `size` password checks at once; `take` never waits."""

    def __init__(self, size: int = PASSWORD_CHECKS_AT_ONCE) -> None:
        self._slots = threading.BoundedSemaphore(size)

    def take(self) -> bool:
        """Take a slot if one is free (then `give` it back), else False at once."""
        return self._slots.acquire(blocking=False)

    def give(self) -> None:
        self._slots.release()


def password_stamp(password_hash: str) -> str:
    """What a session remembers of its user's password hash (SHA-256, hex): a changed
    password no longer matches."""
    return hashlib.sha256(password_hash.encode()).hexdigest()


@dataclass(frozen=True)
class StaffSession:
    """A signed-in user's session on the server: who, since when (monotonic s), and the stamp
    of the password hash they signed in with."""

    username: str
    display_name: str
    started: float
    stamp: str


@dataclass
class SessionStore:
    """Server-side sessions by random id (256 bits), at most `max_sessions`, each
    `max_age_s` long."""

    max_sessions: int = MAX_SESSIONS
    max_age_s: float = SESSION_MAX_AGE_S
    clock: Callable[[], float] = time.monotonic
    _sessions: OrderedDict[str, StaffSession] = field(default_factory=OrderedDict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def open(self, username: str, display_name: str, password_hash: str) -> str:
        """A new session of `username`; its id (for the cookie)."""
        sid = secrets.token_urlsafe(32)
        session = StaffSession(username, display_name, self.clock(), password_stamp(password_hash))
        with self._lock:
            self._sessions[sid] = session
            while len(self._sessions) > self.max_sessions:
                self._sessions.popitem(last=False)
        return sid

    def get(self, sid: str) -> StaffSession | None:
        """The live session `sid`, or None (unknown, revoked or older than max_age_s)."""
        with self._lock:
            session = self._sessions.get(sid)
            if session is None:
                return None
            if self.clock() - session.started > self.max_age_s:
                del self._sessions[sid]
                return None
            self._sessions.move_to_end(sid)
            return session

    def revoke(self, sid: str) -> None:
        """End session `sid` (sign-out)."""
        with self._lock:
            self._sessions.pop(sid, None)

    def revoke_user(self, username: str) -> int:
        """End every session of `username` (password changed, user made inactive); how many."""
        with self._lock:
            ended = [sid for sid, s in self._sessions.items() if s.username == username]
            for sid in ended:
                del self._sessions[sid]
        return len(ended)

    def __len__(self) -> int:
        with self._lock:
            return len(self._sessions)


def parse_proxies(text: str) -> tuple[str, ...]:
    """Trusted proxy addresses from "ADDR[,ADDR...]" (IPv4 or IPv6, normalised); ValueError
    naming --proxy for anything else."""
    found = []
    for item in (part.strip() for part in text.split(",")):
        try:
            found.append(str(ipaddress.ip_address(item)))
        except ValueError:
            raise ValueError(f"--proxy: {item!r} is not an IP address") from None
    return tuple(found)


def client_address(peer: str | None, forwarded_for: Iterable[str], proxies: Iterable[str]) -> str:
    """The client's address: the peer's own unless the peer is one of `proxies`; then the
    right-most X-Forwarded-For entry that is not itself a trusted proxy (what the proxy saw;
    anything further left the client wrote itself)."""
    trusted = set(proxies)
    if peer is None:
        return "?"
    try:
        peer = str(ipaddress.ip_address(peer))  # one spelling per address (IPv6)
    except ValueError:
        return peer
    if peer not in trusted:
        return peer
    hops = [hop.strip() for line in forwarded_for for hop in line.split(",") if hop.strip()]
    for hop in reversed(hops):
        if hop not in trusted:
            try:
                return str(ipaddress.ip_address(hop))
            except ValueError:
                return peer  # garbage from the proxy's side: count it on the proxy
    return peer


MIN_SECRET_LENGTH = 32
MIN_SECRET_BITS = 100.0  # the secret's estimated entropy (bits), see secret_problem
MAX_REPEAT = 8  # no run of characters this long occurs twice in a secret


def secret_problem(secret: str) -> str | None:
    """Why `secret` is too weak to sign sessions with, or None: shorter than
    MIN_SECRET_LENGTH; a substring of MAX_REPEAT characters occurring twice (repetition:
    'abcd' * 10); fewer than MIN_SECRET_BITS by the Shannon estimate of its own characters
    (length x entropy per character: 40 x 'a' is 0 bits, 43 characters of
    secrets.token_urlsafe(32) about 220)."""
    if len(secret) < MIN_SECRET_LENGTH:
        return f"shorter than {MIN_SECRET_LENGTH} characters"
    seen: set[str] = set()
    for start in range(len(secret) - MAX_REPEAT + 1):
        piece = secret[start : start + MAX_REPEAT]
        if piece in seen:
            return f"repeats {piece!r}"
        seen.add(piece)
    counts = Counter(secret)
    per_char = -sum(n / len(secret) * math.log2(n / len(secret)) for n in counts.values())
    bits = per_char * len(secret)
    if bits < MIN_SECRET_BITS:
        return f"about {bits:.0f} bits of entropy, fewer than {MIN_SECRET_BITS:.0f}"
    return None
