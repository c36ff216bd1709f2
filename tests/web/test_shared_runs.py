"""A sensor's runs shared with other DUTs in the web view (issue 36, channels point 3): the
staff's sensor page lists each shared run's batch and the other members' serials and
positions (from runs.batch_id, migration 0015); the customer portal shows nothing of a shared
run's other members, which may belong to other customers. Through Starlette's TestClient,
and the staff page in a real headless browser (Selenium, Chromium) like test_browser."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from starlette.testclient import TestClient

from app.certificate import CertificateInfo
from app.certificate.register_issue import issue_registered
from app.procedure.batch import MemberChoice, execute_batch
from app.procedure.request import RunRequest
from app.records.db.engine import make_engine, resolve_url
from app.records.db.lab import Lab
from app.records.db.runs import index_finished_run
from app.stand import config as stand_config
from app.web.accounts import add_account
from app.web.users import add_user
from tests.records_db import new_records
from tests.web.conftest import PASSWORD, USER

pytestmark = pytest.mark.integration

STAND = Path(__file__).parents[2] / "sim" / "stand-fixture4.toml"
ACME_A, OTHER_B, ACME_C = "SN-SH-ACME-A", "SN-SH-OTHER-B", "SN-SH-ACME-C"
SECRET = "s" * 8 + "hared-runs-secret-0123456789abcdef"
ACCOUNT, ACCOUNT_PASSWORD = "acme.shared", "acme shared portal password"


@dataclass(frozen=True)
class SharedRecords:
    url: str
    batch_id: str
    number: str  # ACME's certificate of SN-SH-ACME-A's member run


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory) -> SharedRecords:
    """One batch of three DUTs (A: ACME's, B: Other GmbH's, C: ACME's), every member indexed,
    ACME's A certified; a staff user and an ACME portal account."""
    base = tmp_path_factory.mktemp("shared")
    url = resolve_url(new_records(base / "records.sqlite"))
    engine = make_engine(url)
    lab = Lab(engine, actor="test")
    lab.add_customer("ACME Ltd", "1 Test Street, Testville")
    lab.add_customer("Other GmbH", "2 Other Street, Elsewhere")
    lab.add_model(
        "Sim",
        "P-100",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5.0,
        frequency_min_hz=10.0,
        frequency_max_hz=10000.0,
    )
    for serial, owner in ((ACME_A, "ACME Ltd"), (OTHER_B, "Other GmbH"), (ACME_C, "ACME Ltd")):
        lab.add_sensor(serial, model="P-100", owner=owner)
    request = RunRequest(
        stand_file=STAND, out=base / "runs", seed=9, periods=3, stored_response=False
    )
    choices = [MemberChoice("A", ACME_A, "piezo"), MemberChoice("B", OTHER_B, "piezo"),
               MemberChoice("C", ACME_C, "piezo")]  # fmt: skip
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("XDG_DATA_HOME", str(base / "data"))
        finished = execute_batch(request, choices, config=stand_config.load(STAND))
    folders = {c.serial: base / "runs" / str(one.record.run_id) for c, one in finished.members}
    for serial in (OTHER_B, ACME_C):
        assert "run indexed" in index_finished_run(folders[serial], url)
    info = CertificateInfo(authorised_by="J. Smith", dut_type="piezoelectric accelerometer",
                           temperature_c=23.0, mounting="stud-mounted")  # fmt: skip
    issued = issue_registered(
        folders[ACME_A], info, base / "acme.pdf", url=url, prepared_by="A. Preparer"
    )
    add_user(engine, USER, PASSWORD, display_name="Quality Manager", actor="test")
    add_account(engine, ACCOUNT, ACCOUNT_PASSWORD, customer="ACME Ltd",
                display_name="ACME purchasing", actor="test")  # fmt: skip
    engine.dispose()
    return SharedRecords(url, finished.batch_id, issued.number)


@pytest.fixture(scope="module")
def store(shared: SharedRecords) -> Iterator:
    from app.web.store import Store, open_read_only

    engine = open_read_only(shared.url)
    yield Store(engine)
    engine.dispose()


@pytest.fixture
def client(store) -> TestClient:
    from app.web.server import WebConfig, create_app

    return TestClient(create_app(store, WebConfig(secret_key=SECRET)))


def _login(client: TestClient, path: str, user: str, password: str) -> None:
    page = client.get(path)
    match = re.search(r'name="csrf" value="([^"]+)"', page.text)
    assert match is not None
    data = {"username": user, "password": password, "csrf": match.group(1)}
    assert client.post(path, data=data, follow_redirects=False).status_code == 303


def test_the_store_names_each_shared_run_with_the_others_serials_and_positions(
    store, shared: SharedRecords
) -> None:
    (run,) = store.shared_runs(ACME_A)
    assert (run.batch_id, run.position, run.status) == (shared.batch_id, "A", "complete")
    assert [(m.serial, m.position) for m in run.others] == [(OTHER_B, "B"), (ACME_C, "C")]
    (run_b,) = store.shared_runs(OTHER_B)
    assert run_b.position == "B" and [m.serial for m in run_b.others] == [ACME_A, ACME_C]
    assert store.shared_runs("SN-NOT-THERE") == []


def test_the_positions_stay_blank_when_the_run_folder_is_not_readable(
    store, shared: SharedRecords, monkeypatch
) -> None:
    import app.web.shared as module

    def unreadable(cls, folder: Path):
        raise PermissionError(f"{folder}: permission denied")

    monkeypatch.setattr(module.RunStart, "read", classmethod(unreadable))
    (run,) = store.shared_runs(ACME_A)
    assert (run.batch_id, run.position) == (shared.batch_id, "")  # the records still say
    assert [(m.serial, m.position) for m in run.others] == [(ACME_C, ""), (OTHER_B, "")]


def test_the_staff_sensor_page_shows_the_runs_it_shared(client, shared: SharedRecords) -> None:
    _login(client, "/login", USER, PASSWORD)
    page = client.get(f"/sensors/{ACME_A}")
    assert page.status_code == 200
    table = page.text.split('<table id="shared">', 1)[1].split("</table>", 1)[0]
    assert shared.batch_id in table
    assert f'<a href="/sensors/{OTHER_B}">{OTHER_B}</a> at B' in table
    assert f'<a href="/sensors/{ACME_C}">{ACME_C}</a> at C' in table
    assert ACME_A not in table  # the sensor itself is not among the others


def test_the_portal_never_names_another_customers_sensor_of_a_shared_run(
    client, shared: SharedRecords
) -> None:
    _login(client, "/portal/login", ACCOUNT, ACCOUNT_PASSWORD)
    pages = [
        client.get("/portal"),
        client.get(f"/portal/sensors/{ACME_A}"),
        client.get(f"/portal/sensors/{ACME_C}"),
    ]
    assert [p.status_code for p in pages] == [200, 200, 200]
    assert shared.number in pages[0].text and ACME_A in pages[0].text
    documents = [client.get(f"/portal/certificates/{shared.number}/certificate.{kind}")
                 for kind in ("pdf", "xml")]  # fmt: skip
    assert [d.status_code for d in documents] == [200, 200]
    for text in [p.text for p in pages] + [d.text for d in documents]:
        assert OTHER_B not in text and "Other GmbH" not in text
    for page in pages:  # the portal's pages list no shared run (the certificate itself states
        assert shared.batch_id not in page.text  # its batch and position: app.certificate)
    assert client.get(f"/portal/sensors/{OTHER_B}").status_code == 404


@pytest.mark.long
def test_the_staff_sensor_page_in_a_browser_links_the_other_members(store, shared) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait

    from tests.web.test_browser import _chrome, _serve

    for base in _serve(store, SECRET):
        for browser in _chrome():
            browser.get(f"{base}/login")
            browser.find_element(By.ID, "username").send_keys(USER)
            browser.find_element(By.ID, "password").send_keys(PASSWORD)
            browser.find_element(By.ID, "sign-in").click()
            WebDriverWait(browser, 30).until(ec.url_contains("/register"))
            browser.get(f"{base}/sensors/{ACME_A}")
            rows = browser.find_elements(By.CSS_SELECTOR, "#shared tr")
            assert len(rows) == 2, browser.page_source[:2000]  # the header and the one run
            assert browser.find_element(By.CSS_SELECTOR, "#shared td.batch").text == (
                shared.batch_id
            )
            links = browser.find_elements(By.CSS_SELECTOR, "#shared a")
            assert [link.text for link in links] == [OTHER_B, ACME_C]
            links[0].click()
            WebDriverWait(browser, 30).until(
                ec.text_to_be_present_in_element((By.TAG_NAME, "h1"), f"Sensor {OTHER_B}")
            )
            others = browser.find_elements(By.CSS_SELECTOR, "#shared a")
            assert [link.text for link in others] == [ACME_A, ACME_C]
