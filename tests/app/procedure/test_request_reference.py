"""Issue 24: the typed Override of the run record (results.json round trip, old and future
readers) and the reference standard's rule in the request builder (`resolve_reference`),
without a database."""

from __future__ import annotations

import json
from dataclasses import replace
from datetime import UTC, date, datetime

import pytest

from app.procedure.request import ReferenceRefusal, RunIdentity, resolve_reference
from app.records.db.references import ReferenceTable
from app.records.run_record import Override, OverrideKind, RunRecord, RunRecordError
from app.stand import config as stand_config
from tests.lab_stand import lab_stand_file

NOW = datetime(2026, 11, 25, 8, 30, tzinfo=UTC)
TODAY = NOW.date()
OVERRIDE = Override(
    OverrideKind.EXPIRED_REFERENCE,
    "alice",
    "new cert in transit",
    "2026-11-25T08:30:00+00:00",
    "reference standard REF-1 was due for calibration on 2026-11-24",
)


def _table(due: date, phases: tuple[float | None, ...] = (None, None)) -> ReferenceTable:
    return ReferenceTable(
        identifier="REF-1",
        model="8305",
        serial="SIM-0001",
        certificate_number="PTB-1",
        calibration_date=date(2025, 11, 1),
        due_date=due,
        frequencies_hz=(160.0, 1000.0),
        sensitivity_mv_per_ms2=(1.0, 1.01),
        relative_expanded_uncertainty=(0.005, 0.005),
        phase_deg=phases,
    )


def _resolve(table: ReferenceTable | None, reason: str | None, config=None):
    return resolve_reference(
        config or stand_config.load(None),
        table,
        today=TODAY,
        override_reason=reason,
        who="alice",
        now_utc=NOW,
    )


def test_overrides_round_trip_through_results_json_and_config_json() -> None:
    record = RunRecord(run_id="r1", status="complete", overrides=(OVERRIDE,))
    data = json.loads(record.to_json())
    assert data["overrides"] == [
        {
            "kind": "expired reference",
            "who": "alice",
            "why": "new cert in transit",
            "when_utc": "2026-11-25T08:30:00+00:00",
            "what": "reference standard REF-1 was due for calibration on 2026-11-24",
        }
    ]
    assert data["schema_version"] == 1  # an optional key: older readers keep it as extra
    assert RunRecord.from_dict(data).overrides == (OVERRIDE,)
    assert "overrides" not in RunRecord.from_dict(data).extra
    identity = RunIdentity(level_ms2=5.0, overrides=(OVERRIDE,))
    assert RunIdentity.from_dict(identity.to_dict()) == identity


def test_old_folders_and_future_kinds_read() -> None:
    old = {"run_id": "r0", "status": "complete"}  # written before overrides existed
    assert RunRecord.from_dict(old).overrides == ()
    assert "overrides" not in RunRecord.from_dict(old).to_dict()
    future = {**OVERRIDE.to_dict(), "kind": "stand response disagrees"}
    (read,) = RunRecord.from_dict({**old, "overrides": [future]}).overrides
    assert read.kind == "stand response disagrees" and read.why == "new cert in transit"


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ("yes", "overrides is not a list"),
        (["x"], "an override is not an object"),
        ([{"kind": "k", "who": "w", "why": "y", "when_utc": "t"}], "an override has no 'what'"),
        ([{**OVERRIDE.to_dict(), "why": " "}], "override why: must be a non-empty text"),
    ],
)
def test_a_malformed_override_is_refused_by_name(overrides: object, message: str) -> None:
    with pytest.raises(RunRecordError, match=message):
        RunRecord.from_dict({"run_id": "r", "status": "complete", "overrides": overrides})


def test_a_reference_due_today_needs_no_override_one_due_yesterday_does() -> None:
    resolved = _resolve(_table(TODAY), None)
    assert resolved.table is not None and resolved.overrides == ()
    assert resolved.table.identifier == "REF-1"
    for blank in (None, "", "   "):
        with pytest.raises(
            ReferenceRefusal, match="REF-1 was due for calibration on 2026-11-24"
        ) as e:
            _resolve(_table(date(2026, 11, 24)), blank)
        assert e.value.overridable
    resolved = _resolve(_table(date(2026, 11, 24)), "  new cert in transit ")
    assert resolved.overrides == (OVERRIDE,)
    assert resolved.table is not None  # the records' table, under the override


