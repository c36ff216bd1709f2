"""The web view's pages through Starlette's TestClient over real records (conftest): login,
register search, a certificate's page and documents, due lists, a sensor's history and the
public verification page."""

from __future__ import annotations

import base64
import hashlib
import hmac
import re
from pathlib import Path

import pytest
from sqlalchemy import text
from starlette.testclient import TestClient

from app.certificate.readback import items_from_dcc, parse_inert
from app.records.run_folder import MANIFEST_NAME, sha256_of
from app.web.users import add_user
from tests.web.conftest import PASSWORD, SERIAL, USER, Records

pytestmark = pytest.mark.integration

STAFF_PAGES = ("/register", "/due", "/sensors/SN-WEB-1")
RUN_OF_CERTIFICATE = (0, 1, 0)  # conftest: the third certificate is of run 0 again


def _csrf(client: TestClient) -> str:
    page = client.get("/login")
    match = re.search(r'name="csrf" value="([^"]+)"', page.text)
    assert match is not None
    return match.group(1)


def _login(client: TestClient, user: str = USER, password: str = PASSWORD, **extra: str):
    data = {"username": user, "password": password, "csrf": _csrf(client), **extra}
    return client.post("/login", data=data, follow_redirects=False)


@pytest.fixture
def client(web_app) -> TestClient:
    return TestClient(web_app)


@pytest.fixture
def staff(client: TestClient) -> TestClient:
    assert _login(client).status_code == 303
    return client


def _code(number: str, manifest: str) -> str:
    """The verification code by hand: base32 of the first 10 bytes of HMAC-SHA256."""
    mac = hmac.new(bytes.fromhex(manifest), number.encode(), hashlib.sha256).digest()[:10]
    return base64.b32encode(mac).decode().lower()  # 80 bits: 16 characters, no padding


def _manifest(records: Records, index: int) -> str:
    return sha256_of(records.runs[index] / MANIFEST_NAME)


@pytest.mark.parametrize("path", [*STAFF_PAGES, "/certificates/ACC-2026-0001"])
def test_staff_pages_send_a_stranger_to_the_login(client: TestClient, path: str) -> None:
    response = client.get(path, follow_redirects=False)
    assert response.status_code == 303
    assert response.headers["location"].startswith("/login?next=")
    assert "ACME" not in response.text


def test_a_certificates_documents_need_a_login_too(client: TestClient, records: Records) -> None:
    for kind in ("pdf", "xml"):
        url = f"/certificates/{records.numbers[1]}/certificate.{kind}"
        response = client.get(url, follow_redirects=False)
        assert response.status_code == 303 and not response.content.startswith(b"%PDF")


def test_login_takes_the_user_back_where_they_were_going(client: TestClient) -> None:
    response = _login(client, next="/due?days=400")
    assert response.status_code == 303 and response.headers["location"] == "/due?days=400"
    assert client.get("/register").status_code == 200


@pytest.mark.parametrize("target", ["//evil.example/x", "https://evil.example/", "/\\evil"])
def test_login_never_redirects_off_the_site(client: TestClient, target: str) -> None:
    response = _login(client, next=target)
    assert response.headers["location"] == "/register"


def test_a_wrong_password_or_unknown_user_is_refused_alike(client: TestClient) -> None:
    wrong = _login(client, password="not the password")
    unknown = _login(client, user="nobody", password=PASSWORD)
    assert wrong.status_code == unknown.status_code == 401
    assert "Unknown user name or wrong password." in wrong.text
    assert "Unknown user name or wrong password." in unknown.text
    assert client.get("/register", follow_redirects=False).status_code == 303


def test_a_login_without_its_form_token_is_refused(client: TestClient) -> None:
    client.get("/login")
    data = {"username": USER, "password": PASSWORD, "csrf": "forged"}
    response = client.post("/login", data=data, follow_redirects=False)
    assert response.status_code == 400
    assert client.get("/register", follow_redirects=False).status_code == 303


def test_five_failures_lock_a_user_name_out_even_with_the_right_password(web_app) -> None:
    client = TestClient(web_app, client=("10.0.0.9", 5000))
    for _ in range(5):
        assert _login(client, user="QM", password="guess").status_code == 401
    assert _login(client, password=PASSWORD).status_code == 429  # same name, any case
    other = TestClient(web_app, client=("10.0.0.10", 5000))
    assert _login(other, user="someone", password="x" * 12).status_code == 401  # not locked


