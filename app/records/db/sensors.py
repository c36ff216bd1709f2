"""The lab's customers, sensor models (nominal sensitivity in its unit, tolerance in %, range
in Hz, level in m/s^2), sensors (serial, owner, calibration interval in months, TEDS identity)
and the run templates of each model. Every write is checked first and names the field.
"""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session, joinedload

from app.records.db.models import Customer, RunTemplate, Sensor, SensorModel
from app.records.db.store import RecordsError, Store, number_field, text_field
from app.records.db.units import check_unit


def find_model(s: Session, text: str) -> SensorModel:
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


def _set_model_fields(
    row: SensorModel,
    *,
    maker: str,
    model: str,
    nominal_sensitivity: float,
    unit: str,
    tolerance_percent: float,
    frequency_min_hz: float,
    frequency_max_hz: float,
    preset: str,
    level_ms2: float,
    phase_tolerance_deg: float | None,
) -> None:
    """Check every field of a sensor model (a refusal names the field), then set them on `row`:
    nominal sensitivity in `unit`, tolerance in %, range in Hz, level in m/s^2 peak, phase
    tolerance in degrees (None: not assessed)."""
    maker, model = (
        text_field(maker, "maker", max_len=100),
        text_field(model, "model", max_len=100),
    )
    try:
        check_unit(unit)
    except ValueError as exc:
        raise RecordsError(str(exc)) from None
    number_field(nominal_sensitivity, "nominal sensitivity", low=0, high=1e6)
    number_field(tolerance_percent, "tolerance", low=0, high=100)
    number_field(frequency_min_hz, "frequency min", low=0, high=1e6)
    number_field(frequency_max_hz, "frequency max", low=frequency_min_hz, high=1e6)
    number_field(level_ms2, "level", low=0, high=1000)
    if phase_tolerance_deg is not None:
        number_field(phase_tolerance_deg, "phase tolerance", low=0, high=180)
    row.maker, row.model, row.unit, row.preset = maker, model, unit, preset
    row.nominal_sensitivity = float(nominal_sensitivity)
    row.tolerance_percent = float(tolerance_percent)
    row.frequency_min_hz = float(frequency_min_hz)
    row.frequency_max_hz = float(frequency_max_hz)
    row.level_ms2 = float(level_ms2)
    row.phase_tolerance_deg = phase_tolerance_deg


class SensorRecords(Store):
    """Customers, models, sensors and run templates."""

    # ---- customers, models, sensors ------------------------------------------------------
    def add_customer(self, name: str, address: str = "") -> Customer:
        """A new customer; a duplicate name is refused."""
        name = text_field(name, "customer")
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
        row = SensorModel()
        _set_model_fields(
            row,
            maker=maker,
            model=model,
            nominal_sensitivity=nominal_sensitivity,
            unit=unit,
            tolerance_percent=tolerance_percent,
            frequency_min_hz=frequency_min_hz,
            frequency_max_hz=frequency_max_hz,
            preset=preset,
            level_ms2=level_ms2,
            phase_tolerance_deg=phase_tolerance_deg,
        )
        maker, model = row.maker, row.model
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
        serial = text_field(serial, "serial", max_len=100)
        if not 1 <= interval_months <= 120:
            raise RecordsError(f"interval: must be 1 to 120 months, got {interval_months}")
        with self.session() as s:
            if s.scalar(select(Sensor).where(Sensor.serial == serial)):
                raise RecordsError(f"serial: {serial!r} already exists")
            model_row = find_model(s, model)
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

    def update_customer(self, name: str, *, new_name: str, address: str) -> Customer:
        """Rename customer `name` and/or change its address (audited); an unknown customer or a
        new name another customer has is refused."""
        new_name = text_field(new_name, "customer")
        with self.session() as s:
            row = s.scalar(select(Customer).where(Customer.name == name.strip()))
            if row is None:
                raise RecordsError(f"customer: no customer named {name!r}")
            if new_name != row.name and s.scalar(select(Customer).where(Customer.name == new_name)):
                raise RecordsError(f"customer: {new_name!r} already exists")
            row.name, row.address = new_name, address.strip()
        return row

    def move_sensor(self, serial: str, *, owner: str) -> Sensor:
        """Give sensor `serial` to customer `owner` (sold, or moved in the records; audited and
        chained). Its certificates stay the customer's they were issued to (Certificate.
        customer_id); its due date is the new owner's. Unknown sensor or customer: refused."""
        with self.session() as s:
            sensor = s.scalar(select(Sensor).where(Sensor.serial == serial.strip()))
            if sensor is None:
                raise RecordsError(f"serial: no sensor {serial!r}")
            customer = s.scalar(select(Customer).where(Customer.name == owner.strip()))
            if customer is None:
                raise RecordsError(f"owner: no customer named {owner!r}")
            sensor.owner = customer
        return sensor

    def update_model(
        self,
        name: str,
        *,
        maker: str,
        model: str,
        nominal_sensitivity: float,
        unit: str,
        tolerance_percent: float,
        frequency_min_hz: float,
        frequency_max_hz: float,
        preset: str = "piezo",
        level_ms2: float = 5.0,
        phase_tolerance_deg: float | None = None,
    ) -> SensorModel:
        """Change every field of the model `name` ('maker model'), checked as `add_model` checks
        them (audited); a maker and model another model has are refused."""
        with self.session() as s:
            row = find_model(s, name)
            _set_model_fields(
                row,
                maker=maker,
                model=model,
                nominal_sensitivity=nominal_sensitivity,
                unit=unit,
                tolerance_percent=tolerance_percent,
                frequency_min_hz=frequency_min_hz,
                frequency_max_hz=frequency_max_hz,
                preset=preset,
                level_ms2=level_ms2,
                phase_tolerance_deg=phase_tolerance_deg,
            )
            with s.no_autoflush:
                other = s.scalar(
                    select(SensorModel).where(
                        SensorModel.maker == row.maker,
                        SensorModel.model == row.model,
                        SensorModel.id != row.id,
                    )
                )
            if other is not None:
                raise RecordsError(f"model: {row.maker} {row.model} already exists")
        return row

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

        name = text_field(name, "template name", max_len=100)
        if preset not in PRESETS:
            raise RecordsError(f"preset: {preset!r} is none of {', '.join(PRESETS)}")
        if estimator not in ESTIMATORS:
            raise RecordsError(f"estimator: {estimator!r} is none of {', '.join(ESTIMATORS)}")
        number_field(level_ms2, "level", low=0, high=1000)
        try:
            check_periods(estimator, int(periods))
        except ValueError as exc:
            raise RecordsError(str(exc)) from None
        if target_type_a is not None:
            number_field(target_type_a, "type A target", low=0, high=0.1)
        if max_acquisition_s is not None:
            number_field(max_acquisition_s, "time bound", low=0, high=100_000)
        if tolerance_percent is not None:
            number_field(tolerance_percent, "tolerance", low=0, high=100)
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
            model_row = find_model(s, model)
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
            model_row = find_model(s, model)
            query = (
                select(RunTemplate)
                .where(RunTemplate.model_id == model_row.id)
                .order_by(RunTemplate.name)
            )
            return list(s.scalars(query).all())
