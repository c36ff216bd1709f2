"""The run request and the one way the faces build it: the DUT resolved (records, TEDS, stand
file or simulated catalogue) into a DutSpec, the operator's choices over its defaults, the
reference standard resolved from the records (its table, certificate and due date; overrides
with a reason), the run's identity as stored in config.json. The CLI and the GUI both call
`build_request`.

Units in the names: levels in m/s^2 peak per line, sensitivities in mV/(m/s^2), masses in g.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import date
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.errors import Refusal
from app.io.vocabulary import Backend, Mode
from app.procedure.errors import PreflightError
from app.procedure.reference import (
    ReferenceRefusal,
    ResolvedReference,
    audit_overrides,
    open_records,
    reference_from_records,
    resolve_reference,
)
from app.records.run_record import DutIdentity, Override, technician_name
from app.stand.dut import DutSpec, Tolerances, spec_from_record, spec_from_stand, spec_from_teds
from app.stand.simulated import CATALOGUE, catalogue_spec
from dsp.estimators import Estimator, default_estimator
from dsp.multisine import PRESETS
from dsp.profiles import Profile
from dsp.spectral import MIN_PERIODS

if TYPE_CHECKING:
    from app.procedure.settings import RunSettings
    from app.records.db.references import ReferenceTable
    from app.records.db.runs import SensorDefaults
    from app.stand.config import StandConfig
    from app.stand.simulated import DrivenHum, Fault

DEFAULT_LEVEL_MS2 = 5.0

__all__ = [
    "DEFAULT_LEVEL_MS2",
    "DutChoice",
    "DutSpec",
    "ReferenceRefusal",
    "RequestError",
    "ResolvedReference",
    "RunIdentity",
    "RunRequest",
    "build_request",
    "check_request",
    "resolve_dut",
    "resolve_reference",
    "resolve_request",
    "spec_from_sensor",
]


class RequestError(Refusal):
    """The DUT or the run cannot be resolved as asked; the message names the option."""


@dataclass(frozen=True)
class RunIdentity:
    """Who and what the run is about: the DUT as the run knew it, the level (m/s^2), the
    measuring amplifier's read-back settings; stored as config.json's "identity"."""

    dut: DutIdentity | None = None
    level_ms2: float | None = None
    measuring_amplifier: Mapping[str, Any] | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)
    overrides: tuple[Override, ...] = ()  # checks gone past with a reason (results.json)
    technician: str | None = None  # who ran it (the certificate's "Prepared by"); None: unsaid

    def to_dict(self) -> dict[str, Any]:
        """The JSON object config.json has always held (keys absent when not known)."""
        out: dict[str, Any] = {}
        if self.dut is not None:
            out["dut"] = self.dut.to_dict()
        if self.level_ms2 is not None:
            out["level_ms2"] = self.level_ms2
        if self.measuring_amplifier is not None:
            out["measuring_amplifier"] = dict(self.measuring_amplifier)
        if self.overrides:
            out["overrides"] = [o.to_dict() for o in self.overrides]
        if self.technician:
            out["technician"] = self.technician
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> RunIdentity:
        from app.records.run_record import overrides_from

        data = dict(data or {})
        dut = DutIdentity.from_dict(data.pop("dut", None))
        level = data.pop("level_ms2", None)
        amplifier = data.pop("measuring_amplifier", None)
        overrides = overrides_from(data.pop("overrides", None))
        technician = technician_name(data.pop("technician", None))
        return cls(
            dut, None if level is None else float(level), amplifier, data, overrides, technician
        )


@dataclass(frozen=True)
class RunRequest:
    """What the operator asked for, resolved (units in the names): a plain value, it opens and
    reads nothing (the run service, app.procedure.service, loads the stand file and the
    records once and hands their values on). `dut_spec` is the DUT's specification (None: the
    simulated catalogue DUT `dut` on the simulated stand, else an unknown DUT)."""

    stand_file: Path | None = None
    dut: str = "piezo"
    dut_id: str | None = None
    preset: str | None = None
    frequencies_hz: tuple[float, ...] | None = None  # custom lines on the preset's fs/period
    level_ms2: float = DEFAULT_LEVEL_MS2
    periods: int = 8
    target_type_a: float | None = None
    max_acquisition_s: float | None = None  # None: with a target, the default bound
    # None: the mode's (dsp.estimators.default_estimator: lpm for a multisine, periodic for a
    # stepped sine), resolved when the request is made
    estimator: Estimator = None  # type: ignore[assignment]
    mode: Mode = Mode.MULTISINE
    stepped_block_s: float | None = None  # None: app.procedure.modes.DEFAULT_STEPPED_BLOCK_S
    tolerance_percent: float | None = None
    nominal_mv_per_ms2: float | None = None
    seed: int = 0
    paced: bool = False
    faults: tuple[Fault, ...] = ()
    sim_hum: tuple[DrivenHum, ...] = ()  # simulated stand: hum only while driven
    # simulated stand: draw its deviations from its stand file's [simulation] map (False: at
    # its nominal values, for a benchmark that puts a truth of its own on the recording)
    sim_systematic: bool = True
    exact_mains_bins: bool = False  # keep lines on mains harmonics (default: moved one bin)
    out: Path = Path("runs")
    dut_mass_g: float | None = None  # None: the DUT spec's, on the simulated stand its catalogue's
    stored_response: bool = True  # start equalisation from the stand's stored response
    response_store: Path | None = None  # where stored responses live (None: user data dir)
    dut_spec: DutSpec | None = None
    # the multisine's phases (rad), optimised already for these lines (the GUI does it as the
    # lines are typed); None: from the phase store when the plan is made
    # (app.procedure.phase_store: a new custom plan is optimised once, about 1 s)
    phases_rad: tuple[float, ...] | None = None
    # issue 26: the plan beyond presets (None: the preset's) and the simulated exciter
    sample_rate_hz: float | None = None
    period_samples: int | None = None
    reference_frequency_hz: float | None = None
    profile: Profile = Profile.ACCELERATION
    corner_hz: float | None = None
    exciter: str | None = None  # simulated stand: a name of its exciter catalogue
    fade_in_s: float | None = None  # lpm: the fade-in before the record (None: fade_in_for)
    resonance: bool = False  # search the mounted resonance in the response (dsp.resonance)
    records_chain_head: str | None = None  # hex: the records' chain head, named by the seal
    # the reference standard as on record (None: the stand file's, or the simulated stand's)
    reference: ReferenceTable | None = None
    overrides: tuple[Override, ...] = ()  # checks gone past with a stated reason
    technician: str | None = None  # who runs it (run --technician, the GUI's Technician)

    def __post_init__(self) -> None:
        if self.estimator is None:  # the mode's, as RunOptions resolves it for the faces
            object.__setattr__(self, "estimator", default_estimator(str(self.mode)))

    def spec(self, backend: Backend) -> DutSpec:
        """The DUT's specification on a stand of `backend`, with what the request states
        (serial, nominal, tolerance, mass) over it."""
        base = self.dut_spec
        if base is None:
            base = catalogue_spec(self.dut) if backend == Backend.SIM else DutSpec()
        return base.with_options(
            serial=self.dut_id,
            nominal_mv_per_ms2=self.nominal_mv_per_ms2,
            tolerance_percent=self.tolerance_percent,
            mass_g=self.dut_mass_g,
        )

    def tolerances(self, backend: Backend, reference_frequency_hz: float) -> Tolerances:
        """What the verdict checks, from the DUT's specification (see `spec`)."""
        return self.spec(backend).tolerances(reference_frequency_hz)

    def mass_g(self, backend: Backend) -> float | None:
        """The DUT mass the run states (g): given, else the DUT spec's, else (simulated stand)
        the catalogue DUT's; on real hardware without one, not stated."""
        mass = self.spec(backend).mass_g
        if mass is None and backend == Backend.SIM:
            return catalogue_spec(self.dut).mass_g
        return mass

    def identity(self, backend: Backend) -> RunIdentity:
        """The run's identity as config.json and the run record store it."""
        return RunIdentity(
            DutIdentity(
                self.dut if backend == Backend.SIM else None, self.dut_id, self.nominal_mv_per_ms2
            ),
            self.level_ms2,
            overrides=self.overrides,
            technician=technician_name(self.technician),
        )

    @property
    def custom_plan(self) -> bool:
        """True when the plan is more than a preset at one level (then the stroke clips it)."""
        return (
            self.exciter is not None
            or self.profile != Profile.ACCELERATION
            or any(
                v is not None
                for v in (
                    self.frequencies_hz,
                    self.sample_rate_hz,
                    self.period_samples,
                    self.reference_frequency_hz,
                )
            )
        )

    def time_bound_s(self, period_s: float) -> float | None:
        """The bound on the acquisition (s) of this run on a plan of `period_s` (s): as given,
        else with a type A target the default (app.procedure.stopping.default_time_bound_s),
        else none (the periods bound it)."""
        if self.max_acquisition_s is not None or self.target_type_a is None:
            return self.max_acquisition_s
        from app.procedure.stopping import default_time_bound_s

        return default_time_bound_s(period_s)

    def settings(self, backend: Backend, period_s: float | None = None) -> RunSettings:
        """How to run on a stand of `backend` (it decides the DUT mass) on a plan of
        `period_s` (s; the default time bound of a run with a target needs it: None, none)."""
        from app.procedure.modes import DEFAULT_STEPPED_BLOCK_S
        from app.procedure.settings import RunSettings

        bound = self.max_acquisition_s if period_s is None else self.time_bound_s(period_s)
        return RunSettings(
            dut_mass_g=self.mass_g(backend),
            periods=self.periods,
            target_type_a=self.target_type_a,
            max_acquisition_s=bound,
            max_acquisition_default=bound is not None and self.max_acquisition_s is None,
            estimator=self.estimator,
            mode=self.mode,
            stepped_block_s=(
                DEFAULT_STEPPED_BLOCK_S if self.stepped_block_s is None else self.stepped_block_s
            ),
            tolerance_percent=self.tolerance_percent,
            dut_nominal_mv_per_ms2=self.nominal_mv_per_ms2,
            fade_in_s=self.fade_in_s,
            resonance=self.resonance,
        )


