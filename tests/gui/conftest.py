"""GUI tests never open the user's own records: $ACCELCAL_DB points at an empty file per test
(the Sensors tab then says the records have no schema); tests that use records pass `db=`."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _isolated_records(tmp_path_factory: pytest.TempPathFactory, monkeypatch) -> None:
    folder = tmp_path_factory.mktemp("records")
    monkeypatch.setenv("ACCELCAL_DB", f"sqlite:///{folder / 'none.sqlite'}")
    monkeypatch.setenv("XDG_DATA_HOME", str(folder))