def test_sign_out_ends_the_session(staff: TestClient) -> None:
    page = staff.get("/register")
    token = re.search(r'name="csrf" value="([^"]+)"', page.text)
    assert token is not None
    staff.post("/logout", data={"csrf": token.group(1)}, follow_redirects=False)
    assert staff.get("/register", follow_redirects=False).status_code == 303


def test_a_user_made_inactive_is_out_at_the_next_request(web_app, records: Records) -> None:
    add_user(records.engine, "temp", "a long enough password", display_name="Temp", actor="t")
    client = TestClient(web_app)
    assert _login(client, user="temp", password="a long enough password").status_code == 303
    assert client.get("/register").status_code == 200
    with records.engine.begin() as conn:
        conn.execute(text("UPDATE users SET active = false WHERE username = 'temp'"))
    assert client.get("/register", follow_redirects=False).status_code == 303


def _numbers_listed(page: str) -> list[str]:
    return re.findall(r'<a href="/certificates/([^"]+)">', page)


def test_the_register_lists_every_certificate_newest_first(
    staff: TestClient, records: Records
) -> None:
    page = staff.get("/register").text
    assert _numbers_listed(page) == list(reversed(records.numbers))
    assert "3 certificates." in page


@pytest.mark.parametrize(
    ("search", "expected"),
    [
        ("ACC-2026-0002", [1]),
        ("sn-web-1", [2, 1, 0]),  # case-insensitive, the serial
        ("acme", [2, 1, 0]),  # the customer
        ("Other GmbH", []),  # a customer with no certificate
        ("%", []),  # a LIKE wildcard is a plain character here
        ("_", []),
    ],
)
def test_register_search(staff: TestClient, records: Records, search: str, expected) -> None:
    page = staff.get("/register", params={"q": search}).text
    assert _numbers_listed(page) == [records.numbers[i] for i in expected]


def test_register_search_by_run_id(staff: TestClient, records: Records) -> None:
    page = staff.get("/register", params={"q": records.runs[0].name}).text
    assert _numbers_listed(page) == [records.numbers[2], records.numbers[0]]  # both of run 0
    page = staff.get("/register", params={"q": records.runs[1].name}).text
    assert _numbers_listed(page) == [records.numbers[1]]


def test_a_certificates_page_states_status_amendment_and_verification(
    staff: TestClient, records: Records
) -> None:
    old, new, withdrawn = records.numbers
    page = staff.get(f"/certificates/{old}").text
    assert 'class="amended">amended</span>' in page
    assert f'amended by <a href="/certificates/{new}">' in page
    assert "typing error in the mounting" in page
    assert "A. Preparer" in page and "J. Smith" in page
    # accelcal verify's checks with the run folder, and the PDF's own number
    for name in ("embedded DCC valid", "run manifest verified", "DCC numbers equal the run"):
        assert re.search(rf'<td class="ok">pass</td><td>{name}', page), name
    assert f'<td class="ok">pass</td><td>the PDF is certificate {old}' in page
    assert '<td class="bad">FAIL</td><td>signature</td><td>the PDF is not signed' in page
    code = _code(old, _manifest(records, 0))
    assert f"https://lab.example/verify/{old}?code={code}" in page
    signed = staff.get(f"/certificates/{new}").text
    assert 'class="valid">valid</span>' in signed
    assert '<td class="ok">pass</td><td>signature intact, covering the whole file' in signed
    assert 'id="verified" class="ok">Every check passed.' in signed
    assert 'class="withdrawn">withdrawn' in staff.get(f"/certificates/{withdrawn}").text


def test_the_pdf_and_dcc_downloads_are_the_issued_ones(staff: TestClient, records: Records) -> None:
    number = records.numbers[1]
    with records.engine.connect() as conn:
        file, sha256, dcc_sha256 = conn.execute(
            text("SELECT file, sha256, dcc_sha256 FROM certificates WHERE number = :n"),
            {"n": number},
        ).one()
    pdf = staff.get(f"/certificates/{number}/certificate.pdf")
    assert pdf.headers["content-type"] == "application/pdf"
    assert hashlib.sha256(pdf.content).hexdigest() == sha256
    assert pdf.content == Path(file).read_bytes() and Path(file).name == "certificate-1.pdf"
    dcc = staff.get(f"/certificates/{number}/certificate.xml")
    assert dcc.headers["content-type"].startswith("application/xml")
    assert hashlib.sha256(dcc.content).hexdigest() == dcc_sha256
    assert items_from_dcc(parse_inert(dcc.content)).number == number
    assert staff.get(f"/certificates/{number}/certificate.exe").status_code == 404


