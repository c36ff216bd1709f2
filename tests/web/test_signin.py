"""Sign-in that holds under attack (issue 33 point 5), over real HTTP against the real server
(`python -m app.web` in its own process, so its memory can be read from /proc): 40 concurrent
sign-ins, a cookie copied before sign-out, a password change, X-Forwarded-For from an address
that is not the configured proxy, a weak secret, Secure cookies.

Each server is started once per module; the tests use their own user names and (through the
trusted proxy's X-Forwarded-For) their own client addresses, so one test's back-off does not
reach another's."""

from __future__ import annotations

import io
import os
import re
import secrets
import socket
import ssl
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from http.client import HTTPConnection, HTTPSConnection
from pathlib import Path
from urllib.parse import urlencode

import pytest

from app.cli import main as cli_main
from app.web.__main__ import main as web_main
from app.web.guard import FREE_ATTEMPTS, PASSWORD_CHECKS_AT_ONCE, secret_problem
from app.web.users import add_user
from tests.web.conftest import Records

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[2]
MEMORY_LIMIT_MB = 600.0
COOKIE = "accelcal_session"


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@dataclass
class Server:
    """A `python -m app.web` process: its base URL, process and stderr log."""

    port: int
    process: subprocess.Popen[bytes]
    log: Path

    def memory_mb(self, which: str = "VmHWM") -> float:
        """The process's resident memory (MB): VmRSS now, VmHWM its peak since start."""
        status = Path(f"/proc/{self.process.pid}/status").read_text()
        match = re.search(rf"^{which}:\s+(\d+) kB", status, re.MULTILINE)
        assert match is not None, status
        return int(match.group(1)) / 1024


def _start(records: Records, folder: Path, *options: str) -> Iterator[Server]:
    port = _free_port()
    log = folder / f"server-{port}.log"
    env = {**os.environ, "ACCELCAL_WEB_SECRET": secrets.token_urlsafe(32)}
    argv = [sys.executable, "-m", "app.web", "--db", records.url, "--port", str(port), *options]
    with log.open("wb") as err:
        process = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=err, stderr=err)
    server = Server(port, process, log)
    deadline = time.monotonic() + 60
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=2).close()  # listening
            break
        except OSError:
            if process.poll() is not None or time.monotonic() > deadline:
                process.kill()
                pytest.fail(f"the web view did not start: {log.read_text()[-2000:]}")
            time.sleep(0.1)
    yield server
    process.terminate()
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


@pytest.fixture(scope="module")
def behind_proxy(records: Records, tmp_path_factory) -> Iterator[Server]:
    """The server behind a TLS proxy at 127.0.0.1 (so the tests can name their client)."""
    yield from _start(records, tmp_path_factory.mktemp("proxied"), "--proxy", "127.0.0.1")


@pytest.fixture(scope="module")
def direct(records: Records, tmp_path_factory) -> Iterator[Server]:
    """The server with no proxy configured (plain HTTP, its default)."""
    yield from _start(records, tmp_path_factory.mktemp("direct"))


@dataclass(frozen=True)
class Answer:
    """An HTTP response: status, headers (lower-case names), body text."""

    status_code: int
    headers: dict[str, str]
    text: str


