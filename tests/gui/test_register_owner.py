"""The Register tab's Customer column is the customer each certificate was issued to (issue 35
point 5, migration 0014), not the sensor's owner now."""

from __future__ import annotations

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from pathlib import Path

from app.gui.register_tab import RegisterTab
from app.records.db.engine import make_engine
from tests.app.records.db.test_chain import _lab_day


def test_the_register_names_the_customer_a_certificate_was_issued_to(
    records_url: str, tmp_path: Path
) -> None:
    engine = make_engine(records_url)
    lab = _lab_day(engine, tmp_path)
    lab.add_customer("Buyer GmbH")
    lab.move_sensor("SN-1", owner="Buyer GmbH")
    (certificate,) = lab.register()
    cells = RegisterTab._row(certificate)
    assert cells[3:5] == ("SN-1", "ACME Ltd")
    engine.dispose()