def check_request(request: RunRequest) -> None:
    """Refuse (PreflightError, naming the field) what must never reach a stand: a DUT not in the
    simulated stand's catalogue, a nominal DUT sensitivity that is not a finite positive
    number, a level or period count out of range."""
    if request.dut not in CATALOGUE:
        raise PreflightError(
            f"dut: {request.dut!r} is not in the DUT catalogue ({', '.join(CATALOGUE)})"
        )
    nominal = request.nominal_mv_per_ms2
    if nominal is not None and not (math.isfinite(nominal) and nominal > 0):
        raise PreflightError(f"nominal sensitivity: must be > 0 mV/(m/s^2), got {nominal:g}")
    if not (math.isfinite(request.level_ms2) and request.level_ms2 > 0):
        raise PreflightError(f"level: must be > 0 m/s^2, got {request.level_ms2:g}")
    need = MIN_PERIODS.get(request.estimator, 2)
    if request.periods < min(need, 2):  # lpm: one record of one period; the others: 2
        raise PreflightError(f"periods: at least {min(need, 2)}, got {request.periods}")
    mass = request.dut_mass_g
    if mass is not None and not (math.isfinite(mass) and 0 <= mass <= 100_000):
        raise PreflightError(f"DUT mass: must be between 0 and 100000 g, got {mass:g}")