@dataclass
class Browser:
    """One client of the web view: it keeps the session cookie itself (a Secure cookie too,
    over plain HTTP: the TLS proxy is simulated) and names its address to the proxy."""

    server: Server
    address: str | None = None
    cookie: str | None = None
    headers: dict[str, str] = field(default_factory=dict)

    def _send(self, method: str, path: str, data: dict[str, str] | None = None) -> Answer:
        headers = dict(self.headers)
        if self.address:
            headers["x-forwarded-for"] = self.address
        if self.cookie:
            headers["cookie"] = f"{COOKIE}={self.cookie}"
        body = None
        if data is not None:
            body = urlencode(data).encode()
            headers["content-type"] = "application/x-www-form-urlencoded"
        connection = HTTPConnection("127.0.0.1", self.server.port, timeout=60)
        try:
            connection.request(method, path, body=body, headers=headers)
            response = connection.getresponse()
            answer = Answer(
                response.status,
                {k.lower(): v for k, v in response.getheaders()},
                response.read().decode(),
            )
        finally:
            connection.close()
        match = re.search(rf"{COOKIE}=([^;]*)", answer.headers.get("set-cookie", ""))
        if match:
            self.cookie = match.group(1) or None
        return answer

    def get(self, path: str) -> Answer:
        return self._send("GET", path)

    def csrf(self) -> str:
        match = re.search(r'name="csrf" value="([^"]+)"', self.get("/login").text)
        assert match is not None
        return match.group(1)

    def sign_in(self, user: str, password: str, token: str | None = None) -> Answer:
        data = {"username": user, "password": password, "csrf": token or self.csrf()}
        return self._send("POST", "/login", data=data)

    def sign_out(self) -> Answer:
        page = self.get("/register").text
        match = re.search(r'name="csrf" value="([^"]+)"', page)
        assert match is not None, page[:500]
        return self._send("POST", "/logout", data={"csrf": match.group(1)})

    def staff_page(self) -> int:
        """The status of /register for this client: 200 signed in, 303 sent to sign in."""
        return self.get("/register").status_code


def _burst(
    browsers: list[Browser],
    users: list[str],
    passwords: list[str],
    tokens: list[str] | None = None,
) -> list[int]:
    """Every browser posts its sign-in at the same moment (form tokens fetched first)."""
    tokens = tokens or [b.csrf() for b in browsers]
    gate = threading.Barrier(len(browsers))
    statuses = [0] * len(browsers)

    def one(i: int) -> None:
        gate.wait()
        statuses[i] = browsers[i].sign_in(users[i], passwords[i], tokens[i]).status_code

    threads = [threading.Thread(target=one, args=(i,)) for i in range(len(browsers))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=120)
    return statuses


def _add(records: Records, user: str, password: str) -> None:
    add_user(records.engine, user, password, display_name=user.title(), actor="test")


@pytest.mark.slow  # a server process to start (~5 s on the loaded machine), then 40 sign-ins
def test_40_concurrent_sign_ins_of_one_user_check_at_most_the_free_attempts(
    behind_proxy: Server, records: Records
) -> None:
    """The attacker's burst: 39 wrong guesses and the right password at once, from one
    client; at most FREE_ATTEMPTS are checked, the rest are 429 without hashing."""
    password = "burst password 1"
    _add(records, "burst", password)
    browsers = [Browser(behind_proxy, "10.33.0.1") for _ in range(40)]
    guesses = [f"guess {i:02d} wrong" for i in range(39)] + [password]
    statuses = _burst(browsers, ["burst"] * 40, guesses)
    checked = [s for s in statuses if s != 429]
    assert set(statuses) <= {303, 401, 429}, statuses
    assert 1 <= len(checked) <= FREE_ATTEMPTS, statuses
    if statuses[-1] == 303:  # the right one may sign in only as one of the checked few
        assert browsers[-1].staff_page() == 200


@pytest.mark.slow  # waits out the 2 s back-off; 7 argon2 checks (64 MiB, ~0.5 s each)
def test_after_the_free_attempts_the_right_password_waits_its_back_off(
    behind_proxy: Server, records: Records
) -> None:
    """Past the limit nothing signs in, not even the right password among 40 concurrent; the
    owner then waits seconds, not 15 minutes (a back-off, not a lock-out)."""
    password = "limit password 1"
    _add(records, "limit", password)
    browsers = [Browser(behind_proxy, "10.33.1.1") for _ in range(40)]
    tokens = [b.csrf() for b in browsers]
    attacker = Browser(behind_proxy, "10.33.1.1")
    for i in range(FREE_ATTEMPTS):
        assert attacker.sign_in("limit", f"wrong guess {i}").status_code == 401
    guesses = [f"guess {i:02d} wrong" for i in range(39)] + [password]
    statuses = _burst(browsers, ["LIMIT"] * 40, guesses, tokens)  # any case: the same user
    assert statuses == [429] * 40
    assert browsers[-1].staff_page() == 303
    owner = Browser(behind_proxy, "10.33.1.2")  # another client: the user's own back-off
    refused = owner.sign_in("limit", password)
    assert refused.status_code == 429 and "wait" in refused.text
    wait = int(refused.headers["retry-after"])
    assert 1 <= wait <= 2
    time.sleep(wait + 0.2)
    assert owner.sign_in("limit", password).status_code == 303
    assert owner.staff_page() == 200


