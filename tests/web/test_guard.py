"""app.web.guard on its own (a fake clock, no server): the throttle counts before it lets a
check run and does so atomically, backs off by doubling to its caps, forgets, and holds a
bounded number of keys; the session store is bounded and ends sessions; X-Forwarded-For is
read only from a trusted proxy, right-most first."""

from __future__ import annotations

import threading
import tracemalloc

import pytest

from app.web.guard import (
    CLIENT_DELAY_CAP_S,
    FREE_ATTEMPTS,
    MAX_KEYS,
    USER_DELAY_CAP_S,
    CheckSlots,
    KeyKind,
    SessionStore,
    Throttle,
    client_address,
    parse_proxies,
    password_stamp,
)


class Clock:
    """A monotonic clock the test moves (s)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_40_threads_at_once_get_exactly_the_free_attempts() -> None:
    throttle = Throttle()
    gate = threading.Barrier(40)
    allowed: list[bool] = []

    def one() -> None:
        gate.wait()
        allowed.append(throttle.attempt("qm", "10.0.0.1").allowed)

    threads = [threading.Thread(target=one) for _ in range(40)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert allowed.count(True) == FREE_ATTEMPTS and len(allowed) == 40


def test_the_delay_doubles_to_the_users_cap_and_the_clients() -> None:
    clock = Clock()
    throttle = Throttle(clock=clock)
    waits = []
    for i in range(20):
        verdict = throttle.attempt("qm", f"10.0.1.{i}")  # a new client each time: the user's
        if not verdict.allowed:
            waits.append(round(verdict.wait_s))
            clock.now += verdict.wait_s
            assert throttle.attempt("qm", f"10.0.1.{i}").allowed
    assert waits == [2, 4, 8, 16, 32, 64, 128, 256, 300, 300, 300, 300, 300, 300, 300]
    assert USER_DELAY_CAP_S == 300
    client = Throttle(clock=clock)
    for i in range(30):
        verdict = client.attempt(f"user{i}", "10.0.2.1")
        if not verdict.allowed:
            clock.now += verdict.wait_s
            assert client.attempt(f"user{i}", "10.0.2.1").allowed
    assert client.delay_s(KeyKind.CLIENT, 30) == CLIENT_DELAY_CAP_S == 900
    assert client.delay_s(KeyKind.USER, 30) == USER_DELAY_CAP_S


def test_a_refused_attempt_is_not_counted_and_a_sign_in_clears_the_user() -> None:
    clock = Clock()
    throttle = Throttle(clock=clock)
    for _ in range(FREE_ATTEMPTS):
        assert throttle.attempt("QM", "10.0.3.1").allowed
    for _ in range(100):  # hammering while refused does not lengthen the wait
        assert throttle.attempt("qm", "10.0.3.2").wait_s == pytest.approx(2.0)
    clock.now += 2.0
    assert throttle.attempt("qm", "10.0.3.2").allowed
    throttle.succeeded("qm", "10.0.3.2")
    assert throttle.attempt("Qm", "10.0.3.2").allowed  # the name starts afresh


def test_the_delay_runs_from_the_failed_checks_answer() -> None:
    """A check that took 3 s (argon2 on a loaded server) does not use up the 2 s delay."""
    clock = Clock()
    throttle = Throttle(clock=clock)
    for _ in range(FREE_ATTEMPTS):
        assert throttle.attempt("qm", "10.0.6.1").allowed
        clock.now += 3.0  # the check
        throttle.failed("qm", "10.0.6.1")
    clock.now += 0.5
    assert throttle.attempt("qm", "10.0.6.2").wait_s == pytest.approx(1.5)


def test_a_sign_in_gives_back_only_its_own_attempt_of_the_client() -> None:
    """An attacker with an account of their own cannot wipe their client's failures."""
    throttle = Throttle(clock=Clock())
    for i in range(FREE_ATTEMPTS - 1):
        assert throttle.attempt(f"victim{i}", "10.0.4.1").allowed
    assert throttle.attempt("mine", "10.0.4.1").allowed
    throttle.succeeded("mine", "10.0.4.1")
    assert throttle.attempt("victim9", "10.0.4.1").allowed  # the 5th counted attempt
    assert not throttle.attempt("victim10", "10.0.4.1").allowed