def test_a_reference_not_on_record_is_refused_unless_overridden(tmp_path) -> None:
    """A stand whose reference is a lab's (its stand file states the table): not on record,
    refused naming it; the simulator's own (the built-in stand's) is used as such."""
    lab = stand_config.load(lab_stand_file(tmp_path))
    with pytest.raises(ReferenceRefusal, match=r"REF-8305-SIM \(serial SIM-0001\) of .*lab-stand"):
        _resolve(None, None, lab)
    real = replace(stand_config.load(None), backend="nidaqmx")  # a real stand, no table
    with pytest.raises(ReferenceRefusal, match="is not in the records"):
        _resolve(None, None, real)
    own = _resolve(None, None)  # the built-in simulated stand: the simulator's own reference
    assert own.table is None and own.overrides == ()
    (note,) = own.notes
    assert "REF-8305-SIM (serial SIM-0001) of built-in simulated stand" in note
    assert "the simulator's own" in note
    resolved = _resolve(None, "bought last week", lab)
    (override,) = resolved.overrides
    assert override.kind == OverrideKind.UNRECORDED_REFERENCE
    assert override.who == "alice" and override.when_utc == "2026-11-25T08:30:00+00:00"
    assert resolved.table is None  # the stand's own table


def test_phases_from_the_records_and_the_stand_file_comparison() -> None:
    config = stand_config.load(None)
    with_table = replace(
        config,
        reference=replace(
            config.reference,
            frequencies_hz=(160.0, 1000.0),
            sensitivity_mv_per_ms2=(1.0, 1.01),
            phase_deg=(0.0, 0.0),
        ),
    )
    assert _resolve(_table(TODAY), None, with_table).table is not None  # no phase: 0 deg
    with pytest.raises(ReferenceRefusal, match="differs from the records' table of REF-1") as e:
        _resolve(_table(TODAY, (0.0, 0.1)), None, with_table)
    assert not e.value.overridable
    one_off = replace(with_table.reference, sensitivity_mv_per_ms2=(1.0, 1.0100001))
    with pytest.raises(ReferenceRefusal, match="certificate PTB-1"):
        _resolve(_table(TODAY), None, replace(with_table, reference=one_off))
    with pytest.raises(ReferenceRefusal, match="a phase on some rows only"):
        _resolve(_table(TODAY, (0.1, None)), None)


def test_the_records_uncertainty_replaces_the_stand_files_reference_component() -> None:
    """Table 0.5 % at 160 Hz, 1.2 % at 1000 Hz: below 1000 Hz the larger of the two points
    around a line (1.2 %), from 1000 Hz up 1.2 %; one band of 1.2 % from 160 Hz up, and below
    160 Hz the first point's 0.5 %. The stand file's 0.5 % component is gone, the others stay."""
    from app.procedure.reference import REFERENCE_COMPONENT, reference_budget
    from dsp.uncertainty import Quantity

    table = replace(_table(TODAY), relative_expanded_uncertainty=(0.005, 0.012))
    stand = stand_config.load(None).budget
    budget = reference_budget(stand, table)
    names = [c.name for c in budget.components]
    assert names.count(REFERENCE_COMPONENT) == 0
    ours = [c for c in budget.components if "certificate PTB-1 of REF-1" in c.note]
    assert [(c.value, c.min_frequency_hz) for c in ours] == [(0.005, None), (0.012, 160.0)]
    assert ours[0].max_frequency_hz == pytest.approx(160.0) and ours[0].max_frequency_hz < 160.0
    assert ours[1].max_frequency_hz is None
    for f, u in ((10.0, 0.005), (160.0, 0.012), (500.0, 0.012), (5000.0, 0.012)):
        (c,) = [c for c in budget.at(f, Quantity.MAGNITUDE) if c in ours]
        assert c.value == u
    others = [c for c in stand.components if c.name != REFERENCE_COMPONENT]
    assert [c for c in budget.components if c not in ours] == others
    flat = reference_budget(stand, _table(TODAY))  # 0.5 % everywhere: one component
    (only,) = [c for c in flat.components if "PTB-1" in c.note]
    assert only.name == REFERENCE_COMPONENT and only.min_frequency_hz is None
    assert only.max_frequency_hz is None and only.coverage_factor == 2.0
