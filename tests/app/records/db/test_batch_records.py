"""Several DUTs in one run in the records (issue 36): migration 0015's runs.batch_id; each
member indexed as its own sensor's calibration; a sensor's history shows the runs it shared
and with which sensors; a single run's history as before. On SQLite and PostgreSQL."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import inspect, select
from sqlalchemy.engine import Engine

from app.cli.listing import history_object
from app.procedure.batch import MemberChoice, execute_batch
from app.procedure.request import RunRequest
from app.records.db.lab import Lab
from app.records.db.models import Run
from app.stand import config as stand_config

pytestmark = pytest.mark.integration

STAND = Path(__file__).parents[4] / "sim" / "stand-fixture4.toml"
SERIALS = ("SN-A", "SN-B", "SN-C")


@pytest.fixture(scope="module")
def runs_root(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A runs root holding one batch of three DUTs (A, B, C) and its member folders."""
    base = tmp_path_factory.mktemp("batch-records")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("XDG_DATA_HOME", str(base / "data"))
        request = RunRequest(
            stand_file=STAND, out=base / "runs", seed=11, periods=3, stored_response=False
        )
        choices = [MemberChoice(p, s) for p, s in zip("ABC", SERIALS, strict=True)]
        execute_batch(request, choices, config=stand_config.load(STAND))
    yield base / "runs"


@pytest.fixture
def lab(engine: Engine) -> Lab:
    lab = Lab(engine, actor="tester")
    lab.add_customer("ACME Ltd")
    lab.add_model(
        "PCB",
        "352C33",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5,
        frequency_min_hz=10,
        frequency_max_hz=10000,
    )
    for serial in (*SERIALS, "SN-42"):  # SN-42: the session's complete single run
        lab.add_sensor(serial, model="352C33", owner="ACME Ltd")
    return lab


def test_the_run_index_has_an_indexed_batch_id_column(engine: Engine) -> None:
    columns = {c["name"]: c for c in inspect(engine).get_columns("runs")}
    assert columns["batch_id"]["nullable"] is True
    indexes = {i["name"] for i in inspect(engine).get_indexes("runs")}
    assert "ix_runs_batch_id" in indexes


def test_each_member_is_its_sensors_calibration_and_shows_the_runs_it_shared(
    lab: Lab, runs_root: Path
) -> None:
    report = lab.import_runs(runs_root)
    assert len(report.imported) == 3  # the members; the batch folder is not a run
    assert not report.refused
    (batch,) = [p.name for p in runs_root.iterdir() if "batch" in p.name]
    with lab.session() as s:
        rows = s.scalars(select(Run).order_by(Run.dut_id)).all()
        assert [(r.dut_id, r.batch_id, r.sensor.serial) for r in rows] == [
            (serial, batch, serial) for serial in SERIALS
        ]
    history = lab.history("SN-B")
    (point,) = history.points
    assert point.batch_id == batch and point.shared_with == ("SN-A", "SN-C")
    listed = history_object(history)["points"][0]
    assert listed["batch_id"] == batch and listed["shared_with"] == ["SN-A", "SN-C"]
    assert json.dumps(listed)  # JSON-ready
    again = lab.import_runs(runs_root)
    assert not again.imported and len(again.known) == 3


def test_a_single_runs_history_is_as_before(lab: Lab, complete_run: Path) -> None:
    assert lab.import_runs(complete_run).imported
    (point,) = lab.history("SN-42").points
    assert point.batch_id is None and point.shared_with == ()
    assert "batch_id" not in history_object(lab.history("SN-42"))["points"][0]
