"""How a run uses the records: the DUT's settings from its sensor record (`run --sensor`), the
reference standard's due date as the GUI shows it (a run's own rule: app.procedure.reference),
and the finished run indexed.

The run folder is the record: when the database cannot be reached after a run, the run is
kept complete in its folder, the user is told, and the next `accelcal db import` indexes it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import date
from pathlib import Path
from typing import Any

from app.records.db.errors import RecordsInputError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SensorDefaults:
    """What a sensor's record sets for its run (sensitivities in mV/(m/s^2), level m/s^2)."""

    serial: str
    description: str
    nominal_mv_per_ms2: float
    tolerance_percent: float
    level_ms2: float
    preset: str
    charge_unit: bool
    maker: str = ""
    model: str = ""
    frequency_min_hz: float = 0.0
    frequency_max_hz: float = float("inf")
    phase_tolerance_deg: float | None = None  # the phase's tolerance over the model's range


def sensor_defaults(serial: str, url: str | None) -> SensorDefaults:
    """The run settings of sensor `serial` from the records; RecordsInputError naming --sensor
    when the sensor is unknown or the records cannot be reached."""
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab

    try:
        sensor = Lab(open_engine(url)).sensor(serial)
    except RecordsInputError as exc:
        raise RecordsInputError(f"--sensor: {exc}") from None
    return defaults_of(sensor)


def defaults_of(sensor: Any) -> SensorDefaults:
    """The run settings of a sensor read from the records (an app.records.db.models.Sensor
    with its model and owner loaded)."""
    from app.records.db.units import CHARGE_UNITS, to_mv_per_ms2

    model = sensor.model
    return SensorDefaults(
        serial=sensor.serial,
        description=f"{model.maker} {model.model}, owner {sensor.owner.name}",
        nominal_mv_per_ms2=to_mv_per_ms2(model.nominal_sensitivity, model.unit),
        tolerance_percent=model.tolerance_percent,
        level_ms2=model.level_ms2,
        preset=model.preset,
        charge_unit=model.unit in CHARGE_UNITS,
        maker=model.maker,
        model=model.model,
        frequency_min_hz=model.frequency_min_hz,
        frequency_max_hz=model.frequency_max_hz,
        phase_tolerance_deg=model.phase_tolerance_deg,
    )


def reference_due_note(
    lab: Any, reference_id: str, *, today: date, override_reason: str | None
) -> str | None:
    """The reference standard's due date on records already open (`app.records.db.lab.Lab`; the
    GUI's; a run's own rule is app.procedure.reference, through build_request): the records'
    rule (`Lab.reference_for_run`), RecordsInputError naming the due date when refused, else a
    note (None when nothing to say)."""
    from app.records.db.lab import RecordsError

    try:
        ref = lab.reference_for_run(reference_id, today=today, override_reason=override_reason)
    except RecordsError as exc:
        if "no reference standard" in str(exc):
            return f"reference standard {reference_id} is not in the records (stand file only)"
        raise
    if ref.due_date < today:
        return (
            f"reference standard {reference_id} was due on {ref.due_date}; used under the "
            f"override: {override_reason}"
        )
    return None


def index_finished_run(folder: Path, url: str | None, *, lab: Any = None) -> str:
    """Index a finished run folder into the records (`lab` when already open, else those at
    `url`): the one indexing of every face (app.procedure.service). Its report, one line and
    a "WARNING ..." line per control-chart warning of the import, never an exception (the
    folder is the record: an unreachable database loses nothing)."""
    try:
        if lab is None:
            from app.records.db.engine import open_engine
            from app.records.db.lab import Lab

            lab = Lab(open_engine(url))
        report = lab.import_runs(folder)
    except Exception as exc:  # any failure of the database must not fail a recorded run
        log.warning("run %s not indexed: %s", folder, exc)
        return (
            f"records: the run is stored in {folder} but was not indexed ({exc}); "
            "run `accelcal db import` when the database is back"
        )
    if report.refused:
        return f"records: not indexed: {report.refused[0][1]}"
    lines = [f"records: run indexed ({', '.join(report.imported) or 'already known'})"]
    lines += [f"WARNING {warning}" for warning in report.warnings]
    return "\n".join(lines)
