"""The lab's records on SQLite and PostgreSQL: refusals by field, audit trail, due list,
history, certificate register."""

from __future__ import annotations

from datetime import UTC, date, datetime, timedelta

import pytest
from sqlalchemy import Engine, select, text
from sqlalchemy.orm import Session

from app.records.db.lab import Lab
from app.records.db.models import AuditEntry, Run, Sensor, Stand
from app.records.db.run_index import DAYS_PER_YEAR, HistoryPoint, drift_percent_per_year
from app.records.db.store import RecordsError, add_months
from app.records.db.units import STANDARD_GRAVITY_MS2, from_mv_per_ms2, to_mv_per_ms2
from tests.records_db import add_staff

TODAY = date(2026, 11, 23)


@pytest.fixture
def lab(engine: Engine) -> Lab:
    lab = Lab(engine, actor="tester")
    lab.add_customer("ACME Ltd")
    lab.add_customer("Żółć Sp. z o.o.")
    lab.add_model(
        "Brüel & Kjær",
        "4533-B",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5,
        frequency_min_hz=10,
        frequency_max_hz=10000,
    )
    lab.add_sensor("SN-1", model="4533-B", owner="ACME Ltd", interval_months=12)
    lab.add_sensor("SN-2", model="Brüel & Kjær 4533-B", owner="Żółć Sp. z o.o.")
    return lab


def _run(lab: Lab, run_id: str, serial: str, started: datetime, sens: float, status="complete"):
    """Index a run row directly (import from folders is tested in test_import.py)."""
    with lab.session() as s:
        stand = s.scalar(select(Stand)) or Stand(stand_file_sha256="0" * 64, name="stand 1")
        sensor = s.scalar(select(Sensor).where(Sensor.serial == serial))
        s.add(
            Run(
                run_id=run_id,
                manifest_sha256=run_id.ljust(64, "0")[:64],
                folder=f"/runs/{run_id}",
                status=status,
                started_utc=started,
                dut_id=serial,
                stand=stand,
                sensor=sensor,
                reference_frequency_hz=160.0,
                sensitivity_mv_per_ms2=sens,
                expanded_uncertainty_mv_per_ms2=0.05,
            )
        )


# ---- units ---------------------------------------------------------------------------------
def test_mv_per_g_converts_exactly_by_standard_gravity() -> None:
    assert STANDARD_GRAVITY_MS2 == 9.80665
    # 98.0665 mV/g is 10 mV/(m/s^2) by hand
    assert to_mv_per_ms2(98.0665, "mV/g") == pytest.approx(10.0, rel=1e-15)
    assert from_mv_per_ms2(10.0, "mV/g") == pytest.approx(98.0665, rel=1e-15)
    assert to_mv_per_ms2(1.25, "pC/(m/s^2)") == 1.25


# ---- refusals name the field -----------------------------------------------------------------
@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"unit": "mV/furlong"}, "unit"),
        ({"nominal_sensitivity": 0.0}, "nominal sensitivity"),
        ({"nominal_sensitivity": float("nan")}, "nominal sensitivity"),
        ({"tolerance_percent": -1.0}, "tolerance"),
        ({"frequency_max_hz": 5.0}, "frequency max"),
    ],
)
def test_a_bad_model_field_is_refused_by_name(lab: Lab, change: dict, field: str) -> None:
    fields = {
        "nominal_sensitivity": 1.0,
        "unit": "mV/g",
        "tolerance_percent": 5.0,
        "frequency_min_hz": 10.0,
        "frequency_max_hz": 1000.0,
    } | change
    with pytest.raises(RecordsError, match=f"^{field}"):
        lab.add_model("PCB", "352C33", **fields)


def test_duplicate_serial_unknown_model_and_owner_are_refused(lab: Lab) -> None:
    with pytest.raises(RecordsError, match=r"^serial: 'SN-1' already exists"):
        lab.add_sensor("SN-1", model="4533-B", owner="ACME Ltd")
    with pytest.raises(RecordsError, match=r"^model: 'nosuch'"):
        lab.add_sensor("SN-9", model="nosuch", owner="ACME Ltd")
    with pytest.raises(RecordsError, match=r"^owner: no customer"):
        lab.add_sensor("SN-9", model="4533-B", owner="Nobody")
    with pytest.raises(RecordsError, match=r"^serial: no sensor 'SN-9'"):
        lab.sensor("SN-9")
    assert [s.serial for s in lab.sensors()] == ["SN-1", "SN-2"]


