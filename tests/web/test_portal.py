"""The customer portal (issue 35 point 5) through Starlette's TestClient, as an attacker would
try it: a customer signed in sees its own certificates, documents and due dates, and gets the
one same 404 for anything of another customer's (by number, by id, by path tricks), never
reaches a staff page, and cannot make its session a staff one (tampered or re-keyed cookie)."""

from __future__ import annotations

import base64
import csv
import hashlib
import io
import json
import re
from datetime import date

import itsdangerous
import pytest
from starlette.testclient import TestClient

from app.records.run_folder import sha256_of
from app.web.accounts import remove_account, set_account_active, set_account_password
from tests.web.conftest import (
    ACME_ACCOUNT,
    ACME_PASSWORD,
    NEVER_CALIBRATED,
    OTHER_ACCOUNT,
    OTHER_PASSWORD,
    PASSWORD,
    PORTAL_SECRET,
    SERIAL,
    USER,
    PortalRecords,
)

pytestmark = pytest.mark.integration

COOKIE = "accelcal_session"
OTHER_SERIAL = "SN-WEB-2"


def _csrf(client: TestClient, path: str = "/portal/login") -> str:
    match = re.search(r'name="csrf" value="([^"]+)"', client.get(path).text)
    assert match is not None
    return match.group(1)


def _portal_login(client: TestClient, user: str, password: str, **extra: str):
    data = {"username": user, "password": password, "csrf": _csrf(client), **extra}
    return client.post("/portal/login", data=data, follow_redirects=False)


def _staff_login(client: TestClient, user: str = USER, password: str = PASSWORD):
    data = {"username": user, "password": password, "csrf": _csrf(client, "/login")}
    return client.post("/login", data=data, follow_redirects=False)


@pytest.fixture
def acme(portal_app) -> TestClient:
    client = TestClient(portal_app)
    assert _portal_login(client, ACME_ACCOUNT, ACME_PASSWORD).status_code == 303
    return client


def test_a_customer_sees_its_own_certificates_and_due_dates_only(
    acme: TestClient, portal_records: PortalRecords
) -> None:
    page = acme.get("/portal")
    assert page.status_code == 200
    assert "Certificates of ACME Ltd" in page.text
    assert portal_records.acme in page.text and SERIAL in page.text
    assert NEVER_CALIBRATED in page.text and "never calibrated here" in page.text
    assert portal_records.other not in page.text and OTHER_SERIAL not in page.text
    assert "Other GmbH" not in page.text
    # the due date of SN-WEB-1: its run's day plus the sensor's 12 months, in the page
    due = re.search(rf'{SERIAL}</a></td>.*?<td class="[^"]*">(\d{{4}}-\d\d-\d\d)', page.text, re.S)
    assert due is not None and date.fromisoformat(due.group(1)).year >= date.today().year
    sensor = acme.get(f"/portal/sensors/{SERIAL}")
    assert sensor.status_code == 200 and portal_records.acme in sensor.text
    assert f'id="due-date" class="">{due.group(1)}' in sensor.text


def test_a_customer_downloads_its_own_pdf_and_dcc(
    acme: TestClient, portal_records: PortalRecords
) -> None:
    number = portal_records.acme
    pdf = acme.get(f"/portal/certificates/{number}/certificate.pdf")
    assert pdf.status_code == 200 and pdf.headers["content-type"] == "application/pdf"
    assert hashlib.sha256(pdf.content).hexdigest() == sha256_of(portal_records.acme_pdf)
    assert f'filename="{number}.pdf"' in pdf.headers["content-disposition"]
    dcc = acme.get(f"/portal/certificates/{number}/certificate.xml")
    assert dcc.status_code == 200 and dcc.headers["content-type"].startswith("application/xml")
    assert number.encode() in dcc.content and b"<dcc:digitalCalibrationCertificate" in dcc.content


def _not_found(response) -> bool:
    return response.status_code == 404 and "Not found in your records." in response.text


def test_another_customers_certificate_sensor_and_files_are_404_as_if_absent(
    acme: TestClient, portal_records: PortalRecords
) -> None:
    other = portal_records.other
    absent = acme.get("/portal/certificates/NO-SUCH-1/certificate.pdf")
    assert _not_found(absent)
    for path in (
        f"/portal/certificates/{other}/certificate.pdf",
        f"/portal/certificates/{other}/certificate.xml",
        f"/portal/sensors/{OTHER_SERIAL}",
        "/portal/sensors/NO-SUCH-SENSOR",
    ):
        response = acme.get(path)
        assert _not_found(response), path
        assert other not in response.text and OTHER_SERIAL not in response.text.replace(path, "")
        # the same page as for what does not exist: nothing tells "exists, not yours"
        assert len(response.content) - len(path) == pytest.approx(
            len(absent.content) - len("/portal/certificates/NO-SUCH-1/certificate.pdf"), abs=40
        )