@dataclass(frozen=True)
class DutChoice:
    """How the operator named the DUT and its settings (None: not given). `dut` is the
    simulated stand's catalogue DUT; `sensor` a serial in the records; `teds`: read the DUT's
    TEDS; `records`: the records are in use (a sensor, a URL or $ACCELCAL_DB)."""

    stand_file: Path | None = None
    dut: str = "piezo"
    dut_id: str | None = None
    sensor: str | None = None
    db: str | None = None
    records: bool = False
    teds: bool = False
    seed: int = 0
    nominal_mv_per_ms2: float | None = None
    tolerance_percent: float | None = None
    level_ms2: float | None = None
    preset: str | None = None
    dut_mass_g: float | None = None
    reference_override: str | None = None  # the reason to go past the reference check
    spec: DutSpec | None = None  # resolved already by the face (the GUI's records link)
    lab: Any = None  # records already open (the GUI's app.records.db.lab.Lab); else from db
    operator: str | None = None  # who overrides (None: the operating-system user)
    today: date | None = None  # the date the reference's due date is checked on (None: UTC's)


@dataclass(frozen=True)
class ResolvedDut:
    """The DUT a choice names: its specification, the settings it leads to, notes to show."""

    spec: DutSpec
    dut_id: str | None
    nominal_mv_per_ms2: float | None
    tolerance_percent: float | None
    level_ms2: float
    preset: str | None
    notes: tuple[str, ...] = ()


