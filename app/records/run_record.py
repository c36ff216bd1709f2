"""The run record (results.json), typed: the one module that writes and reads it.

Frozen dataclasses, no new dependency: the record is a plain, flat document whose fields the
code reads by attribute (a typo is an AttributeError, not a silent None), `to_dict`/`from_dict`
say exactly what goes into the file, and `schema_version` tells readers which layout they
hold. Nested payloads owned by other modules stay in their own JSON forms (`plan`:
dsp.multisine.Plan.to_dict, `budget`: dsp.uncertainty.Budget.to_list, `reference_chain`,
`results`: dsp.calibration.Results.to_dict); `results_object()` rebuilds the results.

Versions: a results.json without `schema_version` was written before it existed (issue 14)
and has the layout of version 1; version 1 is today's. A newer version is refused by name.
`overrides` (issue 24) is an optional key of version 1: written only when a check was
overridden, read as none when absent, kept as read by older readers (their `extra`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import TYPE_CHECKING, Any

from app.errors import Refusal
from app.io.vocabulary import Mode, RunStatus
from dsp.estimators import Estimator, UncertaintyRule

if TYPE_CHECKING:
    from dsp.calibration import Results

SCHEMA_VERSION = 1
UNVERSIONED = 1  # results.json written before `schema_version`: the same layout as version 1


class RunRecordError(Refusal):
    """A results.json that cannot be read as a run record; the message says why."""


class UnsupportedSchemaError(RunRecordError):
    """A results.json of a schema version this accelcal does not know (a newer one)."""


@dataclass(frozen=True)
class DutIdentity:
    """The device under test as the run knew it."""

    catalogue: str | None = None  # the simulated stand's catalogue DUT; None on real hardware
    id: str | None = None  # serial / id given by the operator
    nominal_sensitivity_mv_per_ms2: float | None = None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> DutIdentity | None:
        if data is None:
            return None
        return cls(
            data.get("catalogue"), data.get("id"), data.get("nominal_sensitivity_mv_per_ms2")
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "catalogue": self.catalogue,
            "id": self.id,
            "nominal_sensitivity_mv_per_ms2": self.nominal_sensitivity_mv_per_ms2,
        }


class OverrideKind(StrEnum):
    """The checks a run may go past with a stated reason (stored as these strings)."""

    EXPIRED_REFERENCE = "expired reference"  # the reference standard is past its due date
    UNRECORDED_REFERENCE = "unrecorded reference"  # the reference standard is not on record


@dataclass(frozen=True)
class Override:
    """A check the run went past: its `kind` (an OverrideKind; any text as read, so a kind
    added later still reads), `who` allowed it, `why`, `when_utc` (ISO 8601) and `what` was
    overridden (the refusal it replaced)."""

    kind: str
    who: str
    why: str
    when_utc: str
    what: str

    def __post_init__(self) -> None:
        for name in ("kind", "who", "why", "when_utc", "what"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value.strip():
                raise RunRecordError(f"override {name}: must be a non-empty text, got {value!r}")

    def to_dict(self) -> dict[str, str]:
        return {
            "kind": self.kind,
            "who": self.who,
            "why": self.why,
            "when_utc": self.when_utc,
            "what": self.what,
        }

    @classmethod
    def from_dict(cls, data: Any) -> Override:
        """An override from its JSON object; RunRecordError naming what is missing."""
        if not isinstance(data, dict):
            raise RunRecordError(f"results.json: an override is not an object: {data!r}")
        try:
            return cls(*(str(data[k]) for k in ("kind", "who", "why", "when_utc", "what")))
        except KeyError as exc:
            raise RunRecordError(f"results.json: an override has no {exc.args[0]!r}") from None

    def line(self) -> str:
        """One line for a certificate or a log: what, why, who, when."""
        return f"{self.kind}: {self.what}; reason: {self.why} (by {self.who}, {self.when_utc})"


def overrides_from(data: Any) -> tuple[Override, ...]:
    """The overrides of a JSON list (None: none); RunRecordError when malformed."""
    if data is None:
        return ()
    if not isinstance(data, list):
        raise RunRecordError(f"results.json: overrides is not a list: {data!r}")
    return tuple(Override.from_dict(item) for item in data)


@dataclass(frozen=True)
class StandInfo:
    """The stand a run used: description, stand-file source, laboratory, reference."""

    description: str = ""
    source: str | None = None
    laboratory: Mapping[str, Any] = field(default_factory=dict)
    reference: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> StandInfo:
        data = data or {}
        return cls(
            str(data.get("description") or ""),
            data.get("source"),
            dict(data.get("laboratory") or {}),
            dict(data.get("reference") or {}),
        )

    @property
    def verify_url(self) -> str | None:
        """The laboratory's public verification URL ([laboratory] verify_url), None unset."""
        url = self.laboratory.get("verify_url")
        return str(url) if url else None

    def to_dict(self) -> dict[str, Any]:
        return {
            "description": self.description,
            "source": self.source,
            "laboratory": dict(self.laboratory),
            "reference": dict(self.reference),
        }


