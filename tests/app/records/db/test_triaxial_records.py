"""A triaxial DUT's orientation run in the records (issue 36 point 3): its three channels are
indexed, the main axis as the sensor's calibration, a cross channel (a transverse
sensitivity, no verdict) outside the sensor's history and drift; the staff's shared-runs view
does not list the sensor as sharing a run with itself. On SQLite and PostgreSQL."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import select
from sqlalchemy.engine import Engine

from app.procedure.batch import MemberChoice
from app.procedure.request import RunRequest
from app.procedure.triaxial import execute_triaxial
from app.records.db.lab import Lab
from app.records.db.models import Run
from app.stand import config as stand_config
from app.web.shared import shared_runs

pytestmark = pytest.mark.integration

STAND = Path(__file__).parents[4] / "sim" / "stand-triaxial.toml"


@pytest.fixture(scope="module")
def runs_root(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A runs root holding the triaxial DUT TRI-1's orientation x run (its three channels)."""
    base = tmp_path_factory.mktemp("triaxial-records")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("ACCELCAL_DATA_DIR", str(base / "data"))
        request = RunRequest(stand_file=STAND, out=base / "runs", seed=7, stored_response=False)
        execute_triaxial(request, MemberChoice("T", "TRI-1"), "x", config=stand_config.load(STAND))
    yield base / "runs"


def test_cross_channels_are_indexed_outside_the_sensors_history(
    engine: Engine, runs_root: Path
) -> None:
    lab = Lab(engine, actor="tester")
    lab.add_customer("ACME Ltd")
    lab.add_model(
        "Sim", "TRI", nominal_sensitivity=10.0, unit="mV/(m/s^2)", tolerance_percent=5,
        frequency_min_hz=10, frequency_max_hz=2500,
    )  # fmt: skip
    lab.add_sensor("TRI-1", model="TRI", owner="ACME Ltd")
    report = lab.import_runs(runs_root)
    assert len(report.imported) == 3 and not report.refused
    with lab.session() as s:
        rows = s.scalars(select(Run).order_by(Run.run_id)).all()
        assert [r.run_id.split("-")[-2] for r in rows] == ["xx", "xy", "xz"]
        assert [r.sensitivity_mv_per_ms2 is not None for r in rows] == [True, False, False]
        main_run = rows[0].run_id
    history = lab.history("TRI-1")
    assert [p.run_id for p in history.points] == [main_run]  # the main axis alone
    assert history.points[0].sensitivity_mv_per_ms2 == pytest.approx(10.2, rel=0.05)
    with lab.session() as s:
        shared = shared_runs(s, "TRI-1")
    assert len(shared) == 3
    assert all(run.others == () for run in shared)  # its own channels are not other sensors