def test_a_due_date_before_the_calibration_date_is_refused(lab: Lab) -> None:
    with pytest.raises(RecordsError, match=r"^due date: 2026-01-01 is not after"):
        lab.add_reference(
            "REF-1",
            model="8305",
            serial="1",
            certificate_number="C-1",
            calibration_date=date(2026, 6, 1),
            due_date=date(2026, 1, 1),
            table=[(160.0, 0.125, 0.005, None)],
        )


# ---- audit trail ---------------------------------------------------------------------------
def test_every_write_is_audited_with_who_and_what(lab: Lab) -> None:
    lab.set_setting("two_person_rule", "on")
    lab.set_setting("two_person_rule", "off")
    with Session(lab.engine) as s:
        entries = s.scalars(select(AuditEntry).order_by(AuditEntry.id)).all()
    by_table = [(e.table_name, e.action, e.row_key) for e in entries]
    assert ("customers", "insert", "ACME Ltd") in by_table
    assert ("sensors", "insert", "SN-2") in by_table
    assert by_table[-2:] == [
        ("settings", "insert", "two_person_rule"),
        ("settings", "update", "two_person_rule"),
    ]
    assert entries[-1].changes == '{"value": ["on", "off"]}'
    assert {e.actor for e in entries} == {"tester"}


def test_the_audit_trail_refuses_update_and_delete(lab: Lab) -> None:
    for statement in ("UPDATE audit_trail SET actor = 'mallory'", "DELETE FROM audit_trail"):
        with lab.engine.connect() as conn, pytest.raises(Exception, match="append-only"):
            conn.execute(text(statement))
    with Session(lab.engine) as s:
        assert s.scalar(select(AuditEntry).where(AuditEntry.actor == "mallory")) is None


# ---- reference standards -----------------------------------------------------------------
def test_an_expired_reference_is_refused_naming_its_due_date_unless_overridden(lab: Lab) -> None:
    lab.add_reference(
        "REF-8305",
        model="B&K 8305",
        serial="123",
        certificate_number="PTB-1",
        calibration_date=date(2025, 6, 1),
        due_date=date(2026, 6, 1),
        table=[(160.0, 0.125, 0.005, 0.1), (1000.0, 0.126, 0.006, None)],
    )
    with pytest.raises(RecordsError, match="due for calibration on 2026-06-01"):
        lab.reference_for_run("REF-8305", today=TODAY)
    ref = lab.reference_for_run("REF-8305", today=TODAY, override_reason="PTB slot booked")
    assert [p.frequency_hz for p in ref.points] == [160.0, 1000.0]
    assert lab.reference_for_run("REF-8305", today=date(2026, 5, 31)).certificate_number == "PTB-1"


# ---- due list and history -----------------------------------------------------------------
def test_add_months_keeps_the_day_or_takes_the_month_end() -> None:
    assert add_months(date(2025, 1, 31), 1) == date(2025, 2, 28)
    assert add_months(date(2024, 1, 31), 1) == date(2024, 2, 29)
    assert add_months(date(2025, 11, 15), 12) == date(2026, 11, 15)
    assert add_months(date(2025, 12, 1), 1) == date(2026, 1, 1)


def test_due_lists_sensors_by_last_complete_run_plus_interval(lab: Lab) -> None:
    _run(lab, "r-old", "SN-1", datetime(2025, 12, 1, tzinfo=UTC), 10.0)
    _run(lab, "r-aborted", "SN-1", datetime(2026, 11, 1, tzinfo=UTC), 10.0, status="aborted")
    items = lab.due(today=TODAY, days=30)
    # SN-2 was never calibrated here: listed first without a date; SN-1 due 2026-12-01
    assert [(i.identifier, i.due) for i in items] == [("SN-2", None), ("SN-1", date(2026, 12, 1))]
    assert [i.identifier for i in lab.due(today=TODAY, days=7)] == ["SN-2"]
    _run(lab, "r-new", "SN-1", datetime(2026, 11, 20, tzinfo=UTC), 10.0)
    assert [i.identifier for i in lab.due(today=TODAY, days=30)] == ["SN-2"]