def test_40_concurrent_sign_ins_keep_the_server_under_600_mb(behind_proxy: Server, capsys) -> None:
    """40 clients, 40 user names at once (no throttle in the way): at most
    PASSWORD_CHECKS_AT_ONCE argon2 checks (64 MiB each) run together, the others are 429."""
    before = behind_proxy.memory_mb("VmRSS")
    browsers = [Browser(behind_proxy, f"10.34.0.{i + 1}") for i in range(40)]
    statuses = _burst(browsers, [f"nobody{i}" for i in range(40)], ["x" * 12] * 40)
    peak = behind_proxy.memory_mb("VmHWM")
    with capsys.disabled():
        print(f"\n40 concurrent sign-ins: server RSS {before:.0f} MB before, peak {peak:.0f} MB")
    assert set(statuses) <= {401, 429} and statuses.count(401) >= 1, statuses
    assert peak < MEMORY_LIMIT_MB
    assert peak - before < (PASSWORD_CHECKS_AT_ONCE + 1) * 64 + 50  # not 40 x 64 MiB


def test_sign_ins_posted_and_hung_up_on_free_no_extra_check(behind_proxy: Server) -> None:
    """40 clients post a sign-in and close the connection at once (the check must not be
    dropped while its argon2 still runs, freeing a slot for another): still at most
    PASSWORD_CHECKS_AT_ONCE checks together, the peak under 600 MB."""
    browsers = [Browser(behind_proxy, f"10.38.0.{i + 1}") for i in range(40)]
    tokens = [b.csrf() for b in browsers]

    def hang_up(i: int) -> None:
        body = urlencode({"username": f"hangup{i}", "password": "x" * 12, "csrf": tokens[i]})
        head = (
            f"POST /login HTTP/1.1\r\nHost: x\r\nCookie: {COOKIE}={browsers[i].cookie}\r\n"
            f"X-Forwarded-For: 10.38.0.{i + 1}\r\n"
            "Content-Type: application/x-www-form-urlencoded\r\n"
            f"Content-Length: {len(body)}\r\n\r\n"
        )
        with socket.create_connection(("127.0.0.1", behind_proxy.port)) as raw:
            raw.sendall((head + body).encode())

    threads = [threading.Thread(target=hang_up, args=(i,)) for i in range(40)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    probe = Browser(behind_proxy, "10.38.1.1")
    deadline = time.monotonic() + 30
    while probe.sign_in("hangup-probe", "x" * 12).status_code != 401:  # checks done
        assert time.monotonic() < deadline
        time.sleep(0.2)
    assert behind_proxy.memory_mb("VmHWM") < MEMORY_LIMIT_MB
    log = behind_proxy.log.read_text()
    assert "refused: checks busy" in log  # not all 40 were checked


def test_a_cookie_copied_before_sign_out_is_refused_after_it(
    behind_proxy: Server, records: Records
) -> None:
    _add(records, "copied", "copied password")
    user = Browser(behind_proxy, "10.33.2.1")
    assert user.sign_in("copied", "copied password").status_code == 303
    thief = Browser(behind_proxy, "10.33.2.2", cookie=user.cookie)  # the copy
    assert thief.staff_page() == 200
    assert user.sign_out().status_code == 303
    assert thief.staff_page() == 303
    assert "copied" not in thief.get("/login").text  # nor shown as signed in
    assert user.staff_page() == 303


@pytest.mark.slow  # 8 argon2 hashes and checks (64 MiB, ~0.5 s each)
def test_a_password_change_ends_the_users_other_sessions(
    behind_proxy: Server, records: Records, monkeypatch
) -> None:
    """`accelcal records user passwd NAME` (another process, as in the lab): every session of
    that user ends at its next request; the new password signs in, the old one no more."""
    _add(records, "changer", "old password 1")
    desk, laptop = Browser(behind_proxy, "10.33.3.1"), Browser(behind_proxy, "10.33.3.2")
    other = Browser(behind_proxy, "10.33.3.3")
    _add(records, "bystander", "bystander password")
    for browser, user, password in (
        (desk, "changer", "old password 1"),
        (laptop, "changer", "old password 1"),
        (other, "bystander", "bystander password"),
    ):
        assert browser.sign_in(user, password).status_code == 303
        assert browser.staff_page() == 200
    monkeypatch.setattr(sys, "stdin", io.StringIO("new password 2\n"))
    argv = ["records", "user", "passwd", "changer", "--password-stdin", "--db", records.url]
    assert cli_main(argv) == 0
    assert desk.staff_page() == 303 and laptop.staff_page() == 303
    assert other.staff_page() == 200  # another user's session stays
    fresh = Browser(behind_proxy, "10.33.3.4")
    assert fresh.sign_in("changer", "old password 1").status_code == 401
    assert fresh.sign_in("changer", "new password 2").status_code == 303
    assert fresh.staff_page() == 200


def test_a_password_change_of_an_unknown_user_exits_2(records: Records, monkeypatch, capsys):
    monkeypatch.setattr(sys, "stdin", io.StringIO("new password 2\n"))
    argv = ["records", "user", "passwd", "nosuch", "--password-stdin", "--db", records.url]
    assert cli_main(argv) == 2
    assert "username: no staff user 'nosuch'" in capsys.readouterr().err


@pytest.mark.slow  # its own server process to start, 6 argon2 checks
def test_x_forwarded_for_from_an_unconfigured_address_is_ignored(direct: Server) -> None:
    """Without --proxy, a client naming a new address in each X-Forwarded-For is still one
    client: after FREE_ATTEMPTS (each a different user name) it waits."""
    for i in range(FREE_ATTEMPTS):
        spoofer = Browser(direct, f"10.35.0.{i + 1}")
        assert spoofer.sign_in(f"spoof{i}", "x" * 12).status_code == 401
    spoofer = Browser(direct, "10.35.0.99")
    assert spoofer.sign_in("spoof-last", "x" * 12).status_code == 429


@pytest.mark.slow  # 12 argon2 checks (64 MiB, ~0.5 s each)
def test_x_forwarded_for_from_the_configured_proxy_names_the_client(behind_proxy: Server):
    """The same sequence through the configured proxy: each address is its own client (so
    the test above could fail); a client's own left-most entry is not believed."""
    for i in range(FREE_ATTEMPTS + 1):
        client = Browser(behind_proxy, f"10.36.0.{i + 1}")
        assert client.sign_in(f"proxied{i}", "x" * 12).status_code == 401
    for i in range(FREE_ATTEMPTS):  # one real client, a new forged address each time
        forger = Browser(behind_proxy, f"10.37.9.{i + 1}, 10.37.0.1")
        assert forger.sign_in(f"forger{i}", "x" * 12).status_code == 401
    forger = Browser(behind_proxy, "10.37.9.99, 10.37.0.1")
    assert forger.sign_in("forger-last", "x" * 12).status_code == 429


def test_cookies_are_secure_behind_the_proxy_and_a_warning_says_when_not(
    behind_proxy: Server, direct: Server
) -> None:
    secure = Browser(behind_proxy).get("/login").headers["set-cookie"].lower()
    plain = Browser(direct).get("/login").headers["set-cookie"].lower()
    assert "; secure" in secure and "; secure" not in plain
    assert "the session cookie is not Secure" in direct.log.read_text()
    assert "the session cookie is not Secure" not in behind_proxy.log.read_text()


def _self_signed(folder: Path) -> tuple[Path, Path]:
    """A throwaway certificate and key for 127.0.0.1 (PEM files)."""
    import ipaddress
    from datetime import UTC, datetime, timedelta

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "127.0.0.1")])
    now = datetime.now(UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - timedelta(days=1))
        .not_valid_after(now + timedelta(days=2))
        .add_extension(
            x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
            critical=False,
        )
        .sign(key, hashes.SHA256())
    )
    cert_file, key_file = folder / "tls.pem", folder / "tls.key"
    cert_file.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    key_file.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return cert_file, key_file