@pytest.mark.parametrize(
    "path",
    [
        "/portal/certificates/1/certificate.pdf",  # guessing row ids
        "/portal/certificates/2/certificate.pdf",
        "/portal/certificates/2/certificate.xml",
        "/portal/sensors/1",
        "/portal/sensors/2",
        "/portal/certificates/{own}/certificate.run",  # a kind that is not served
        "/portal/certificates/{own}/../{other}/certificate.pdf",
        "/portal/certificates/{own}%2F..%2F{other}/certificate.pdf",
        "/portal/certificates/{own}/certificate.pdf/../../{other}/certificate.pdf",
        "/portal/certificates/{other}%00/certificate.pdf",
        "/portal/certificates/%2e%2e/%2e%2e/certificates/{other}/certificate.pdf",
        "/portal/certificates/{own_lower}/certificate.pdf",  # the number, other case
        "/portal/certificates/%25/certificate.pdf",  # a LIKE wildcard
        "/portal/sensors/%25",
        "/portal/sensors/SN-WEB-_",
        "/portal/due.txt",
        "/portal/nothing-here",
    ],
)
def test_guessed_ids_and_path_tricks_find_nothing(
    acme: TestClient, portal_records: PortalRecords, path: str
) -> None:
    own, other = portal_records.acme, portal_records.other
    url = path.format(own=own, other=other, own_lower=own.lower())
    response = acme.get(url)
    assert response.status_code == 404, url
    assert (
        not response.content.startswith(b"%PDF") and b"digitalCalibration" not in response.content
    )


@pytest.mark.parametrize("path", ["/register", "/due", "/sensors/SN-WEB-1", "/certificates/{own}",
                                  "/certificates/{own}/certificate.pdf"])  # fmt: skip
def test_a_customer_cookie_never_opens_a_staff_page(
    acme: TestClient, portal_records: PortalRecords, path: str
) -> None:
    response = acme.get(path.format(own=portal_records.acme), follow_redirects=False)
    assert response.status_code == 303
    assert response.headers["location"].startswith("/login?next=")
    assert acme.get("/portal").status_code == 200  # and the customer stays signed in


def _session(client: TestClient) -> dict:
    """The signed session cookie's content (Starlette: base64 JSON, then an itsdangerous
    timestamp signature)."""
    value = client.cookies[COOKIE]
    payload = itsdangerous.TimestampSigner(PORTAL_SECRET).unsign(value)
    return dict(json.loads(base64.b64decode(payload)))


def _signed(content: dict) -> str:
    data = base64.b64encode(json.dumps(content).encode())
    return itsdangerous.TimestampSigner(PORTAL_SECRET).sign(data).decode()


def test_a_portal_session_cannot_be_turned_into_a_staff_session(
    portal_app, acme: TestClient
) -> None:
    content = _session(acme)
    assert "portal" in content and "sid" not in content
    # even with the server's key, the portal session id under the staff's key opens nothing
    forged = TestClient(portal_app)
    forged.cookies.set(COOKIE, _signed({**content, "sid": content["portal"]}))
    assert forged.get("/register", follow_redirects=False).status_code == 303
    # nor does a staff session open the portal
    staff = TestClient(portal_app)
    assert _staff_login(staff).status_code == 303
    assert staff.get("/register").status_code == 200
    staff_content = _session(staff)
    page = staff.get("/portal", follow_redirects=False)
    assert page.status_code == 303 and page.headers["location"].startswith("/portal/login")
    both = TestClient(portal_app)
    both.cookies.set(COOKIE, _signed({"portal": staff_content["sid"]}))
    assert both.get("/portal", follow_redirects=False).status_code == 303


def test_a_tampered_cookie_is_no_session(portal_app, acme: TestClient) -> None:
    value = acme.cookies[COOKIE]
    flipped = value[:-3] + ("A" if value[-3] != "A" else "B") + value[-2:]
    for cookie in (flipped, value.split(".")[0] + ".x.y", _signed({"portal": "guessed"})):
        client = TestClient(portal_app)
        client.cookies.set(COOKIE, cookie)
        response = client.get("/portal", follow_redirects=False)
        assert response.status_code == 303, cookie
        assert response.headers["location"].startswith("/portal/login")


def test_passwords_do_not_cross_between_staff_and_customers(portal_app) -> None:
    client = TestClient(portal_app)
    assert _portal_login(client, USER, PASSWORD).status_code == 401  # staff at the portal
    assert _staff_login(client, ACME_ACCOUNT, ACME_PASSWORD).status_code == 401
    assert _portal_login(client, ACME_ACCOUNT, OTHER_PASSWORD).status_code == 401


@pytest.mark.parametrize("target", ["/register", "//evil.example/", "https://evil.example/",
                                    "/portal\\..\\register", "/portalx"])  # fmt: skip
def test_the_portal_sign_in_goes_back_only_into_the_portal(portal_app, target: str) -> None:
    client = TestClient(portal_app)
    response = _portal_login(client, ACME_ACCOUNT, ACME_PASSWORD, next=target)
    assert response.status_code == 303 and response.headers["location"] == "/portal"
    kept = _portal_login(TestClient(portal_app), ACME_ACCOUNT, ACME_PASSWORD,
                         next=f"/portal/sensors/{SERIAL}")  # fmt: skip
    assert kept.headers["location"] == f"/portal/sensors/{SERIAL}"