def test_history_is_in_time_order_with_the_drift_per_year(lab: Lab) -> None:
    t0 = datetime(2024, 3, 1, tzinfo=UTC)
    _run(lab, "r2", "SN-1", t0 + timedelta(days=DAYS_PER_YEAR), 10.1)
    _run(lab, "r1", "SN-1", t0, 10.0)
    history = lab.history("SN-1")
    assert [p.run_id for p in history.points] == ["r1", "r2"]
    # equal U: slope 0.1 mV/(m/s^2) per year over a mean of 10.05 -> 0.99502 % per year
    assert history.drift_percent_per_year == pytest.approx(0.1 / 10.05 * 100, rel=1e-9)


def test_drift_weights_by_uncertainty() -> None:
    t0 = datetime(2024, 1, 1, tzinfo=UTC)
    year = timedelta(days=DAYS_PER_YEAR)
    points = [
        HistoryPoint("a", t0, 160.0, 10.0, 0.02),
        HistoryPoint("b", t0 + year, 10.2, 0.02)
        if False
        else HistoryPoint("b", t0 + year, 160.0, 10.2, 0.02),
        HistoryPoint("c", t0 + 2 * year, 160.0, 10.0, 2.0),
    ]
    # c carries 1/10000 of the weight of a and b: the slope stays close to 0.2 per year
    # (hand: weights 1, 1, 1e-4; t = 0, 1, 2; v = 10, 10.2, 10)
    w, t, v = [1, 1, 1e-4], [0, 1, 2], [10.0, 10.2, 10.0]
    tm = sum(a * b for a, b in zip(w, t, strict=True)) / sum(w)
    vm = sum(a * b for a, b in zip(w, v, strict=True)) / sum(w)
    slope = sum(a * (b - tm) * (c - vm) for a, b, c in zip(w, t, v, strict=True)) / sum(
        a * (b - tm) ** 2 for a, b in zip(w, t, strict=True)
    )
    assert drift_percent_per_year(points) == pytest.approx(100 * slope / vm, rel=1e-9)
    assert 1.9 < drift_percent_per_year(points) < 2.0
    assert drift_percent_per_year(points[:1]) is None
    close = [points[0], HistoryPoint("d", t0 + timedelta(days=29), 160.0, 10.5, 0.02)]
    assert drift_percent_per_year(close) is None  # 29 days: no rate per year
    close[1] = HistoryPoint("d", t0 + timedelta(days=30), 160.0, 10.5, 0.02)
    assert drift_percent_per_year(close) is not None


# ---- certificate register ---------------------------------------------------------------
def test_numbers_are_sequential_in_the_labs_pattern_and_amendments_name_what_they_replace(
    lab: Lab,
) -> None:
    when = datetime(2026, 11, 23, 12, tzinfo=UTC)
    _run(lab, "r1", "SN-1", when, 10.0)
    _run(lab, "r2", "SN-2", when, 10.0)
    first = lab.issue_certificate(run_id="r1", prepared_by="A", approved_by="B", when=when)
    second = lab.issue_certificate(run_id="r2", prepared_by="A", approved_by="A", when=when)
    assert (first.number, second.number) == ("ACC-2026-0001", "ACC-2026-0002")
    with pytest.raises(RecordsError, match=r"^reason: must not be blank"):
        lab.issue_certificate(run_id="r1", prepared_by="A", approved_by="B", replaces=first.number)
    amended = lab.issue_certificate(
        run_id="r1",
        prepared_by="A",
        approved_by="B",
        when=when,
        replaces=first.number,
        reason="customer address corrected",
    )
    assert amended.number == "ACC-2026-0003" and amended.replaces == "ACC-2026-0001"
    with pytest.raises(RecordsError, match="already replaced"):
        lab.issue_certificate(
            run_id="r1", prepared_by="A", approved_by="B", replaces=first.number, reason="x"
        )
    lab.withdraw_certificate(second.number, "wrong sensor mounted")
    states = [(c.number, c.state, c.sensor.serial) for c in lab.register()]
    assert states == [
        ("ACC-2026-0001", "replaced", "SN-1"),
        ("ACC-2026-0002", "withdrawn", "SN-2"),
        ("ACC-2026-0003", "issued", "SN-1"),
    ]
    lab.set_setting("certificate_pattern", "LAB/{year}/{seq:05d}")
    next_year = when.replace(year=2027)
    assert (
        lab.issue_certificate(
            run_id="r1",
            prepared_by="A",
            approved_by="B",
            when=next_year,
            replaces=amended.number,
            reason="new pattern",
        ).number
        == "LAB/2027/00001"
    )