def test_an_unknown_certificate_is_not_found(staff: TestClient) -> None:
    assert staff.get("/certificates/ACC-1999-0001").status_code == 404
    assert staff.get("/certificates/ACC-1999-0001/certificate.pdf").status_code == 404


def test_due_lists_the_sensor_never_calibrated_and_the_other_by_its_date(
    staff: TestClient,
) -> None:
    soon = staff.get("/due", params={"days": 30}).text
    assert "SN-WEB-2" in soon and "never calibrated here" in soon
    assert SERIAL not in soon  # calibrated today, due in 12 months
    later = staff.get("/due", params={"days": 400}).text
    assert SERIAL in later


@pytest.mark.parametrize("days", ["abc", "-1", "99999"])
def test_due_refuses_a_bad_number_of_days(staff: TestClient, days: str) -> None:
    response = staff.get("/due", params={"days": days})
    assert response.status_code == 400 and "days: must be a whole number" in response.text


def test_a_sensors_page_charts_each_calibration(staff: TestClient, records: Records) -> None:
    page = staff.get(f"/sensors/{SERIAL}").text
    assert page.count('class="point"') == 2  # two complete runs
    assert "<svg" in page and "sensitivity in mV/(m/s²)" in page
    for number in records.numbers:
        assert f'href="/certificates/{number}"' in page
    assert staff.get("/sensors/SN-NONE").status_code == 404


@pytest.mark.parametrize(("index", "status"), [(0, "amended"), (1, "valid"), (2, "withdrawn")])
def test_the_public_page_shows_the_status_for_the_right_code(
    web_app, records: Records, index: int, status: str
) -> None:
    number = records.numbers[index]
    code = _code(number, _manifest(records, RUN_OF_CERTIFICATE[index]))
    response = TestClient(web_app).get(f"/verify/{number}", params={"code": code})
    assert response.status_code == 200
    assert f'id="status">{status}</p>' in response.text
    for private in (SERIAL, "ACME", "Preparer", "J. Smith", "Register", "mV"):
        assert private not in response.text  # only the status
    assert "set-cookie" not in response.headers


def test_the_public_page_says_the_same_for_a_wrong_code_and_an_unknown_number(
    web_app, records: Records
) -> None:
    client = TestClient(web_app)
    number = records.numbers[1]
    other_runs_code = _code(number, _manifest(records, 0))
    wrong = client.get(f"/verify/{number}", params={"code": other_runs_code})
    missing = client.get(f"/verify/{number}")
    unknown = client.get("/verify/ACC-2026-0099", params={"code": other_runs_code})
    assert wrong.status_code == missing.status_code == unknown.status_code == 404
    assert wrong.text == missing.text == unknown.text.replace("ACC-2026-0099", number)


def test_every_response_forbids_scripts_framing_and_referrers(web_app) -> None:
    response = TestClient(web_app).get("/login")
    assert "default-src 'none'" in response.headers["content-security-policy"]
    assert response.headers["referrer-policy"] == "no-referrer"
    assert response.headers["x-frame-options"] == "DENY"
    assert "<script" not in response.text


def test_with_the_labs_certificate_the_signer_is_checked_too(store, records: Records) -> None:
    from app.web.server import WebConfig, create_app

    config = WebConfig(secret_key="t" * 40, trust=records.lab_certificate)
    client = TestClient(create_app(store, config))
    assert _login(client).status_code == 303
    signed = client.get(f"/certificates/{records.numbers[1]}").text
    assert '<td class="ok">pass</td><td>signer trusted by the given CA' in signed
    unsigned = client.get(f"/certificates/{records.numbers[0]}").text
    assert "signer trusted" not in unsigned  # no signature to trust
    assert 'id="verified" class="bad">' in unsigned
    # without verify_url the QR leads to this server's own /verify page
    assert f"http://testserver/verify/{records.numbers[0]}?code=" in unsigned


