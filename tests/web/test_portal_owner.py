"""A certificate is issued to one customer (issue 35 point 5, ISO/IEC 17025 4.2): when its
sensor changes owner, the customer it was issued to keeps it in the portal and the new owner
never reaches it (404, by its download URLs, as for a number that does not exist), while the
new owner sees the certificates issued to it after the move, and the sensor's due date.

Records of their own (the package's portal records stay as they are): sensor SN-WEB-1 of ACME
Ltd certified (certificate `before`), moved to Other GmbH, certified again (`after`)."""

from __future__ import annotations

import hashlib
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import pytest
from starlette.testclient import TestClient

from app.certificate import CertificateInfo
from app.certificate.register_issue import issue_registered
from app.records.db.engine import make_engine, resolve_url
from app.records.db.lab import Lab
from app.records.run_folder import sha256_of
from tests.records_db import new_records
from tests.web.conftest import SERIAL, Records

pytestmark = pytest.mark.integration

ACME, OTHER = "ACME Ltd", "Other GmbH"
ACME_ACCOUNT, OTHER_ACCOUNT = "acme.moved", "other.moved"
ACME_PASSWORD, OTHER_PASSWORD = "acme moved password", "other moved password"
NOT_FOUND = "Not found in your records."


@dataclass(frozen=True)
class Moved:
    """The records after the move: the URL, the certificate issued to ACME before it (and its
    PDF) and the one issued to Other GmbH after it."""

    url: str
    before: str
    before_pdf: Path
    after: str


@pytest.fixture(scope="module")
def moved(tmp_path_factory: pytest.TempPathFactory, records: Records) -> Moved:
    from app.web.accounts import add_account

    base = tmp_path_factory.mktemp("moved")
    url = resolve_url(new_records(base / "records.sqlite"))
    engine = make_engine(url)
    lab = Lab(engine, actor="test")
    lab.add_customer(ACME, "1 Test Street, Testville")
    lab.add_customer(OTHER, "2 Other Street, Elsewhere")
    lab.add_model(
        "Sim",
        "P-100",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5.0,
        frequency_min_hz=10.0,
        frequency_max_hz=10000.0,
    )
    lab.add_sensor(SERIAL, model="P-100", owner=ACME)
    info = CertificateInfo(
        authorised_by="J. Smith",
        dut_type="piezoelectric accelerometer",
        temperature_c=23.0,
        mounting="stud-mounted",
    )
    runs = []
    for run in records.runs[:2]:  # copies: the staff tests' runs stay as they are
        runs.append(base / "runs" / run.name)
        shutil.copytree(run, runs[-1])
    before_pdf = base / "before.pdf"
    before = issue_registered(runs[0], info, before_pdf, url=url, prepared_by="A. Preparer")
    lab.move_sensor(SERIAL, owner=OTHER)
    after = issue_registered(runs[1], info, base / "after.pdf", url=url, prepared_by="A. Preparer")
    for name, password, customer in (
        (ACME_ACCOUNT, ACME_PASSWORD, ACME),
        (OTHER_ACCOUNT, OTHER_PASSWORD, OTHER),
    ):
        add_account(engine, name, password, customer=customer, display_name=name, actor="test")
    engine.dispose()
    return Moved(url, before.number, before_pdf, after.number)


@pytest.fixture(scope="module")
def moved_app(moved: Moved):
    from app.web.server import WebConfig, create_app
    from app.web.store import Store, open_read_only

    engine = open_read_only(moved.url)
    yield create_app(Store(engine), WebConfig(secret_key="m" * 40))
    engine.dispose()


def _client(app, user: str, password: str) -> TestClient:
    client = TestClient(app)
    form = client.get("/portal/login").text
    match = re.search(r'name="csrf" value="([^"]+)"', form)
    assert match is not None
    data = {"username": user, "password": password, "csrf": match.group(1)}
    assert client.post("/portal/login", data=data, follow_redirects=False).status_code == 303
    return client


def _not_found(response) -> bool:
    return response.status_code == 404 and NOT_FOUND in response.text


def test_each_certificate_is_bound_to_the_owner_it_was_issued_to(moved: Moved) -> None:
    lab = Lab(make_engine(moved.url), actor="test")
    customers = {c.id: c.name for c in lab.customers()}
    bound = {c.number: customers[c.customer_id] for c in lab.register()}
    assert bound == {moved.before: ACME, moved.after: OTHER}
    assert lab.sensor(SERIAL).owner.name == OTHER  # the sensor is the new owner's now


def test_the_previous_owner_keeps_and_downloads_its_certificate(moved_app, moved: Moved) -> None:
    acme = _client(moved_app, ACME_ACCOUNT, ACME_PASSWORD)
    home = acme.get("/portal")
    assert home.status_code == 200
    assert moved.before in home.text and moved.after not in home.text
    assert OTHER not in home.text  # not even the new owner's name
    pdf = acme.get(f"/portal/certificates/{moved.before}/certificate.pdf")
    assert pdf.status_code == 200 and pdf.headers["content-type"] == "application/pdf"
    assert hashlib.sha256(pdf.content).hexdigest() == sha256_of(moved.before_pdf)
    dcc = acme.get(f"/portal/certificates/{moved.before}/certificate.xml")
    assert dcc.status_code == 200 and moved.before.encode() in dcc.content
    # the sensor and its due date are the new owner's business now
    assert _not_found(acme.get(f"/portal/sensors/{SERIAL}"))
    assert _not_found(acme.get(f"/portal/certificates/{moved.after}/certificate.pdf"))
    assert SERIAL not in acme.get("/portal/due.csv").text


def test_the_new_owner_never_reaches_the_previous_owners_certificate(
    moved_app, moved: Moved
) -> None:
    other = _client(moved_app, OTHER_ACCOUNT, OTHER_PASSWORD)
    absent = other.get("/portal/certificates/NO-SUCH-1/certificate.pdf")
    assert _not_found(absent)
    for kind in ("pdf", "xml"):
        response = other.get(f"/portal/certificates/{moved.before}/certificate.{kind}")
        assert _not_found(response), kind
        assert moved.before not in response.text
    home = other.get("/portal")
    assert home.status_code == 200 and moved.before not in home.text
    sensor = other.get(f"/portal/sensors/{SERIAL}")
    assert sensor.status_code == 200 and moved.before not in sensor.text
    assert ACME not in home.text and ACME not in sensor.text


def test_the_new_owner_sees_what_was_issued_to_it_after_the_move(moved_app, moved: Moved) -> None:
    other = _client(moved_app, OTHER_ACCOUNT, OTHER_PASSWORD)
    home = other.get("/portal")
    assert moved.after in home.text and SERIAL in home.text
    sensor = other.get(f"/portal/sensors/{SERIAL}")
    assert moved.after in sensor.text
    pdf = other.get(f"/portal/certificates/{moved.after}/certificate.pdf")
    assert pdf.status_code == 200 and pdf.content.startswith(b"%PDF")
    assert SERIAL in other.get("/portal/due.csv").text  # the due date follows the sensor