@dataclass(frozen=True)
class AnalysisSettings:
    """How a run's results were analysed, as results.json's "settings" holds it (the
    defaults where a run from before a setting existed does not state it)."""

    estimator: Estimator = Estimator.PERIODIC
    probability: float = 0.9545
    rule: UncertaintyRule = UncertaintyRule.GUM
    tolerance_percent: float | None = None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> AnalysisSettings:
        try:
            tolerance = data.get("tolerance_percent")
            return cls(
                Estimator(str(data.get("estimator") or Estimator.PERIODIC)),
                float(data.get("probability") or 0.9545),
                UncertaintyRule(str(data.get("rule") or UncertaintyRule.GUM)),
                float(tolerance) if tolerance else None,
            )
        except (TypeError, ValueError) as exc:
            raise RunRecordError(f"results.json: settings: {exc}") from None


@dataclass(frozen=True)
class ReferenceResult:
    """The result at the reference frequency as results.json holds it: frequency (Hz),
    sensitivity and its expanded uncertainty (mV/(m/s^2))."""

    frequency_hz: float | None
    sensitivity_mv_per_ms2: float | None
    expanded_uncertainty_mv_per_ms2: float | None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ReferenceResult:
        def number(key: str) -> float | None:
            value = data.get(key)
            return None if value is None else float(value)

        try:
            return cls(
                number("frequency_hz"),
                number("sensitivity_mv_per_ms2"),
                number("expanded_uncertainty_mv_per_ms2"),
            )
        except (TypeError, ValueError) as exc:
            raise RunRecordError(f"results.json: results.reference: {exc}") from None