def test_an_idle_key_is_forgotten() -> None:
    clock = Clock()
    throttle = Throttle(clock=clock)
    for _ in range(FREE_ATTEMPTS):
        throttle.attempt("qm", "10.0.5.1")
    clock.now += 2.0 + 15 * 60 + 1
    for _ in range(FREE_ATTEMPTS):
        assert throttle.attempt("qm", "10.0.5.1").allowed
    assert throttle.size() == 2


def test_the_throttles_memory_is_bounded() -> None:
    """12 000 user names from 12 000 clients: at most MAX_KEYS of each kind, about 1 MB."""
    throttle = Throttle(clock=Clock())
    tracemalloc.start()
    try:
        for i in range(12_000):
            throttle.attempt(
                f"name-{i:06d}-" + "x" * 80, f"10.{i // 65536}.{i // 256 % 256}.{i % 256}"
            )
        current, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert throttle.size() == 2 * MAX_KEYS
    assert current < 4_000_000  # bytes, for 8192 keys (was ~0.9 kB a name, never freed)


def test_the_check_slots_never_wait() -> None:
    slots = CheckSlots(2)
    assert slots.take() and slots.take()
    assert not slots.take()
    slots.give()
    assert slots.take()


def test_sessions_are_bounded_end_after_8_h_and_are_revoked() -> None:
    clock = Clock()
    store = SessionStore(max_sessions=3, clock=clock)
    first = store.open("a", "A", "hash-a")
    ids = [store.open("b", "B", "hash-b") for _ in range(3)]
    assert store.get(first) is None and len(store) == 3  # the oldest went
    assert store.get(ids[0]) is not None
    assert store.get(ids[0]).stamp == password_stamp("hash-b") != password_stamp("hash-c")
    store.revoke(ids[0])
    assert store.get(ids[0]) is None
    assert store.revoke_user("b") == 2 and len(store) == 0
    late = store.open("c", "C", "hash-c")
    clock.now += 8 * 3600 + 1
    assert store.get(late) is None


@pytest.mark.parametrize(
    ("peer", "forwarded", "proxies", "expected"),
    [
        ("127.0.0.1", ["10.0.0.7"], (), "127.0.0.1"),  # no proxy configured: ignored
        ("10.1.1.1", ["10.0.0.7"], ("127.0.0.1",), "10.1.1.1"),  # not from the proxy
        ("127.0.0.1", ["10.0.0.7"], ("127.0.0.1",), "10.0.0.7"),
        ("127.0.0.1", ["1.2.3.4, 10.0.0.7"], ("127.0.0.1",), "10.0.0.7"),  # client's own: no
        ("127.0.0.1", ["1.2.3.4", "10.0.0.7"], ("127.0.0.1",), "10.0.0.7"),  # two headers
        ("127.0.0.1", ["10.0.0.7, 127.0.0.1"], ("127.0.0.1",), "10.0.0.7"),  # proxy chain
        ("127.0.0.1", ["not-an-address"], ("127.0.0.1",), "127.0.0.1"),
        ("127.0.0.1", [], ("127.0.0.1",), "127.0.0.1"),
        ("0:0:0:0:0:0:0:1", ["10.0.0.7"], parse_proxies("::1"), "10.0.0.7"),  # IPv6 spellings
        ("::1", ["10.0.0.7"], (), "::1"),
    ],
)
def test_x_forwarded_for_is_read_only_from_a_trusted_proxy(peer, forwarded, proxies, expected):
    assert client_address(peer, forwarded, proxies) == expected


def test_proxy_addresses_are_checked() -> None:
    assert parse_proxies("127.0.0.1, ::1") == ("127.0.0.1", "::1")
    with pytest.raises(ValueError, match="--proxy: 'localhost' is not an IP address"):
        parse_proxies("127.0.0.1,localhost")