def _from_teds(choice: DutChoice, notes: list[str]) -> tuple[DutSpec | None, str | None]:
    """The DUT's TEDS read on the stand: with the records, the serial of the sensor of that
    identity (for `sensor`); without, a spec from the TEDS itself."""
    from app.stand import teds as teds_io
    from hardware.teds import TedsError, decode

    try:
        teds = decode(teds_io.open_port(choice.stand_file, choice.dut, choice.seed).read())
    except TedsError as exc:
        raise RequestError(f"--teds: {exc}") from None
    identity = teds.basic.identity
    notes.append(f"TEDS identity {identity}")
    if choice.records:
        from app.records.db.engine import open_engine
        from app.records.db.lab import Lab

        sensor = Lab(open_engine(choice.db)).sensor_by_teds(identity)
        if choice.sensor and choice.sensor != sensor.serial:
            raise RequestError(
                f"--sensor: {choice.sensor!r} is not the TEDS sensor {sensor.serial!r}"
            )
        return None, sensor.serial
    nominal = teds.accelerometer.sensitivity_mv_per_ms2 if teds.accelerometer else None
    return spec_from_teds(identity, nominal, choice.dut_id), choice.sensor


def _from_records(serial: str, db: str | None) -> DutSpec:
    """The sensor `serial`'s specification from the records (RecordsInputError naming
    --sensor when unknown or not reachable)."""
    from app.records.db.runs import sensor_defaults

    return spec_from_sensor(sensor_defaults(serial, db))


def spec_from_sensor(sensor: SensorDefaults) -> DutSpec:
    """The DutSpec of a sensor on record (app.records.db.runs.defaults_of a Sensor)."""
    return spec_from_record(
        serial=sensor.serial,
        manufacturer=sensor.maker,
        model=sensor.model,
        description=sensor.description,
        nominal_mv_per_ms2=sensor.nominal_mv_per_ms2,
        tolerance_percent=sensor.tolerance_percent,
        frequency_min_hz=sensor.frequency_min_hz,
        frequency_max_hz=sensor.frequency_max_hz,
        phase_tolerance_deg=sensor.phase_tolerance_deg,
        preset=sensor.preset if sensor.preset in PRESETS else None,
        level_ms2=sensor.level_ms2,
    )