@dataclass(frozen=True)
class StoredPlan:
    """The plan a run stored (results.json "plan"), as the certificate states it: nominal
    line frequencies (Hz), sample rate (Hz) and period (samples); 0 where not stored."""

    frequencies_hz: tuple[float, ...] = ()
    sample_rate_hz: float = 0.0
    period_samples: int = 0

    @property
    def period_s(self) -> float:
        return self.period_samples / self.sample_rate_hz if self.sample_rate_hz else 0.0

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> StoredPlan:
        try:
            lines = data.get("lines") or ()
            return cls(
                tuple(float(line["nominal_frequency_hz"]) for line in lines),
                float(data.get("sample_rate_hz") or 0.0),
                int(data.get("period_samples") or 0),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise RunRecordError(f"results.json: plan: {exc}") from None


# keys written only when they have a value (as before schema_version existed)
_OPTIONAL = (
    "dut",
    "level_ms2",
    "measuring_amplifier",
    "stand_response",
    "verdict",
    "raw_data_sha256",
)


@dataclass(frozen=True)
class RunRecord:
    """What results.json holds about one run (units in the names)."""

    run_id: str | None
    status: str  # a RunStatus (complete or aborted) as written; any text as read
    abort_reason: str | None = None
    mode: str = Mode.MULTISINE  # a Mode
    started_utc: str = ""
    finished_utc: str = ""
    excitation_time_s: float = 0.0
    periods_read: int = 0
    final_output_v: float | None = None
    equalisation_worst: tuple[float, ...] = ()
    background_v: Mapping[str, list[float]] = field(default_factory=dict)
    budget: tuple[Mapping[str, Any], ...] = ()
    reference_chain: Mapping[str, Any] = field(default_factory=dict)
    software_version: str = ""
    settings: Mapping[str, Any] = field(default_factory=dict)
    plan: Mapping[str, Any] = field(default_factory=dict)
    stand: StandInfo = field(default_factory=StandInfo)
    dut: DutIdentity | None = None
    level_ms2: float | None = None
    measuring_amplifier: Mapping[str, Any] | None = None
    # where equalisation started: "stored" (with the entry's date, run and stand hash),
    # "identified", or "stored, disagreed: identified" (with its check error)
    stand_response: Mapping[str, Any] | None = None
    verdict: str | None = None
    verdict_reasons: tuple[str, ...] = ()
    raw_data_sha256: str | None = None
    results: Mapping[str, Any] | None = None  # dsp.calibration.Results.to_dict(); None: none
    overrides: tuple[Override, ...] = ()  # checks gone past with a stated reason
    technician: str | None = None  # who ran it (run --technician; the certificate's preparer)
    extra: Mapping[str, Any] = field(default_factory=dict)  # keys of no field, kept as read
    schema_version: int = SCHEMA_VERSION

    # --- derived -------------------------------------------------------------------------

    @property
    def complete(self) -> bool:
        return self.status == RunStatus.COMPLETE

    @property
    def analysis(self) -> AnalysisSettings:
        """The analysis settings the run stored (typed: estimator, probability, rule)."""
        return AnalysisSettings.from_dict(self.settings)

    @property
    def stored_plan(self) -> StoredPlan:
        """The plan the run stored (typed: lines, rate, period)."""
        return StoredPlan.from_dict(self.plan)

    @property
    def reference_result(self) -> ReferenceResult | None:
        """The stored result at the reference frequency; None without results."""
        reference = (self.results or {}).get("reference")
        return ReferenceResult.from_dict(reference) if isinstance(reference, Mapping) else None

    @property
    def stated_verdict(self) -> tuple[str | None, tuple[str, ...]]:
        """The verdict and its reasons as stored (the record's own, else its results'), None
        when the run states none."""
        return verdict_stated(
            {
                "verdict": self.verdict,
                "verdict_reasons": list(self.verdict_reasons),
                "results": self.results,
            }
        )

    def results_object(self) -> Results | None:
        """The stored results rebuilt (dsp.calibration.Results), or None."""
        if not self.results:
            return None
        from dsp.calibration import Results

        return Results.from_dict(dict(self.results))

    def with_results(self, results: Results | None, raw_data_sha256: str | None) -> RunRecord:
        """The record with its results (and verdict) and the raw data's hash."""
        if results is None:
            return replace(self, results=None, raw_data_sha256=raw_data_sha256)
        return replace(
            self,
            results=results.to_dict(),
            verdict=results.verdict,
            verdict_reasons=tuple(results.verdict_reasons),
            raw_data_sha256=raw_data_sha256,
        )

    # --- JSON ------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The JSON document, keys in a stable order; optional keys only when set."""
        data: dict[str, Any] = {
            "schema_version": self.schema_version,
            "run_id": self.run_id,
            "status": self.status,
            "abort_reason": self.abort_reason,
            "mode": self.mode,
            "started_utc": self.started_utc,
            "finished_utc": self.finished_utc,
            "excitation_time_s": self.excitation_time_s,
            "periods_read": self.periods_read,
            "final_output_v": self.final_output_v,
            "equalisation_worst": list(self.equalisation_worst),
            "background_v": dict(self.background_v),
            "budget": [dict(c) for c in self.budget],
            "reference_chain": dict(self.reference_chain),
            "software_version": self.software_version,
            "settings": dict(self.settings),
            "plan": dict(self.plan),
            "stand": self.stand.to_dict(),
        }
        if self.dut is not None:
            data["dut"] = self.dut.to_dict()
        if self.level_ms2 is not None:
            data["level_ms2"] = self.level_ms2
        if self.measuring_amplifier is not None:
            data["measuring_amplifier"] = dict(self.measuring_amplifier)
        if self.stand_response is not None:
            data["stand_response"] = dict(self.stand_response)
        if self.technician:
            data["technician"] = self.technician
        data.update(self.extra)
        if self.verdict is not None:
            data["verdict"] = self.verdict
            data["verdict_reasons"] = list(self.verdict_reasons)
        if self.raw_data_sha256 is not None:
            data["raw_data_sha256"] = self.raw_data_sha256
        if self.overrides:
            data["overrides"] = [o.to_dict() for o in self.overrides]
        data["results"] = dict(self.results) if self.results is not None else None
        return data

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, default=str)

    @classmethod
    def from_dict(cls, data: Any) -> RunRecord:
        """A record from a results.json document; RunRecordError when it is none,
        UnsupportedSchemaError for a schema version newer than this code knows."""
        if not isinstance(data, dict):
            raise RunRecordError(f"results.json: not a JSON object ({type(data).__name__})")
        version = data.get("schema_version", UNVERSIONED)
        if not isinstance(version, int) or isinstance(version, bool) or version < 1:
            raise RunRecordError(f"results.json: schema_version {version!r} is not valid")
        if version > SCHEMA_VERSION:
            raise UnsupportedSchemaError(
                f"results.json: schema_version {version} is newer than this accelcal reads "
                f"(up to {SCHEMA_VERSION}); read it with a newer accelcal"
            )
        known = {f for f in cls.__dataclass_fields__ if f not in ("extra", "schema_version")}
        known |= {"verdict_reasons"}
        try:
            return cls(
                run_id=data.get("run_id"),
                status=str(data["status"]),
                abort_reason=data.get("abort_reason"),
                mode=str(data.get("mode") or Mode.MULTISINE),
                started_utc=str(data.get("started_utc") or ""),
                finished_utc=str(data.get("finished_utc") or ""),
                excitation_time_s=float(data.get("excitation_time_s") or 0.0),
                periods_read=int(data.get("periods_read") or 0),
                final_output_v=data.get("final_output_v"),
                equalisation_worst=tuple(data.get("equalisation_worst") or ()),
                background_v=dict(data.get("background_v") or {}),
                budget=tuple(data.get("budget") or ()),
                reference_chain=dict(data.get("reference_chain") or {}),
                software_version=str(data.get("software_version") or ""),
                settings=dict(data.get("settings") or {}),
                plan=dict(data.get("plan") or {}),
                stand=StandInfo.from_dict(data.get("stand")),
                dut=DutIdentity.from_dict(data.get("dut")),
                level_ms2=data.get("level_ms2"),
                measuring_amplifier=data.get("measuring_amplifier"),
                stand_response=data.get("stand_response"),
                verdict=data.get("verdict"),
                verdict_reasons=tuple(data.get("verdict_reasons") or ()),
                raw_data_sha256=data.get("raw_data_sha256"),
                results=data.get("results"),
                overrides=overrides_from(data.get("overrides")),
                technician=technician_name(data.get("technician")),
                extra={k: v for k, v in data.items() if k not in known and k != "schema_version"},
                schema_version=SCHEMA_VERSION,
            )
        except KeyError as exc:
            raise RunRecordError(f"results.json: no {exc.args[0]!r}") from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise RunRecordError(f"results.json: malformed ({exc})") from None

    @classmethod
    def from_json(cls, text: str) -> RunRecord:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise RunRecordError(f"results.json: not JSON ({exc})") from None
        return cls.from_dict(data)


def verdict_stated(data: Mapping[str, Any]) -> tuple[str | None, tuple[str, ...]]:
    """The verdict and its reasons a results.json document (or any part of one holding them)
    states: its own, else its results'; None when it states none."""
    results = data.get("results") or {}
    verdict = data.get("verdict") or results.get("verdict")
    reasons = data.get("verdict_reasons") or results.get("verdict_reasons") or ()
    return (str(verdict) if verdict else None), tuple(str(r) for r in reasons)


def technician_name(value: Any) -> str | None:
    """A technician's name as a run stores it: stripped text, None when absent or blank."""
    text = str(value).strip() if value is not None else ""
    return text or None
