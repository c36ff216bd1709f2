"""$ACCELCAL_DATA_DIR moves the user's data (default records file, stored stand responses), so
`make demo` and tests never read or write the user's own (issue 27 point 4)."""

from __future__ import annotations

from pathlib import Path

from app.files import data_dir
from app.records.db.engine import default_url
from app.stand.response import ResponseStore


def test_the_variable_moves_records_and_responses(tmp_path, monkeypatch):
    monkeypatch.setenv("ACCELCAL_DATA_DIR", str(tmp_path / "demo"))
    assert data_dir() == tmp_path / "demo"
    assert default_url() == f"sqlite:///{tmp_path / 'demo' / 'records.sqlite'}"
    assert ResponseStore.default().root == tmp_path / "demo" / "stand-responses"


def test_without_it_the_user_data_directory(monkeypatch):
    from platformdirs import user_data_dir

    monkeypatch.delenv("ACCELCAL_DATA_DIR", raising=False)
    assert data_dir() == Path(user_data_dir("accelcal", appauthor=False))
    assert ResponseStore.default().root == data_dir() / "stand-responses"
