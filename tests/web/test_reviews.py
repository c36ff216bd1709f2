"""A certificate under review in the web view (issue 27, ISO/IEC 17025 7.10): the public page
(the QR code's) and the staff pages say "under review (reference standard REF found out of
tolerance on DATE)" while a review is open, "valid" again once it is closed as confirmed and
"amended by N" once closed by its amendment. On a copy of the web tests' records (their
fixture is shared and read-only)."""

from __future__ import annotations

import re
import sqlite3
from datetime import UTC, datetime
from pathlib import Path

import pytest
from sqlalchemy.engine import make_url
from starlette.testclient import TestClient

from app.certificate.qr import verification_code
from app.records.db.engine import make_engine, resolve_url
from app.records.db.lab import Lab
from app.records.db.reviews import impact_subject
from app.records.run_folder import MANIFEST_NAME, sha256_of
from app.web.server import WebConfig, create_app
from app.web.store import Store, open_read_only
from tests.web.conftest import PASSWORD, USER, Records
from tests.web.test_pages import _login

pytestmark = pytest.mark.integration


def _copy(records: Records, folder: Path) -> str:
    """The test records copied (SQLite's backup: WAL included) into `folder`; its URL."""
    source = make_url(records.url).database
    target = folder / "records.sqlite"
    with sqlite3.connect(source) as src, sqlite3.connect(target) as dst:
        src.backup(dst)
    return resolve_url(f"sqlite:///{target}")


def _status(page: str) -> str:
    """The text of the element with id "status" (whatever its other attributes)."""
    match = re.search(r'id="status"[^>]*>([^<]*)<', page)
    assert match is not None, page[:2000]
    return match.group(1)


def test_public_and_staff_pages_follow_a_review_from_open_to_closed(
    records: Records, tmp_path: Path
) -> None:
    url = _copy(records, tmp_path)
    writer = make_engine(url)
    lab = Lab(writer, actor="qm")
    valid = records.numbers[1]  # the amendment, of run 1, in force
    code = verification_code(valid, sha256_of(records.runs[1] / MANIFEST_NAME))
    assert lab.open_review(valid, subject=impact_subject("SIM-0001"), reason="impact: check")
    today = datetime.now(UTC).date().isoformat()
    under = f"under review (reference standard SIM-0001 found out of tolerance on {today})"
    engine = open_read_only(url)
    app = create_app(Store(engine), WebConfig(secret_key="k" * 40))
    public, staff = TestClient(app), TestClient(app)
    assert _login(staff, USER, PASSWORD).status_code == 303

    def shown() -> tuple[str, str]:
        answer = public.get(f"/verify/{valid}", params={"code": code})
        assert answer.status_code == 200
        return _status(answer.text), _status(staff.get(f"/certificates/{valid}").text)

    assert shown() == (under, under)
    page = public.get(f"/verify/{valid}", params={"code": code}).text
    assert 'class="status review"' in page and "reviewing this certificate" in page
    assert f'<td class="review">{under}</td>' in staff.get("/register").text
    # a wrong code tells nothing, review or not
    assert public.get(f"/verify/{valid}", params={"code": "x" * 16}).status_code == 404
    lab.close_review(valid, outcome="confirmed", reason="change 0.1 U: stands")
    assert shown() == ("valid", "valid")
    # under review again (another reference), then amended: "amended by" the new number
    assert lab.open_review(valid, subject=impact_subject("SIM-0002"), reason="impact: check")
    assert shown()[0].startswith("under review (reference standard SIM-0002 found")
    run_id = records.runs[1].name
    new = lab.issue_certificate(
        run_id=run_id,
        prepared_by="A. Preparer",
        approved_by="J. Smith",
        replaces=valid,
        reason="sensitivity corrected (impact of SIM-0002)",
    ).number
    assert shown()[0].startswith("under review")  # replaced, but the review is still open
    lab.close_review(valid, outcome="amended", reason="2 % change", amended_by=new)
    assert shown() == (f"amended by {new}", f"amended by {new}")
    page = public.get(f"/verify/{valid}", params={"code": code}).text
    assert 'class="status amended"' in page and "Preparer" not in page
    engine.dispose()
    writer.dispose()
