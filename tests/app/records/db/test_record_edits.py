"""Customers, sensor models and reference standards edited through `Lab` (issue 24 point 7, the
GUI's path) on SQLite and PostgreSQL: each change checked as the add is, refused by field, and
its old value kept in the audit trail."""

from __future__ import annotations

import json
from datetime import date

import pytest
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from app.records.db.lab import Lab, RecordsError
from app.records.db.models import AuditEntry

MODEL = {
    "nominal_sensitivity": 10.0,
    "unit": "mV/(m/s^2)",
    "tolerance_percent": 5.0,
    "frequency_min_hz": 1.0,
    "frequency_max_hz": 10_000.0,
}
TABLE = [(160.0, 0.1257, 0.005, 0.1), (1000.0, 0.1262, 0.007, None)]


@pytest.fixture
def lab(engine: Engine) -> Lab:
    lab = Lab(engine, actor="editor")
    lab.add_customer("ACME Ltd", "1 Main Street")
    lab.add_customer("Other GmbH")
    lab.add_model("PCB", "352C33", **MODEL)
    lab.add_model("PCB", "356A16", **MODEL)
    lab.add_reference(
        "REF-1",
        model="8305",
        serial="1",
        certificate_number="C-2025",
        calibration_date=date(2025, 3, 1),
        due_date=date(2026, 3, 1),
        table=TABLE,
    )
    return lab


def trail(lab: Lab, table: str) -> list[tuple[str, str, dict]]:
    with Session(lab.engine) as s:
        rows = s.scalars(
            select(AuditEntry).where(AuditEntry.table_name == table).order_by(AuditEntry.id)
        ).all()
        return [(e.action, e.row_key, json.loads(e.changes)) for e in rows]


def test_a_customer_is_renamed_and_readdressed_audited(lab: Lab) -> None:
    lab.update_customer("ACME Ltd", new_name="ACME Ltd.", address="2 High Street")
    assert next((c.name, c.address) for c in lab.customers()) == ("ACME Ltd.", "2 High Street")
    action, key, changes = trail(lab, "customers")[-1]
    assert (action, key) == ("update", "ACME Ltd.")
    assert changes["address"] == ["1 Main Street", "2 High Street"]
    assert changes["name"] == ["ACME Ltd", "ACME Ltd."]
    with pytest.raises(RecordsError, match="customer: 'Other GmbH' already exists"):
        lab.update_customer("ACME Ltd.", new_name="Other GmbH", address="")
    with pytest.raises(RecordsError, match="customer: must not be blank"):
        lab.update_customer("ACME Ltd.", new_name=" ", address="")
    with pytest.raises(RecordsError, match="customer: no customer named 'Nobody'"):
        lab.update_customer("Nobody", new_name="X", address="")


def test_a_model_is_changed_with_the_checks_of_an_add(lab: Lab) -> None:
    lab.update_model("PCB 352C33", maker="PCB", model="352C33", **{**MODEL, "unit": "mV/g"})
    model = next(m for m in lab.models() if m.model == "352C33")
    assert model.unit == "mV/g" and model.nominal_sensitivity == 10.0
    assert trail(lab, "sensor_models")[-1][2] == {"unit": ["mV/(m/s^2)", "mV/g"]}
    with pytest.raises(RecordsError, match="model: PCB 356A16 already exists"):
        lab.update_model("PCB 352C33", maker="PCB", model="356A16", **MODEL)
    with pytest.raises(RecordsError, match="frequency max"):
        lab.update_model(
            "PCB 352C33", maker="PCB", model="352C33", **{**MODEL, "frequency_max_hz": 0.5}
        )
    with pytest.raises(RecordsError, match="unit: unknown unit"):
        lab.update_model("PCB 352C33", maker="PCB", model="352C33", **{**MODEL, "unit": "V/g"})
    # a refused change leaves the model as it was
    model = next(m for m in lab.models() if m.model == "352C33")
    assert (model.unit, model.frequency_max_hz) == ("mV/g", 10_000.0)


def test_a_reference_is_recalibrated_its_old_table_in_the_audit_trail(lab: Lab) -> None:
    lab.update_reference(
        "REF-1",
        model="8305",
        serial="1",
        certificate_number="C-2026",
        calibration_date=date(2026, 2, 20),
        due_date=date(2027, 2, 20),
        table=[(160.0, 0.1259, 0.004, None)],
    )
    (ref,) = lab.references()
    assert ref.certificate_number == "C-2026" and ref.due_date == date(2027, 2, 20)
    assert [(p.frequency_hz, p.sensitivity_mv_per_ms2) for p in ref.points] == [(160.0, 0.1259)]
    points = trail(lab, "reference_points")
    deleted = sorted(c["sensitivity_mv_per_ms2"] for a, _k, c in points if a == "delete")
    assert deleted == [0.1257, 0.1262]
    with pytest.raises(RecordsError, match="table row 1 uncertainty"):
        lab.update_reference(
            "REF-1",
            model="8305",
            serial="1",
            certificate_number="C-2026",
            calibration_date=date(2026, 2, 20),
            due_date=date(2027, 2, 20),
            table=[(160.0, 0.1259, 4.0, None)],
        )
    with pytest.raises(RecordsError, match="due date: 2026-01-01 is not after"):
        lab.update_reference(
            "REF-1",
            model="8305",
            serial="1",
            certificate_number="C-2026",
            calibration_date=date(2026, 2, 20),
            due_date=date(2026, 1, 1),
        )
    (ref,) = lab.references()
    assert len(ref.points) == 1 and ref.points[0].relative_expanded_uncertainty == 0.004