def test_a_stranger_is_sent_to_sign_in_alike_for_what_exists_and_what_does_not(
    portal_app, portal_records: PortalRecords
) -> None:
    client = TestClient(portal_app)
    for path in (f"/portal/sensors/{OTHER_SERIAL}", "/portal/sensors/NOPE", "/portal/due.ics"):
        response = client.get(path, follow_redirects=False)
        assert response.status_code == 303 and response.headers["location"].startswith(
            "/portal/login?next="
        )


def test_the_due_dates_export_as_csv_and_icalendar(
    acme: TestClient, portal_records: PortalRecords
) -> None:
    from icalendar import Calendar

    page = acme.get("/portal").text
    shown = re.search(rf'{SERIAL}</a></td>.*?<td class="[^"]*">(\d{{4}}-\d\d-\d\d)', page, re.S)
    assert shown is not None
    csv_file = acme.get("/portal/due.csv")
    assert csv_file.status_code == 200 and csv_file.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(csv_file.text)))
    assert {r["serial"] for r in rows} == {SERIAL, NEVER_CALIBRATED}
    by_serial = {r["serial"]: r for r in rows}
    assert by_serial[SERIAL]["due"] == shown.group(1)
    assert by_serial[SERIAL]["interval_months"] == "12"
    assert by_serial[NEVER_CALIBRATED]["due"] == ""
    assert by_serial[NEVER_CALIBRATED]["state"] == "never calibrated here"

    ics = acme.get("/portal/due.ics")
    assert ics.status_code == 200 and ics.headers["content-type"].startswith("text/calendar")
    assert b"\r\n" in ics.content and OTHER_SERIAL.encode() not in ics.content
    calendar = Calendar.from_ical(ics.content)
    events = list(calendar.walk("VEVENT"))
    assert len(events) == 1  # the never-calibrated sensor has no date, so no event
    (event,) = events
    assert event.decoded("dtstart") == date.fromisoformat(shown.group(1))
    assert (event.decoded("dtend") - event.decoded("dtstart")).days == 1
    assert SERIAL in str(event["summary"]) and "P-100" in str(event["summary"])
    assert str(event["uid"]) == str(
        next(iter(Calendar.from_ical(acme.get("/portal/due.ics").content).walk("VEVENT")))["uid"]
    )  # stable: importing the file again updates the event


def test_the_other_customers_export_is_its_own(portal_app, portal_records: PortalRecords) -> None:
    other = TestClient(portal_app)
    assert _portal_login(other, OTHER_ACCOUNT, OTHER_PASSWORD).status_code == 303
    rows = list(csv.DictReader(io.StringIO(other.get("/portal/due.csv").text)))
    assert [r["serial"] for r in rows] == [OTHER_SERIAL]
    ics = other.get("/portal/due.ics").content
    assert SERIAL.encode() not in ics and NEVER_CALIBRATED.encode() not in ics
    assert _not_found(other.get(f"/portal/certificates/{portal_records.acme}/certificate.pdf"))
    assert (
        other.get(f"/portal/certificates/{portal_records.other}/certificate.pdf").status_code == 200
    )


def test_disabling_removing_or_a_new_password_ends_the_customers_sessions(
    portal_app, portal_records: PortalRecords
) -> None:
    from app.web.accounts import add_account

    engine = portal_records.engine
    name, secret = "acme.temp", "a temporary password"
    add_account(engine, name, secret, customer="ACME Ltd", display_name="Temp", actor="test")
    client = TestClient(portal_app)
    assert _portal_login(client, name, secret).status_code == 303
    assert client.get("/portal").status_code == 200
    set_account_active(engine, name, False, actor="test")
    assert client.get("/portal", follow_redirects=False).status_code == 303
    assert _portal_login(client, name, secret).status_code == 401  # disabled: no sign-in
    set_account_active(engine, name, True, actor="test")
    assert _portal_login(client, name, secret).status_code == 303
    set_account_password(engine, name, "another temporary password", actor="test")
    assert client.get("/portal", follow_redirects=False).status_code == 303
    assert _portal_login(client, name, "another temporary password").status_code == 303
    remove_account(engine, name, actor="test")
    assert client.get("/portal", follow_redirects=False).status_code == 303
    assert _portal_login(client, name, "another temporary password").status_code == 401


def test_sign_out_ends_the_portal_session(portal_app, acme: TestClient) -> None:
    copied = acme.cookies[COOKIE]
    token = re.search(r'name="csrf" value="([^"]+)"', acme.get("/portal").text)
    assert token is not None
    out = acme.post("/portal/logout", data={"csrf": token.group(1)}, follow_redirects=False)
    assert out.status_code == 303 and out.headers["location"] == "/portal/login"
    replay = TestClient(portal_app)
    replay.cookies.set(COOKIE, copied)  # a copy of the cookie from before sign-out
    assert replay.get("/portal", follow_redirects=False).status_code == 303