def test_what_a_user_typed_is_shown_escaped(staff: TestClient) -> None:
    page = staff.get("/register", params={"q": '<script>alert(1)</script>"'}).text
    assert "<script>alert(1)" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page


def test_the_session_cookie_is_http_only_and_same_site(client: TestClient) -> None:
    response = client.get("/login")
    cookie = response.headers["set-cookie"]
    assert cookie.startswith("accelcal_session=")
    assert "httponly" in cookie.lower() and "samesite=lax" in cookie.lower()
    assert "max-age=28800" in cookie.lower()  # 8 h


# --- issue 35 point 5: what the pages say to a lab that does not sign, and to a customer ------


def test_an_unsigned_labs_page_says_not_signed_by_its_policy(store, records: Records) -> None:
    """Without a lab CA (a lab that does not sign) an unsigned certificate is "not signed, by
    the laboratory's policy", every other check still shown; with a CA it stays a failure."""
    from app.web.server import WebConfig, create_app

    def signed_in(config: WebConfig) -> TestClient:
        client = TestClient(create_app(store, config))
        assert _login(client).status_code == 303
        return client

    unsigned_lab = signed_in(
        WebConfig(secret_key="k" * 40, verify_url="https://lab.example/verify")
    )
    old = records.numbers[0]
    page = unsigned_lab.get(f"/certificates/{old}").text
    assert "Every check passed; not signed, by the laboratory's policy." in page
    assert '<td class="note">not signed</td><td>signature</td>' in page
    assert "FAIL" not in page and "Some checks failed" not in page
    for name in ("embedded DCC valid", "run manifest verified", "DCC numbers equal the run"):
        assert re.search(rf'<td class="ok">pass</td><td>{name}', page), name
    signing_lab = signed_in(WebConfig(secret_key="k" * 40, verify_url="https://lab.example/verify",
                                      trust=records.lab_certificate))  # fmt: skip
    page = signing_lab.get(f"/certificates/{old}").text
    assert '<td class="bad">FAIL</td><td>signature</td><td>the PDF is not signed' in page
    assert "Some checks failed." in page


def test_the_page_speaks_of_a_qr_code_only_where_one_was_printed(
    staff: TestClient, records: Records
) -> None:
    """The test runs' stand names no verify_url, so their certificates carry no QR code: the
    page says so and gives the public address (with its code for staff to pass on)."""
    new = records.numbers[1]
    page = staff.get(f"/certificates/{new}").text
    assert "The QR code on the certificate leads to" not in page
    assert '<p id="no-qr">No QR code was printed on this certificate' in page
    assert f"https://lab.example/verify/{new}?code=" in page


def test_the_page_names_the_address_page_1_printed(records: Records, tmp_path: Path) -> None:
    """Where a QR code was printed, the page shows the address the PDF was drawn with (the
    run's verify_url), not the server's own."""
    import shutil

    from app.web.documents import DocumentError, printed_verification_address

    run = records.runs[1]
    assert printed_verification_address(records.numbers[1], str(run)) is None
    copy = tmp_path / run.name
    shutil.copytree(run, copy)
    (copy / "results.json").chmod(0o644)
    (copy / "results.json").write_text("{}")  # the run can no longer be read
    with pytest.raises(DocumentError):
        printed_verification_address(records.numbers[1], str(copy))


@pytest.mark.parametrize(
    ("serial", "shown"),
    [("SN-WEB-1", "•••••B-1"), ("A1", "•1"), ("X", "X"), ("1234567890123456", "••••••••••••3456")],
)
def test_a_serial_is_masked_to_its_last_third_at_most_four(serial: str, shown: str) -> None:
    from app.web.store import masked_serial

    assert masked_serial(serial) == shown


def test_the_public_page_names_the_item_by_model_and_masked_serial(
    web_app, records: Records
) -> None:
    number = records.numbers[1]
    code = _code(number, _manifest(records, RUN_OF_CERTIFICATE[1]))
    page = TestClient(web_app).get(f"/verify/{number}", params={"code": code}).text
    assert '<p id="item">Item: Sim P-100, serial •••••B-1</p>' in page
    assert SERIAL not in page