def resolve_dut(choice: DutChoice, backend: Backend, certificate: Mapping[str, Any]) -> ResolvedDut:
    """The DUT `choice` names on a stand of `backend` whose stand file's [certificate] table is
    `certificate`: from the records (a sensor, or the TEDS identity on record), else the TEDS,
    else the simulated catalogue (simulated stand) or the stand file; what the operator gave
    wins over what the source says (RequestError when the serials disagree)."""
    notes: list[str] = []
    spec: DutSpec | None = choice.spec
    sensor_serial = None if spec is not None else choice.sensor
    if choice.teds and spec is None:
        spec, sensor_serial = _from_teds(choice, notes)
    known = spec is not None  # the DUT itself told (TEDS) or is on record
    if sensor_serial:
        known = True
        spec = _from_records(sensor_serial, choice.db)
        if choice.dut_id is not None and choice.dut_id != spec.serial:
            raise RequestError(f"--dut-id: {choice.dut_id!r} differs from --sensor {spec.serial!r}")
        notes.append(f"sensor {spec.serial}: {spec.description}")
    if spec is None:
        spec = (
            catalogue_spec(choice.dut) if backend == Backend.SIM else spec_from_stand(certificate)
        )
    nominal = choice.nominal_mv_per_ms2 or (spec.nominal_mv_per_ms2 if known else None)
    tolerance = choice.tolerance_percent
    if tolerance is None and known:
        tolerance = spec.tolerance_percent
    level = choice.level_ms2 if choice.level_ms2 is not None else spec.level_ms2
    return ResolvedDut(
        spec=spec,
        dut_id=(choice.dut_id or spec.serial) if known else choice.dut_id,
        nominal_mv_per_ms2=nominal,
        tolerance_percent=tolerance,
        level_ms2=DEFAULT_LEVEL_MS2 if level is None else level,
        preset=choice.preset or (spec.preset if known else None),
        notes=tuple(notes),
    )


def build_request(
    choice: DutChoice, *, config: StandConfig | None = None, **run: Any
) -> tuple[RunRequest, tuple[str, ...]]:
    """`resolve_request` of `choice` on the stand file it names (loaded here unless `config`
    is given) and the run's other settings `run` (RunRequest's fields). The run service
    (app.procedure.service) calls `resolve_request` itself with typed values."""
    from app.stand import config as stand_config

    if config is None:
        config = stand_config.load(choice.stand_file)
    return resolve_request(choice, config, RunRequest(**run))


def resolve_request(
    choice: DutChoice, config: StandConfig, run: RunRequest
) -> tuple[RunRequest, tuple[str, ...]]:
    """The run request of `choice` on the stand of `config` (loaded once by the caller) with
    the run's other settings from `run` (periods, estimator, mode, out, faults...), and notes
    for the operator. Refuses (a Refusal) a DUT that cannot be resolved; with the records in
    use, a reference standard not on record or past its due date without an override reason,
    or one whose stand-file table differs from the records'. An override granted is in the
    request (for results.json) and in the records' audit trail."""
    from app.records.db.actor import current_actor

    resolved = resolve_dut(choice, config.backend, config.raw.get("certificate") or {})
    notes = list(resolved.notes)
    reference, lab = ResolvedReference(), None
    if choice.records or choice.lab is not None:
        lab, unreachable = open_records(choice.lab, choice.db)
        if lab is None:  # the run still records to its folder; `db import` indexes it later
            notes.append(f"records not reachable, reference due date not checked: {unreachable}")
        else:
            reference = reference_from_records(
                config,
                lab,
                override_reason=choice.reference_override,
                who=choice.operator or current_actor(),
                today=choice.today,
            )
            notes += reference.notes
    request = dataclasses.replace(
        run,
        stand_file=choice.stand_file,
        dut=choice.dut,
        dut_id=resolved.dut_id,
        preset=resolved.preset,
        level_ms2=resolved.level_ms2,
        tolerance_percent=resolved.tolerance_percent,
        nominal_mv_per_ms2=resolved.nominal_mv_per_ms2,
        seed=choice.seed,
        dut_mass_g=choice.dut_mass_g,
        dut_spec=resolved.spec,
        reference=reference.table,
        overrides=reference.overrides,
    )
    if lab is not None and reference.overrides:
        audit_overrides(lab, config, reference.overrides)
    return request, tuple(notes)