@pytest.mark.slow  # its own server process to start (~5 s on the loaded machine)
def test_served_over_https_the_cookie_is_secure_without_being_asked(
    records: Records, tmp_path: Path
) -> None:
    cert, key = _self_signed(tmp_path)
    for server in _start(records, tmp_path, "--tls-cert", str(cert), "--tls-key", str(key)):
        context = ssl.create_default_context(cafile=str(cert))
        connection = HTTPSConnection("127.0.0.1", server.port, timeout=60, context=context)
        try:
            connection.request("GET", "/login")
            response = connection.getresponse()
            assert response.status == 200
            cookie = (response.getheader("set-cookie") or "").lower()
        finally:
            connection.close()
        assert cookie.startswith(f"{COOKIE}=") and "; secure" in cookie
        assert "the session cookie is not Secure" not in server.log.read_text()


@pytest.mark.slow  # a Python process to start (~3 s on the loaded machine)
def test_a_weak_secret_is_refused_at_start_with_exit_2(records: Records) -> None:
    """The issue's case, 40 x 'a' (was accepted), in a real server process."""
    env = {**os.environ, "ACCELCAL_WEB_SECRET": "a" * 40}
    argv = [sys.executable, "-m", "app.web", "--db", records.url, "--port", str(_free_port())]
    done = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("error: ACCELCAL_WEB_SECRET: repeats 'aaaaaaaa'")
    assert "too weak" in done.stderr and "secrets.token_urlsafe(32)" in done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr


DE_BRUIJN_48 = "aaaaaaaabaaaaaabbaaaaababaaaaabbbaaaabaabaaaabab"  # no 8 characters twice


@pytest.mark.parametrize(
    ("secret", "why"),
    [
        ("abcd" * 10, "repeats 'abcdabcd'"),
        ("0123456789abcdef" * 2, "repeats '01234567'"),  # 32 characters, 128 "bits"
        ("abcdefghijklmnopqrstuvwxyzABCDE", "shorter than 32 characters"),
        (DE_BRUIJN_48, "about 39 bits of entropy, fewer than 100"),
    ],
)
def test_other_weak_secrets_are_refused_naming_the_setting(
    records: Records, monkeypatch, capsys, secret: str, why: str
) -> None:
    monkeypatch.setenv("ACCELCAL_WEB_SECRET", secret)
    assert web_main(["--db", records.url, "--port", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: ACCELCAL_WEB_SECRET: {why}"), err
    assert err.count("\n") == 1


def test_strong_secrets_pass() -> None:
    """No false refusals of what the hint makes, nor of 64 hex digits or a long phrase."""
    for _ in range(500):
        assert secret_problem(secrets.token_urlsafe(32)) is None
        assert secret_problem(secrets.token_hex(32)) is None
    assert secret_problem("correct horse battery staple in the calibration lab") is None


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--proxy", "localhost"], "--proxy: 'localhost' is not an IP address"),
        (["--tls-cert", "/nonexistent/c.pem"], "--tls-cert and --tls-key: give both or neither"),
        (["--tls-cert", "/no/c.pem", "--tls-key", "/no/k.pem"], "--tls-cert: no such file"),
    ],
)
def test_bad_proxy_and_tls_options_exit_2(capsys, argv: list[str], message: str) -> None:
    assert web_main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
