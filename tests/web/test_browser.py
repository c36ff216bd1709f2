"""The web view in a real headless browser (Debian's Chromium through Selenium and its
chromedriver; `make browser` installs them): sign in, search the register, open a
certificate's page, read the QR code the browser drew and follow it, signed out, to the
public status page. Skipped without Chromium, except under CI=true where it fails."""

from __future__ import annotations

import io
import os
import shutil
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.web.conftest import (
    ACME_ACCOUNT,
    ACME_PASSWORD,
    NEVER_CALIBRATED,
    PASSWORD,
    USER,
    PortalRecords,
    Records,
)

pytestmark = pytest.mark.integration

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")


def _need_browser() -> None:
    if CHROMIUM and CHROMEDRIVER:
        return
    why = "no chromium/chromedriver (make browser)"
    if os.environ.get("CI") == "true":
        pytest.fail(f"the browser test cannot run in CI: {why}")
    pytest.skip(why)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture
def server(store) -> Iterator[str]:
    """The web view served by uvicorn on a free local port, in a thread; its base URL."""
    yield from _serve(store, "s" * 40)


def _chrome(downloads: Path | None = None) -> Iterator:
    """A headless Chromium (downloads saved to `downloads` without asking, when given)."""
    _need_browser()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                     "--window-size=1280,1000", "--disable-gpu"):  # fmt: skip
        options.add_argument(argument)
    if downloads is not None:
        options.add_experimental_option(
            "prefs",
            {"download.default_directory": str(downloads), "download.prompt_for_download": False},
        )
    driver = webdriver.Chrome(service=Service(executable_path=str(CHROMEDRIVER)), options=options)
    driver.set_page_load_timeout(30)
    driver.implicitly_wait(20)  # a loaded 2-core machine: elements may come late
    if downloads is not None:  # headless Chromium asks for this besides the preference
        where = {"behavior": "allow", "downloadPath": str(downloads)}
        driver.execute_cdp_cmd("Browser.setDownloadBehavior", where)
    try:
        yield driver
    finally:
        driver.quit()


@pytest.fixture
def browser() -> Iterator:
    yield from _chrome()


