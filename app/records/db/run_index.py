"""The index of run folders in the records (each verified by its manifest hash first; the folder
stays the record) and what it answers: a sensor's history with its drift in % per year, and a
check standard's individuals control chart (ISO 7870-2), sensitivities in mV/(m/s^2).
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.records.batch import is_batch_folder
from app.records.db.models import AuditEntry, Run, Sensor, Stand
from app.records.db.sensors import SensorRecords
from app.records.db.store import RecordsError, utc
from app.records.run_folder import MANIFEST_NAME, STATUS_COMPLETE, inspect_run, sha256_of
from app.records.run_record import RunRecord
from app.records.run_start import RunStart

DAYS_PER_YEAR = 365.2425
MIN_DRIFT_SPAN_DAYS = 30
MIN_CONTROL_POINTS = 5  # earlier points before control limits mean anything
D2_MOVING_RANGE = 1.128  # d2 for moving ranges of two (ISO 7870-2, table 2)


@dataclass(frozen=True)
class HistoryPoint:
    """One complete run of a sensor: when, sensitivity and expanded U at the reference
    frequency, in mV/(m/s^2)."""

    run_id: str
    started_utc: datetime
    reference_frequency_hz: float
    sensitivity_mv_per_ms2: float
    expanded_uncertainty_mv_per_ms2: float | None
    batch_id: str | None = None  # one DUT of several in one run (issue 36)
    shared_with: tuple[str, ...] = ()  # the serials of the other DUTs of that run


@dataclass(frozen=True)
class History:
    """A sensor's calibrations in time order and the fitted drift in percent per year."""

    serial: str
    points: tuple[HistoryPoint, ...]
    drift_percent_per_year: float | None


@dataclass(frozen=True)
class ControlChart:
    """A check standard's individuals chart on one stand, in mV/(m/s^2). Limits are None
    until MIN_CONTROL_POINTS earlier points exist; `warning` names an out-of-limits newest."""

    serial: str
    stand: str
    points: tuple[tuple[str, float], ...]
    centre: float | None
    lower: float | None
    upper: float | None
    warning: str | None


@dataclass(frozen=True)
class ImportReport:
    """What `import_runs` did: run ids indexed, already known, folders refused with why, and
    check standards whose newest run left their control limits."""

    imported: tuple[str, ...]
    known: tuple[str, ...]
    refused: tuple[tuple[str, str], ...]
    warnings: tuple[str, ...] = ()


def override_entries(record: RunRecord) -> list[AuditEntry]:
    """The run's overrides as audit entries keyed by its run id (table runs): an auditor finds
    every run made past a check, and why, in the trail, beside the entry made when the
    override was granted (keyed by what was overridden, before the run had an id)."""
    return [
        AuditEntry(
            at_utc=datetime.now(UTC),
            actor=override.who,
            action="override",
            table_name="runs",
            row_key=str(record.run_id),
            changes=json.dumps(override.to_dict(), sort_keys=True),
        )
        for override in record.overrides
    ]


