"""What a lab does with its records: sensors, reference standards, runs, due dates, history and
the certificate register. Every write is checked first (a refusal names the field) and audited
(app.records.db.audit); every read verifies what it hands over.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import json
import math
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime, timedelta
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, event, or_, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, joinedload

from app.records.db import audit
from app.records.db.errors import RecordsInputError
from app.records.db.models import (
    Certificate,
    Customer,
    ReferencePoint,
    ReferenceStandard,
    RegisterCounter,
    Run,
    RunTemplate,
    Sensor,
    SensorModel,
    Setting,
    Stand,
)
from app.records.db.units import check_unit
from app.records.run_folder import MANIFEST_NAME, STATUS_COMPLETE, inspect_run, sha256_of
from app.records.run_record import RunRecord

DEFAULT_PATTERN = "ACC-{year}-{seq:04d}"
SETTING_PATTERN = "certificate_pattern"
SETTING_TWO_PERSON = "two_person_rule"
DAYS_PER_YEAR = 365.2425
MIN_DRIFT_SPAN_DAYS = 30
MIN_CONTROL_POINTS = 5  # earlier points before control limits mean anything
D2_MOVING_RANGE = 1.128  # d2 for moving ranges of two (ISO 7870-2, table 2)


class RecordsError(RecordsInputError):
    """A refused write or an unknown record; the message names the field and the reason."""


def _text(value: str | None, field: str, *, max_len: int = 200) -> str:
    text = (value or "").strip()
    if not text:
        raise RecordsError(f"{field}: must not be blank")
    if len(text) > max_len:
        raise RecordsError(f"{field}: longer than {max_len} characters")
    return text


def _number(value: float, field: str, *, low: float, high: float) -> float:
    if not (math.isfinite(value) and low < value <= high):
        raise RecordsError(f"{field}: must be in ({low:g}, {high:g}], got {value!r}")
    return float(value)


def add_months(day: date, months: int) -> date:
    """`day` plus whole calendar months (the last day of the month when it has fewer days)."""
    month_index = day.month - 1 + months
    year, month = day.year + month_index // 12, month_index % 12 + 1
    for last in (31, 30, 29, 28):
        with contextlib.suppress(ValueError):
            return date(year, month, min(day.day, last))
    raise AssertionError("unreachable")


@dataclass(frozen=True)
class DueItem:
    """A sensor or reference standard due for calibration by `due` (None: never calibrated)."""

    kind: str
    identifier: str
    due: date | None
    owner: str


@dataclass(frozen=True)
class HistoryPoint:
    """One complete run of a sensor: when, sensitivity and expanded U at the reference
    frequency, in mV/(m/s^2)."""

    run_id: str
    started_utc: datetime
    reference_frequency_hz: float
    sensitivity_mv_per_ms2: float
    expanded_uncertainty_mv_per_ms2: float | None


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


class Lab:
    """The records of one lab over one database engine."""

    def __init__(self, engine: Engine, *, actor: str | None = None) -> None:
        self.engine = engine
        self.actor = actor or audit.current_actor()

    @contextlib.contextmanager
    def session(self) -> Iterator[Session]:
        """A session whose flushes are audited; committed at the end, rolled back on error."""
        with Session(self.engine, expire_on_commit=False) as session:
            session.info["actor"] = self.actor
            event.listen(session, "before_flush", _keep_sensor_due_dates)
            audit.install(session)  # after: the trail sees the due dates it changed
            try:
                yield session
                session.commit()
            except IntegrityError as exc:
                session.rollback()
                raise RecordsError(_integrity_message(exc)) from None
            except BaseException:
                session.rollback()
                raise

    # ---- customers, models, sensors ------------------------------------------------------
    def add_customer(self, name: str, address: str = "") -> Customer:
        """A new customer; a duplicate name is refused."""
        name = _text(name, "customer")
        with self.session() as s:
            if s.scalar(select(Customer).where(Customer.name == name)):
                raise RecordsError(f"customer: {name!r} already exists")
            customer = Customer(name=name, address=address.strip())
            s.add(customer)
        return customer

    def add_model(
        self,
        maker: str,
        model: str,
        *,
        nominal_sensitivity: float,
        unit: str,
        tolerance_percent: float,
        frequency_min_hz: float,
        frequency_max_hz: float,
        preset: str = "piezo",
        level_ms2: float = 5.0,
        phase_tolerance_deg: float | None = None,
    ) -> SensorModel:
        """A new sensor model, every field checked and named when refused."""
        maker, model = _text(maker, "maker", max_len=100), _text(model, "model", max_len=100)
        try:
            check_unit(unit)
        except ValueError as exc:
            raise RecordsError(str(exc)) from None
        _number(nominal_sensitivity, "nominal sensitivity", low=0, high=1e6)
        _number(tolerance_percent, "tolerance", low=0, high=100)
        _number(frequency_min_hz, "frequency min", low=0, high=1e6)
        _number(frequency_max_hz, "frequency max", low=frequency_min_hz, high=1e6)
        _number(level_ms2, "level", low=0, high=1000)
        if phase_tolerance_deg is not None:
            _number(phase_tolerance_deg, "phase tolerance", low=0, high=180)
        row = SensorModel(
            maker=maker,
            model=model,
            nominal_sensitivity=float(nominal_sensitivity),
            unit=unit,
            tolerance_percent=float(tolerance_percent),
            frequency_min_hz=float(frequency_min_hz),
            frequency_max_hz=float(frequency_max_hz),
            preset=preset,
            level_ms2=float(level_ms2),
            phase_tolerance_deg=phase_tolerance_deg,
        )
        with self.session() as s:
            if s.scalar(
                select(SensorModel).where(SensorModel.maker == maker, SensorModel.model == model)
            ):
                raise RecordsError(f"model: {maker} {model} already exists")
            s.add(row)
        return row

    def add_sensor(
        self,
        serial: str,
        *,
        model: str,
        owner: str,
        interval_months: int = 12,
        teds_identity: str | None = None,
        check_standard: bool = False,
    ) -> Sensor:
        """A new sensor of a known model and customer; a duplicate serial is refused."""
        serial = _text(serial, "serial", max_len=100)
        if not 1 <= interval_months <= 120:
            raise RecordsError(f"interval: must be 1 to 120 months, got {interval_months}")
        with self.session() as s:
            if s.scalar(select(Sensor).where(Sensor.serial == serial)):
                raise RecordsError(f"serial: {serial!r} already exists")
            model_row = self._model(s, model)
            customer = s.scalar(select(Customer).where(Customer.name == owner.strip()))
            if customer is None:
                raise RecordsError(f"owner: no customer named {owner!r}")
            sensor = Sensor(
                serial=serial,
                model=model_row,
                owner=customer,
                interval_months=interval_months,
                teds_identity=teds_identity,
                check_standard=check_standard,
            )
            s.add(sensor)
        return sensor

    @staticmethod
    def _model(s: Session, text: str) -> SensorModel:
        """A model by 'maker model' or by model name alone when that is unambiguous."""
        text = text.strip()
        rows = s.scalars(select(SensorModel)).all()
        matches = [m for m in rows if f"{m.maker} {m.model}" == text] or [
            m for m in rows if m.model == text
        ]
        if len(matches) != 1:
            reason = "no such model" if not matches else "ambiguous, give maker and model"
            raise RecordsError(f"model: {text!r}: {reason}")
        return matches[0]

    def sensor(self, serial: str) -> Sensor:
        """The sensor with `serial`, its model and owner loaded; RecordsError when unknown."""
        with self.session() as s:
            row = s.scalar(
                select(Sensor)
                .options(joinedload(Sensor.model), joinedload(Sensor.owner))
                .where(Sensor.serial == serial.strip())
            )
            if row is None:
                raise RecordsError(f"serial: no sensor {serial!r} in the records")
            return row

    def sensor_by_teds(self, identity: str) -> Sensor:
        """The sensor whose TEDS identity ('manufacturer/model/version/serial') is `identity`."""
        with self.session() as s:
            row = s.scalar(select(Sensor).where(Sensor.teds_identity == identity.strip()))
            if row is None:
                raise RecordsError(
                    f"TEDS: no sensor with TEDS identity {identity!r} in the records "
                    "(register it: accelcal sensors add SERIAL ... --teds IDENTITY)"
                )
            return row

    def sensors(self, search: str = "") -> list[Sensor]:
        """Sensors whose serial contains `search`, by serial."""
        with self.session() as s:
            query = (
                select(Sensor)
                .options(joinedload(Sensor.model), joinedload(Sensor.owner))
                .order_by(Sensor.serial)
            )
            if search:
                query = query.where(Sensor.serial.contains(search.strip()))
            return list(s.scalars(query).all())

    def customers(self) -> list[Customer]:
        """Every customer, by name."""
        with self.session() as s:
            return list(s.scalars(select(Customer).order_by(Customer.name)).all())

    def models(self) -> list[SensorModel]:
        """Every sensor model, by maker and model."""
        with self.session() as s:
            query = select(SensorModel).order_by(SensorModel.maker, SensorModel.model)
            return list(s.scalars(query).all())

    # ---- run templates per sensor model ---------------------------------------------------
    def add_template(
        self,
        model: str,
        name: str,
        *,
        preset: str,
        level_ms2: float,
        periods: int,
        estimator: str,
        frequencies_hz: Sequence[float] | None = None,
        target_type_a: float | None = None,
        max_acquisition_s: float | None = None,
        tolerance_percent: float | None = None,
    ) -> RunTemplate:
        """Named run settings for sensor model `model` ('maker model' or model): preset and
        lines (Hz, None: the preset's), level (m/s^2 peak per line), periods, type A target
        (relative, e.g. 0.002), time bound (s), tolerance (%) and estimator. Every field is
        checked and named when refused; the lines are checked as a plan on the preset's rate."""
        from dsp.estimators import ESTIMATORS
        from dsp.multisine import PRESETS, check_lines
        from dsp.spectral import check_periods

        name = _text(name, "template name", max_len=100)
        if preset not in PRESETS:
            raise RecordsError(f"preset: {preset!r} is none of {', '.join(PRESETS)}")
        if estimator not in ESTIMATORS:
            raise RecordsError(f"estimator: {estimator!r} is none of {', '.join(ESTIMATORS)}")
        _number(level_ms2, "level", low=0, high=1000)
        try:
            check_periods(estimator, int(periods))
        except ValueError as exc:
            raise RecordsError(str(exc)) from None
        if target_type_a is not None:
            _number(target_type_a, "type A target", low=0, high=0.1)
        if max_acquisition_s is not None:
            _number(max_acquisition_s, "time bound", low=0, high=100_000)
        if tolerance_percent is not None:
            _number(tolerance_percent, "tolerance", low=0, high=100)
        lines = None
        if frequencies_hz is not None:
            values = [float(f) for f in frequencies_hz]
            if not values:
                raise RecordsError("frequencies: an empty line list (None: the preset's lines)")
            spec = PRESETS[preset]
            check = check_lines(
                values, spec.sample_rate_hz, spec.period_samples, spec.reference_frequency_hz
            )
            if check.errors:
                raise RecordsError(f"frequencies: {check.errors[0]}")
            lines = ",".join(f"{f:.10g}" for f in values)
        with self.session() as s:
            model_row = self._model(s, model)
            if s.scalar(
                select(RunTemplate).where(
                    RunTemplate.model_id == model_row.id, RunTemplate.name == name
                )
            ):
                raise RecordsError(
                    f"template name: {name!r} exists for {model_row.maker} {model_row.model}"
                )
            row = RunTemplate(
                model=model_row,
                name=name,
                preset=preset,
                frequencies_hz=lines,
                level_ms2=float(level_ms2),
                periods=int(periods),
                target_type_a=target_type_a,
                max_acquisition_s=max_acquisition_s,
                tolerance_percent=tolerance_percent,
                estimator=estimator,
            )
            s.add(row)
        return row

    def templates(self, model: str) -> list[RunTemplate]:
        """The run templates of sensor model `model` ('maker model' or model), by name."""
        with self.session() as s:
            model_row = self._model(s, model)
            query = (
                select(RunTemplate)
                .where(RunTemplate.model_id == model_row.id)
                .order_by(RunTemplate.name)
            )
            return list(s.scalars(query).all())

    # ---- reference standards -------------------------------------------------------------
    def add_reference(
        self,
        identifier: str,
        *,
        model: str,
        serial: str,
        certificate_number: str,
        calibration_date: date,
        due_date: date,
        table: Sequence[tuple[float, float, float, float | None]],
    ) -> ReferenceStandard:
        """A reference standard with its calibration table: rows of (frequency Hz,
        sensitivity mV/(m/s^2), relative expanded uncertainty, phase deg or None)."""
        identifier = _text(identifier, "reference id", max_len=100)
        if due_date <= calibration_date:
            raise RecordsError(
                f"due date: {due_date} is not after the calibration date {calibration_date}"
            )
        if not table:
            raise RecordsError("table: a reference standard needs its calibration table")
        points = []
        for row_number, (freq, sens, rel_u, phase) in enumerate(table, 1):
            where = f"table row {row_number}"
            _number(freq, f"{where} frequency", low=0, high=1e6)
            _number(sens, f"{where} sensitivity", low=0, high=1e6)
            _number(rel_u, f"{where} uncertainty", low=0, high=1)
            points.append(
                ReferencePoint(
                    frequency_hz=freq,
                    sensitivity_mv_per_ms2=sens,
                    relative_expanded_uncertainty=rel_u,
                    phase_deg=phase,
                )
            )
        row = ReferenceStandard(
            identifier=identifier,
            model=_text(model, "model", max_len=100),
            serial=_text(serial, "serial", max_len=100),
            certificate_number=_text(certificate_number, "certificate number", max_len=100),
            calibration_date=calibration_date,
            due_date=due_date,
            points=points,
        )
        with self.session() as s:
            if s.scalar(
                select(ReferenceStandard).where(ReferenceStandard.identifier == identifier)
            ):
                raise RecordsError(f"reference id: {identifier!r} already exists")
            s.add(row)
        return row

    def references(self) -> list[ReferenceStandard]:
        """Every reference standard with its table, by identifier."""
        with self.session() as s:
            query = (
                select(ReferenceStandard)
                .options(joinedload(ReferenceStandard.points))
                .order_by(ReferenceStandard.identifier)
            )
            return list(s.scalars(query).unique().all())

    def reference_for_run(
        self, identifier: str, *, today: date, override_reason: str | None = None
    ) -> ReferenceStandard:
        """The reference standard a run may use today: an expired one is refused naming its
        due date, unless an override reason is given (it then belongs on the certificate)."""
        with self.session() as s:
            ref = s.scalar(
                select(ReferenceStandard)
                .options(joinedload(ReferenceStandard.points))
                .where(ReferenceStandard.identifier == identifier)
            )
            if ref is None:
                raise RecordsError(f"reference: no reference standard {identifier!r}")
        if ref.due_date < today and not (override_reason and override_reason.strip()):
            raise RecordsError(
                f"reference: {identifier} was due for calibration on {ref.due_date}; "
                "recalibrate it, or give an override reason (it is printed on the certificate)"
            )
        return ref

    # ---- due list ------------------------------------------------------------------------
    def due(self, *, today: date, days: int) -> list[DueItem]:
        """Sensors and reference standards due on or before today + days, soonest first;
        sensors never calibrated here come first with no date."""
        horizon = today + timedelta(days=days)
        items: list[DueItem] = []
        with self.session() as s:
            rows = s.execute(
                select(Sensor.serial, Sensor.due_date, Customer.name)
                .join(Customer, Sensor.owner_id == Customer.id)
                .where(or_(Sensor.due_date.is_(None), Sensor.due_date <= horizon))
            ).all()
            items.extend(
                DueItem("sensor", serial, due_day, owner) for serial, due_day, owner in rows
            )
            for ref in s.scalars(
                select(ReferenceStandard).where(ReferenceStandard.due_date <= horizon)
            ):
                items.append(DueItem("reference", ref.identifier, ref.due_date, "lab"))
        return sorted(items, key=lambda i: (i.due is not None, i.due or today, i.identifier))

    # ---- runs ----------------------------------------------------------------------------
    def import_runs(self, root: Path) -> ImportReport:
        """Index every run folder under `root` (or `root` itself): verified folders only,
        by manifest hash; importing twice changes nothing."""
        folders = (
            [root]
            if (root / MANIFEST_NAME).exists()
            else sorted(p for p in root.iterdir() if p.is_dir())
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
        started = _utc(datetime.fromisoformat(record.started_utc))
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
        points = tuple(
            HistoryPoint(
                r.run_id,
                r.started_utc,
                float(r.reference_frequency_hz or 0.0),
                float(r.sensitivity_mv_per_ms2 or 0.0),
                r.expanded_uncertainty_mv_per_ms2,
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

    # ---- lab settings --------------------------------------------------------------------
    def set_setting(self, key: str, value: str) -> None:
        """Set a lab setting (certificate_pattern, two_person_rule), checked first."""
        if key == SETTING_PATTERN:
            check_pattern(value)
        elif key == SETTING_TWO_PERSON:
            if value not in ("on", "off"):
                raise RecordsError(f"{key}: must be 'on' or 'off', got {value!r}")
        else:
            raise RecordsError(f"setting: unknown key {key!r}")
        with self.session() as s:
            row = s.get(Setting, key)
            if row is None:
                s.add(Setting(key=key, value=value))
            else:
                row.value = value

    def setting(self, key: str, default: str) -> str:
        with self.session() as s:
            row = s.get(Setting, key)
            return default if row is None else row.value

    # ---- certificate register ------------------------------------------------------------
    def check_signatories(self, prepared_by: str, approved_by: str) -> tuple[str, str]:
        """Prepared by and approved by as the register takes them (stripped); RecordsError
        naming the field when one is blank or, under the lab's two-person rule, when both are
        the same person (case-insensitive)."""
        prepared_by = _text(prepared_by, "prepared by")
        approved_by = _text(approved_by, "approved by")
        if (
            self.setting(SETTING_TWO_PERSON, "off") == "on"
            and prepared_by.casefold() == approved_by.casefold()
        ):
            raise RecordsError(
                "approved by: the lab's two-person rule needs someone other than the preparer"
            )
        return prepared_by, approved_by

    def complete_runs(self, serial: str) -> list[Run]:
        """The indexed complete runs of sensor `serial`, newest first (what a certificate or
        its amendment may be issued for)."""
        sensor = self.sensor(serial)
        with self.session() as s:
            query = (
                select(Run)
                .where(Run.sensor_id == sensor.id, Run.status == STATUS_COMPLETE)
                .order_by(Run.started_utc.desc(), Run.id.desc())
            )
            return list(s.scalars(query).all())

    def issue_certificate(
        self,
        *,
        run_id: str,
        prepared_by: str,
        approved_by: str,
        when: datetime | None = None,
        replaces: str | None = None,
        reason: str | None = None,
        as_found_run_id: str | None = None,
        produce: Callable[[str], None] | None = None,
    ) -> Certificate:
        """Enter a certificate for a complete, indexed run of a known sensor in the register.
        Its number is the next in the lab's pattern, allocated in the same transaction (no gap,
        no duplicate, whichever stand issues at the same time). With `replaces` it is an
        amendment: the replaced certificate is marked replaced with the reason. With
        `as_found_run_id` the sensor was adjusted: that earlier complete run of the same sensor
        is the as-found result and the certified run the as-left one. `produce(number)`, when
        given, makes the certificate itself inside the transaction: if it fails, the number is
        not taken (no gap, no entry without its certificate)."""
        prepared_by, approved_by = self.check_signatories(prepared_by, approved_by)
        when = when or datetime.now(UTC)
        pattern = self.setting(SETTING_PATTERN, DEFAULT_PATTERN)
        with self.session() as s:
            run = s.scalar(select(Run).where(Run.run_id == run_id))
            if run is None:
                raise RecordsError(f"run: {run_id!r} is not indexed (accelcal db import)")
            if run.status != STATUS_COMPLETE:
                raise RecordsError(f"run: {run_id} is {run.status}, not complete")
            if run.sensor_id is None:
                raise RecordsError(f"run: {run_id}'s DUT {run.dut_id!r} is no sensor on record")
            as_found = None
            if as_found_run_id is not None:
                as_found = s.scalar(select(Run).where(Run.run_id == as_found_run_id))
                if as_found is None:
                    raise RecordsError(f"as found: run {as_found_run_id!r} is not indexed")
                if as_found.sensor_id != run.sensor_id or as_found.status != STATUS_COMPLETE:
                    raise RecordsError(
                        f"as found: run {as_found_run_id} is no complete run of {run.dut_id}"
                    )
                if _utc(as_found.started_utc) >= _utc(run.started_utc):
                    raise RecordsError(
                        f"as found: run {as_found_run_id} is not before the as-left run {run_id}"
                    )
            old = None
            if replaces is not None:
                old = s.scalar(
                    select(Certificate).where(Certificate.number == replaces).with_for_update()
                )
                if old is None:
                    raise RecordsError(f"replaces: no certificate {replaces!r}")
                if old.state != "issued":
                    raise RecordsError(f"replaces: {replaces} is already {old.state}")
                _text(reason, "reason")
                old.state = "replaced"
                old.reason = reason
            prefix = split_pattern(pattern, when.year)
            self._ensure_counter(s, prefix)
            counter = s.scalar(
                select(RegisterCounter).where(RegisterCounter.prefix == prefix).with_for_update()
            )
            assert counter is not None
            counter.last += 1
            number = pattern.format(year=when.year, seq=counter.last)
            certificate = Certificate(
                number=number,
                prefix=prefix,
                sequence=counter.last,
                run_id=run.id,
                sensor_id=run.sensor_id,
                state="issued",
                replaces=replaces,
                reason=reason if replaces else None,
                prepared_by=prepared_by,
                approved_by=approved_by,
                issued_utc=when,
                as_found_run=as_found,
            )
            s.add(certificate)
            if produce is not None:
                s.flush()  # the number is ours (unique) before anything is written
                produce(number)
        return certificate

    @staticmethod
    def _ensure_counter(s: Session, prefix: str) -> None:
        """Create the counter row of `prefix` at 0 unless it exists (race-free on both
        engines: INSERT ... ON CONFLICT DO NOTHING)."""
        if s.get_bind().dialect.name == "postgresql":
            from sqlalchemy.dialects.postgresql import insert
        else:
            from sqlalchemy.dialects.sqlite import insert  # type: ignore[assignment]
        s.execute(insert(RegisterCounter).values(prefix=prefix, last=0).on_conflict_do_nothing())

    def withdraw_certificate(self, number: str, reason: str) -> None:
        """Withdraw an issued certificate; the reason is required and kept."""
        reason = _text(reason, "reason")
        with self.session() as s:
            row = s.scalar(select(Certificate).where(Certificate.number == number))
            if row is None:
                raise RecordsError(f"number: no certificate {number!r}")
            if row.state != "issued":
                raise RecordsError(f"number: {number} is already {row.state}")
            row.state, row.reason = "withdrawn", reason

    def register(self) -> list[Certificate]:
        """Every certificate in the register, in issue order, with run and sensor."""
        with self.session() as s:
            return list(
                s.scalars(
                    select(Certificate)
                    .options(
                        joinedload(Certificate.run),
                        joinedload(Certificate.sensor).joinedload(Sensor.owner),
                        joinedload(Certificate.as_found_run),
                    )
                    .order_by(Certificate.issued_utc, Certificate.id)
                ).all()
            )


_PATTERN_SEQ = re.compile(r"\{seq:0?(\d+)d\}")


def check_pattern(pattern: str) -> str:
    """A certificate-number pattern: text with {year} optional and {seq:0Nd} once, at the end."""
    match = _PATTERN_SEQ.search(pattern)
    if pattern.count("{seq") != 1 or match is None:
        raise RecordsError(
            f"certificate_pattern: needs exactly one {{seq:04d}}-style field, got {pattern!r}"
        )
    if match.end() != len(pattern):
        raise RecordsError("certificate_pattern: {seq:...} must end the pattern")
    try:
        pattern.format(year=2026, seq=1)
    except (KeyError, ValueError, IndexError) as exc:
        raise RecordsError(f"certificate_pattern: {pattern!r} ({exc})") from None
    return pattern


def split_pattern(pattern: str, year: int) -> str:
    """The fixed prefix of a pattern for `year` (numbers sharing it share one sequence)."""
    match = _PATTERN_SEQ.search(check_pattern(pattern))
    assert match is not None
    return pattern[: match.start()].format(year=year)


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


def _keep_sensor_due_dates(session: Session, _context: Any, _instances: Any) -> None:
    """A new complete run of a sensor moves the sensor's last calibration and due date."""
    for obj in list(session.new):
        if not isinstance(obj, Run) or obj.status != STATUS_COMPLETE:
            continue
        sensor = obj.sensor
        if sensor is None and obj.sensor_id is not None:
            sensor = session.get(Sensor, obj.sensor_id)
        if sensor is None:
            continue
        started = _utc(obj.started_utc)
        last = sensor.last_calibrated_utc
        if last is None or _utc(last) < started:
            sensor.last_calibrated_utc = started
            sensor.due_date = add_months(started.date(), sensor.interval_months)


def _utc(moment: datetime) -> datetime:
    """`moment` as an aware UTC time (SQLite hands back naive UTC)."""
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)


def _integrity_message(exc: IntegrityError) -> str:
    text = str(exc.orig).splitlines()[0] if exc.orig is not None else str(exc)
    return f"refused by the database: {text}"