def test_two_person_rule_and_run_checks(lab: Lab) -> None:
    when = datetime(2026, 11, 23, tzinfo=UTC)
    _run(lab, "r1", "SN-1", when, 10.0)
    _run(lab, "r-ab", "SN-1", when, 10.0, status="aborted")
    _run(lab, "r-x", "SN-404", when, 10.0)
    add_staff(lab.engine, ("ann", "Ann"), ("bob", "Bob"))  # the rule takes persons on record
    lab.set_setting("two_person_rule", "on")
    with pytest.raises(RecordsError, match=r"^approved by: the lab's two-person rule"):
        lab.issue_certificate(run_id="r1", prepared_by="Ann", approved_by="ann")
    with pytest.raises(RecordsError, match=r"^run: r-ab is aborted"):
        lab.issue_certificate(run_id="r-ab", prepared_by="Ann", approved_by="Bob")
    with pytest.raises(RecordsError, match=r"^run: r-x's DUT 'SN-404' is no sensor"):
        lab.issue_certificate(run_id="r-x", prepared_by="Ann", approved_by="Bob")
    with pytest.raises(RecordsError, match=r"^run: 'nosuch' is not indexed"):
        lab.issue_certificate(run_id="nosuch", prepared_by="Ann", approved_by="Bob")
    with pytest.raises(RecordsError, match=r"^certificate_pattern"):
        lab.set_setting("certificate_pattern", "ACC-{seq:04d}-{year}")
    assert lab.register() == []


def test_a_check_standard_outside_its_control_limits_is_a_warning() -> None:
    from app.records.db.run_index import individuals_chart

    values = [10.00, 10.02, 9.99, 10.01, 10.00]
    # hand: mean 10.004; moving ranges 0.02, 0.03, 0.02, 0.01 -> mean 0.02; sigma 0.02/1.128
    sigma = 0.02 / 1.128
    points = [(f"r{i}", v) for i, v in enumerate(values)]
    inside = individuals_chart("CS-1", "stand 1", [*points, ("r5", 10.004 + 2.9 * sigma)])
    assert inside.centre == pytest.approx(10.004, rel=1e-12)
    assert inside.upper == pytest.approx(10.004 + 3 * sigma, rel=1e-12)
    assert inside.lower == pytest.approx(10.004 - 3 * sigma, rel=1e-12)
    assert inside.warning is None
    outside = individuals_chart("CS-1", "stand 1", [*points, ("r5", 10.004 - 3.1 * sigma)])
    assert outside.warning is not None and "run r5" in outside.warning
    assert individuals_chart("CS-1", "s", points[:5]).centre is None  # 4 earlier: no limits


def test_as_found_must_be_an_earlier_complete_run_of_the_same_sensor(lab: Lab) -> None:
    t = datetime(2026, 11, 20, tzinfo=UTC)
    _run(lab, "found", "SN-1", t, 10.6)
    _run(lab, "left", "SN-1", t + timedelta(hours=2), 10.0)
    _run(lab, "other", "SN-2", t, 10.0)
    with pytest.raises(RecordsError, match=r"^as found: run other is no complete run of SN-1"):
        lab.issue_certificate(
            run_id="left", prepared_by="A", approved_by="B", as_found_run_id="other"
        )
    with pytest.raises(RecordsError, match=r"^as found: run left is not before"):
        lab.issue_certificate(
            run_id="found", prepared_by="A", approved_by="B", as_found_run_id="left"
        )
    lab.issue_certificate(run_id="left", prepared_by="A", approved_by="B", as_found_run_id="found")
    (entry,) = lab.register()
    assert (entry.run.run_id, entry.as_found_run.run_id) == ("left", "found")