class RunIndex(SensorRecords):
    """Run folders indexed; histories and control charts of sensors on record."""

    # ---- runs ----------------------------------------------------------------------------
    def import_runs(self, root: Path) -> ImportReport:
        """Index every run folder under `root` (or `root` itself): verified folders only,
        by manifest hash; importing twice changes nothing."""
        folders = (
            [root]
            if (root / MANIFEST_NAME).exists()
            else sorted(p for p in root.iterdir() if p.is_dir() and not is_batch_folder(p))
        )
        imported: list[str] = []
        known: list[str] = []
        refused: list[tuple[str, str]] = []
        check_standards: set[str] = set()
        for folder in folders:
            try:
                check = inspect_run(folder)
            except ValueError as exc:
                refused.append((str(folder), str(exc)))
                continue
            if check.record is None:
                refused.append((str(folder), f"{check.state}: " + "; ".join(check.problems)))
                continue
            manifest_hash = sha256_of(folder / MANIFEST_NAME)
            with self.session() as s:
                if s.scalar(select(Run).where(Run.manifest_sha256 == manifest_hash)):
                    known.append(str(check.record.run_id))
                    continue
                row = self._run_row(s, folder, check.record, manifest_hash)
                s.add(row)
                s.add_all(override_entries(check.record))
                if row.sensor is not None and row.sensor.check_standard:
                    check_standards.add(row.sensor.serial)
            imported.append(str(check.record.run_id))
        warnings = [
            chart.warning
            for serial in sorted(check_standards)
            for chart in self.control_chart(serial)
            if chart.warning
        ]
        return ImportReport(tuple(imported), tuple(known), tuple(refused), tuple(warnings))

    def _run_row(self, s: Session, folder: Path, record: RunRecord, manifest: str) -> Run:
        stand_file = folder / "stand.toml"
        stand_hash = (
            sha256_of(stand_file)
            if stand_file.exists()
            else hashlib.sha256(
                json.dumps(record.stand.to_dict(), sort_keys=True).encode()
            ).hexdigest()
        )
        stand = s.scalar(select(Stand).where(Stand.stand_file_sha256 == stand_hash))
        if stand is None:
            name = str(record.stand.description or "stand")[:200]
            stand = Stand(stand_file_sha256=stand_hash, name=name)
            s.add(stand)
        dut_id = str((record.dut.id if record.dut else None) or "")
        sensor = s.scalar(select(Sensor).where(Sensor.serial == dut_id)) if dut_id else None
        reference = ((record.results or {}).get("reference")) or {}
        if existing := s.scalar(select(Run).where(Run.run_id == record.run_id)):
            raise RecordsError(
                f"run {existing.run_id}: already indexed with another manifest "
                f"({existing.folder}); a run id is never reused"
            )
        started = utc(datetime.fromisoformat(record.started_utc))
        link = RunStart.read(folder).batch  # one DUT of several in one run: its batch
        if link is not None and link.transverse:
            # a triaxial sensor's cross channel: a transverse sensitivity, not a calibration
            # of the sensor's (issue 36 point 3); indexed, outside its history and drift
            reference = {}
        return Run(
            run_id=str(record.run_id),
            manifest_sha256=manifest,
            folder=str(folder.resolve()),
            status=record.status,
            started_utc=started,
            dut_id=dut_id,
            stand=stand,
            sensor=sensor,
            reference_frequency_hz=reference.get("frequency_hz"),
            sensitivity_mv_per_ms2=reference.get("sensitivity_mv_per_ms2"),
            expanded_uncertainty_mv_per_ms2=reference.get("expanded_uncertainty_mv_per_ms2"),
            batch_id=None if link is None else link.batch_id,
        )

    def history(self, serial: str) -> History:
        """A sensor's complete runs in time order and its drift (weighted least squares of
        sensitivity over time, weights 1/u^2 with u = U/2, in percent of the mean per year)."""
        sensor = self.sensor(serial)
        with self.session() as s:
            runs = s.scalars(
                select(Run)
                .where(
                    Run.sensor_id == sensor.id,
                    Run.status == STATUS_COMPLETE,
                    Run.sensitivity_mv_per_ms2.is_not(None),
                )
                .order_by(Run.started_utc)
            ).all()
            batches = {r.batch_id for r in runs if r.batch_id}
            shared: dict[str, list[str]] = {}
            if batches:
                for batch_id, dut_id in s.execute(
                    select(Run.batch_id, Run.dut_id)
                    .where(Run.batch_id.in_(batches), Run.dut_id != sensor.serial)
                    .order_by(Run.dut_id)
                ):
                    shared.setdefault(str(batch_id), []).append(dut_id)
        points = tuple(
            HistoryPoint(
                r.run_id,
                r.started_utc,
                float(r.reference_frequency_hz or 0.0),
                float(r.sensitivity_mv_per_ms2 or 0.0),
                r.expanded_uncertainty_mv_per_ms2,
                r.batch_id,
                tuple(shared.get(r.batch_id, ())) if r.batch_id else (),
            )
            for r in runs
        )
        return History(sensor.serial, points, drift_percent_per_year(points))

    def control_chart(self, serial: str) -> list[ControlChart]:
        """The individuals control chart of a check standard on each stand it was measured on
        (ISO 7870-2): centre line the mean, limits +-3 sigma with sigma from the mean moving
        range (d2 = 1.128), computed from every point but the newest; the newest outside the
        limits is a warning on that stand."""
        sensor = self.sensor(serial)
        with self.session() as s:
            rows = s.execute(
                select(Run, Stand.name)
                .join(Stand, Run.stand_id == Stand.id)
                .where(
                    Run.sensor_id == sensor.id,
                    Run.status == STATUS_COMPLETE,
                    Run.sensitivity_mv_per_ms2.is_not(None),
                )
                .order_by(Run.stand_id, Run.started_utc)
            ).all()
        by_stand: dict[str, list[tuple[str, float]]] = {}
        for run, stand_name in rows:
            by_stand.setdefault(stand_name, []).append(
                (run.run_id, float(run.sensitivity_mv_per_ms2 or 0.0))  # not None: the query
            )
        return [individuals_chart(serial, stand, points) for stand, points in by_stand.items()]