def _serve(store, secret: str) -> Iterator[str]:
    """The web view over `store` served by uvicorn on a free local port, in a thread; its
    base URL."""
    import uvicorn

    from app.web.server import WebConfig, create_app

    port = _free_port()
    base = f"http://127.0.0.1:{port}"
    config = WebConfig(secret_key=secret, verify_url=f"{base}/verify")
    server = uvicorn.Server(
        uvicorn.Config(create_app(store, config), host="127.0.0.1", port=port, log_level="warning")
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not server.started:
        if time.monotonic() > deadline or not thread.is_alive():
            pytest.fail("the web view did not start")
        time.sleep(0.05)
    try:
        yield base
    finally:
        server.should_exit = True
        thread.join(timeout=10)


@pytest.mark.long
def test_login_search_certificate_and_the_qr_code_to_the_public_status(
    server: str, browser, records: Records
) -> None:
    import zxingcpp
    from PIL import Image
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait

    def wait_for_url(url: str) -> None:
        WebDriverWait(browser, 30).until(ec.url_to_be(url))

    def wait_for_heading(text: str) -> None:
        WebDriverWait(browser, 30).until(
            ec.text_to_be_present_in_element((By.TAG_NAME, "h1"), text)
        )

    old, new, _ = records.numbers
    browser.get(f"{server}/register")
    assert "/login" in browser.current_url  # a stranger is sent to sign in
    browser.find_element(By.ID, "username").send_keys(USER)
    browser.find_element(By.ID, "password").send_keys(PASSWORD)
    browser.find_element(By.ID, "sign-in").click()
    wait_for_url(f"{server}/register")
    assert browser.find_element(By.TAG_NAME, "h1").text == "Certificate register"

    search = browser.find_element(By.ID, "q")
    search.clear()
    search.send_keys(new)
    browser.find_element(By.ID, "search").click()
    WebDriverWait(browser, 30).until(ec.url_contains("q="))
    links = browser.find_elements(By.CSS_SELECTOR, "#register tbody a[href^='/certificates/']")
    assert [link.text for link in links] == [new]
    links[0].click()

    wait_for_heading(f"Certificate {new}")
    assert browser.find_element(By.TAG_NAME, "h1").text == f"Certificate {new}"
    assert browser.find_element(By.ID, "status").text == "valid"
    assert (
        browser.find_element(By.ID, "pdf")
        .get_attribute("href")
        .endswith(f"/certificates/{new}/certificate.pdf")
    )
    # the test runs' stand names no verify_url: no QR code was printed, and the page says so
    assert browser.find_element(By.ID, "no-qr").text.startswith(
        "No QR code was printed on this certificate"
    )
    picture = browser.find_element(By.ID, "qr").screenshot_as_png  # as the browser drew it
    (code,) = zxingcpp.read_barcodes(Image.open(io.BytesIO(picture)))
    address = code.text
    assert address.startswith(f"{server}/verify/{new}?code=")
    assert address == browser.find_element(By.ID, "address").text

    browser.find_element(By.ID, "logout").click()
    wait_for_url(f"{server}/login")  # signed out: the sign-in page
    browser.delete_all_cookies()
    browser.get(address)  # the QR round trip, as a customer with no account
    status = WebDriverWait(browser, 30).until(
        ec.presence_of_element_located((By.ID, "status")),
        message=f"no status on {browser.current_url}",
    )
    assert status.text == "valid", browser.page_source[:2000]
    assert browser.find_elements(By.ID, "logout") == []
    assert "SN-WEB-1" not in browser.page_source and "ACME" not in browser.page_source
    assert browser.find_element(By.ID, "item").text == "Item: Sim P-100, serial •••••B-1"

    browser.get(address.replace(f"/verify/{new}?", f"/verify/{old}?"))  # code of another
    assert browser.find_element(By.ID, "status").text == "not found"


SHOTS = os.environ.get("ACCELCAL_WEB_SHOTS")  # a folder: the portal's pages saved as PNG there


@pytest.mark.long
def test_a_customer_signs_in_sees_its_certificates_and_due_dates_and_not_anothers(
    portal_store, portal_records: PortalRecords, tmp_path: Path
) -> None:
    from icalendar import Calendar
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait

    def shot(name: str) -> None:
        if SHOTS:
            browser.save_screenshot(str(Path(SHOTS) / f"portal-{name}.png"))

    downloads = tmp_path / "downloads"
    downloads.mkdir()
    served = _serve(portal_store, "c" * 8 + "ustomer-portal-secret-0123456789")
    base = next(served)
    chrome = _chrome(downloads)
    browser = next(chrome)
    try:
        browser.get(f"{base}/portal")
        assert "/portal/login" in browser.current_url  # a stranger is sent to sign in
        shot("login")
        browser.find_element(By.ID, "username").send_keys(ACME_ACCOUNT)
        browser.find_element(By.ID, "password").send_keys(ACME_PASSWORD)
        browser.find_element(By.ID, "sign-in").click()
        WebDriverWait(browser, 30).until(ec.url_to_be(f"{base}/portal"))
        assert browser.find_element(By.TAG_NAME, "h1").text == "Certificates of ACME Ltd"
        shot("home")
        numbers = [
            row.find_element(By.CSS_SELECTOR, "td").text
            for row in browser.find_elements(By.CSS_SELECTOR, "#certificates tbody tr")
        ]
        assert numbers == [portal_records.acme]
        assert portal_records.other not in browser.page_source
        due_rows = browser.find_elements(By.CSS_SELECTOR, "#due tbody tr")
        cells = [row.find_elements(By.TAG_NAME, "td") for row in due_rows]
        due = {row[0].text: row[4].text for row in cells}
        assert set(due) == {"SN-WEB-1", NEVER_CALIBRATED}
        assert due[NEVER_CALIBRATED] == "never calibrated here"
        pdf_link = browser.find_element(By.CSS_SELECTOR, "#certificates a.pdf")
        assert pdf_link.get_attribute("href").endswith(
            f"/portal/certificates/{portal_records.acme}/certificate.pdf"
        )

        browser.find_element(By.ID, "due-ics").click()  # the calendar file, downloaded
        deadline = time.monotonic() + 30
        while not list(downloads.glob("*.ics")) and time.monotonic() < deadline:
            time.sleep(0.2)
        (ics,) = downloads.glob("*.ics")
        (event,) = Calendar.from_ical(ics.read_bytes()).walk("VEVENT")
        assert event.decoded("dtstart").isoformat() == due["SN-WEB-1"]
        assert "SN-WEB-1" in str(event["summary"])

        browser.get(f"{base}/portal/sensors/SN-WEB-1")
        assert browser.find_element(By.ID, "due-date").text == due["SN-WEB-1"]
        shot("sensor")
        for path in (
            f"/portal/certificates/{portal_records.other}/certificate.pdf",
            "/portal/sensors/SN-WEB-2",
        ):
            browser.get(base + path)
            assert browser.find_element(By.TAG_NAME, "h1").text == "Not found"
            assert browser.find_element(By.ID, "message").text == "Not found in your records."
            assert "Other GmbH" not in browser.page_source
        shot("not-found")
        assert not list(downloads.glob("*.pdf"))  # another's certificate: nothing downloaded
        browser.get(f"{base}/register")  # a staff page: the staff sign-in, no register
        assert "/login" in browser.current_url and "/portal" not in browser.current_url
        assert browser.find_element(By.TAG_NAME, "h1").text == "Sign in"
    finally:
        for generator in (chrome, served):
            generator.close()