# ---- run templates per sensor model -----------------------------------------------------------
def test_templates_belong_to_a_model_and_come_back_as_saved(lab: Lab) -> None:
    lab.add_model(
        "PCB",
        "352C33",
        nominal_sensitivity=100.0,
        unit="mV/g",
        tolerance_percent=5,
        frequency_min_hz=1,
        frequency_max_hz=10000,
    )
    lab.add_template(
        "4533-B",
        "quick check",
        preset="piezo",
        frequencies_hz=(40.0, 80.0, 160.0, 315.0, 630.0),
        level_ms2=4.0,
        periods=3,
        estimator="periodic",
        tolerance_percent=2.5,
    )
    lab.add_template(
        "Brüel & Kjær 4533-B",
        "full, 0.2 % type A",
        preset="piezo",
        level_ms2=5.0,
        periods=8,
        target_type_a=0.002,
        max_acquisition_s=30.0,
        estimator="h1",
    )
    lab.add_template(
        "352C33", "quick check", preset="capacitive", level_ms2=3.0, periods=4, estimator="seed"
    )  # same name, another model: allowed
    rows = lab.templates("4533-B")
    assert [t.name for t in rows] == ["full, 0.2 % type A", "quick check"]  # by name
    full, quick = rows
    assert quick.lines_hz() == (40.0, 80.0, 160.0, 315.0, 630.0)
    assert (quick.level_ms2, quick.periods, quick.tolerance_percent) == (4.0, 3, 2.5)
    assert quick.target_type_a is None and quick.estimator == "periodic"
    assert full.lines_hz() is None and full.target_type_a == 0.002
    assert (full.max_acquisition_s, full.estimator) == (30.0, "h1")
    assert [t.preset for t in lab.templates("PCB 352C33")] == ["capacitive"]
    with Session(lab.engine) as s:
        trail = s.scalars(select(AuditEntry).where(AuditEntry.table_name == "run_templates")).all()
    assert [(e.action, e.row_key, e.actor) for e in trail] == [
        ("insert", "quick check", "tester"),
        ("insert", "full, 0.2 % type A", "tester"),
        ("insert", "quick check", "tester"),
    ]
    assert '"level_ms2": 4.0' in trail[0].changes


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"name": "  "}, "template name"),
        ({"name": "quick"}, "template name"),  # exists for the model
        ({"model": "NOPE"}, "model"),
        ({"preset": "quartz"}, "preset"),
        ({"estimator": "h2"}, "estimator"),
        ({"level_ms2": 0.0}, "level"),
        ({"level_ms2": float("nan")}, "level"),
        ({"periods": 2}, "periods"),
        ({"target_type_a": 0.5}, "type A target"),
        ({"max_acquisition_s": -1.0}, "time bound"),
        ({"tolerance_percent": 0.0}, "tolerance"),
        ({"frequencies_hz": (40.0, 80.0)}, "frequencies"),  # no 160 Hz reference line
        ({"frequencies_hz": (160.0, 2900.0)}, "frequencies"),  # above 0.45 fs of 6 kHz
    ],
)
def test_a_bad_template_field_is_refused_by_name(lab: Lab, change: dict, field: str) -> None:
    lab.add_template(
        "4533-B", "quick", preset="piezo", level_ms2=4, periods=3, estimator="periodic"
    )
    values = {
        "model": "4533-B",
        "name": "other",
        "preset": "piezo",
        "level_ms2": 4.0,
        "periods": 3,
        "estimator": "periodic",
    } | change
    model, name = values.pop("model"), values.pop("name")
    with pytest.raises(RecordsError, match=f"^{field}: "):
        lab.add_template(model, name, **values)
    assert [t.name for t in lab.templates("4533-B")] == ["quick"]


def test_the_same_person_is_refused_as_approver_under_the_two_person_rule(lab: Lab) -> None:
    assert lab.check_signatories(" Ann ", "ann") == ("Ann", "ann")  # rule off: allowed
    add_staff(lab.engine, ("ann", "Ann"), ("bob", "Bob"))  # the rule takes persons on record
    lab.set_setting("two_person_rule", "on")
    with pytest.raises(RecordsError, match=r"^approved by: the lab's two-person rule"):
        lab.check_signatories("Ann", " ANN")
    with pytest.raises(RecordsError, match=r"^prepared by: must not be blank"):
        lab.check_signatories("", "Bob")
    assert lab.check_signatories("Ann", "Bob") == ("Ann", "Bob")


def test_complete_runs_of_a_sensor_newest_first(lab: Lab) -> None:
    t = datetime(2026, 11, 20, tzinfo=UTC)
    _run(lab, "old", "SN-1", t, 10.0)
    _run(lab, "new", "SN-1", t + timedelta(days=1), 10.0)
    _run(lab, "cut", "SN-1", t + timedelta(days=2), 10.0, status="aborted")
    _run(lab, "other", "SN-2", t, 10.0)
    assert [r.run_id for r in lab.complete_runs("SN-1")] == ["new", "old"]
    with pytest.raises(RecordsError, match=r"^serial: no sensor"):
        lab.complete_runs("SN-404")