def drift_percent_per_year(points: Sequence[HistoryPoint]) -> float | None:
    """Weighted least-squares slope of sensitivity over time in percent of the weighted mean
    per year; weights 1/u^2 with u = U/2 (equal weights when any U is missing). None with
    fewer than two points or when they span less than MIN_DRIFT_SPAN_DAYS (a rate per year
    from runs minutes apart means nothing)."""
    if len(points) < 2:
        return None
    t0 = points[0].started_utc
    years = [(p.started_utc - t0).total_seconds() / (DAYS_PER_YEAR * 86400) for p in points]
    values = [p.sensitivity_mv_per_ms2 for p in points]
    if any(p.expanded_uncertainty_mv_per_ms2 in (None, 0) for p in points):
        weights = [1.0] * len(points)
    else:
        weights = [1.0 / (p.expanded_uncertainty_mv_per_ms2 / 2) ** 2 for p in points]  # type: ignore[operator]
    sw = sum(weights)
    t_mean = sum(w * t for w, t in zip(weights, years, strict=True)) / sw
    v_mean = sum(w * v for w, v in zip(weights, values, strict=True)) / sw
    sxx = sum(w * (t - t_mean) ** 2 for w, t in zip(weights, years, strict=True))
    if sxx == 0 or years[-1] - years[0] < MIN_DRIFT_SPAN_DAYS / DAYS_PER_YEAR:
        return None
    sxy = sum(
        w * (t - t_mean) * (v - v_mean) for w, t, v in zip(weights, years, values, strict=True)
    )
    return 100.0 * (sxy / sxx) / v_mean


def individuals_chart(serial: str, stand: str, points: Sequence[tuple[str, float]]) -> ControlChart:
    """Centre and 3-sigma limits from all points but the newest (sigma = mean moving range /
    d2); a warning when the newest falls outside them."""
    earlier = [value for _, value in points[:-1]]
    if len(earlier) < MIN_CONTROL_POINTS:
        return ControlChart(serial, stand, tuple(points), None, None, None, None)
    centre = sum(earlier) / len(earlier)
    moving = [abs(b - a) for a, b in itertools.pairwise(earlier)]
    sigma = sum(moving) / len(moving) / D2_MOVING_RANGE
    lower, upper = centre - 3 * sigma, centre + 3 * sigma
    run_id, newest = points[-1]
    warning = None
    if not lower <= newest <= upper:
        warning = (
            f"check standard {serial} on {stand}: run {run_id} gave {newest:.5g} mV/(m/s^2), "
            f"outside the control limits {lower:.5g} to {upper:.5g}: check the stand"
        )
    return ControlChart(serial, stand, tuple(points), centre, lower, upper, warning)
