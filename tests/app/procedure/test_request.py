"""The run request: one DutSpec from the records, the TEDS, the stand file or the simulated
catalogue; the verdict's tolerances from it on any stand; the run identity as stored."""

from __future__ import annotations

import json
import math
from datetime import date
from pathlib import Path

import pytest

from app.procedure.request import (
    DutChoice,
    RunIdentity,
    RunRequest,
    build_request,
    resolve_dut,
)
from app.procedure.run import prepare, request_plan
from app.procedure.verdict import FAIL, PASS, assess
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.records.run_record import DutIdentity
from app.stand.dut import Band, DutSpec, spec_from_record
from app.stand.simulated import catalogue_spec
from tests.app.procedure.test_verdict import _results
from tests.records_db import new_records

# a sensor model on record: 9.8 mV/(m/s^2) +-4 %, phase within 2 degrees from 10 to 1000 Hz
RECORDED = spec_from_record(
    serial="SN-1",
    manufacturer="Maker",
    model="M-1",
    description="Maker M-1, owner ACME",
    nominal_mv_per_ms2=9.8,
    tolerance_percent=4.0,
    frequency_min_hz=10.0,
    frequency_max_hz=1000.0,
    phase_tolerance_deg=2.0,
    preset="piezo",
    level_ms2=4.0,
)


def test_the_verdict_takes_the_records_phase_tolerance_on_real_hardware() -> None:
    request = RunRequest(dut_spec=RECORDED, dut_id="SN-1", nominal_mv_per_ms2=9.8)
    tolerances = request.tolerances("nidaqmx", 160.0)
    assert tolerances.phase == (Band(10.0, 1000.0, 2.0),)
    assert tolerances.nominal_sensitivity_mv_per_ms2 == 9.8
    assert tolerances.sensitivity_percent == 4.0
    # 3.0 deg at 1000 Hz with U 0.5 deg: 3.0 - 0.5 = 2.5 > 2 -> fail (by hand); the simulated
    # catalogue's 5 deg would pass it (3.0 + 0.5 <= 5)
    results = _results(reference_mv=9.8, phase_deg=(0.0, 0.0, 0.0, 3.0, 0.0))
    verdict, reasons, _ = assess(results, tolerances)
    assert verdict == FAIL
    assert "phase: fail at 1000 Hz (tolerance ±2 °)" in reasons
    assert assess(results, catalogue_spec("piezo").tolerances(160.0))[0] == PASS
    # 1.2 + 0.5 <= 2 -> pass; 30 deg at 2500 Hz lies outside the range 10..1000 Hz: not checked
    inside = _results(reference_mv=9.8, phase_deg=(0.0, 0.0, 0.0, 1.2, 30.0))
    verdict, reasons, _ = assess(inside, tolerances)
    assert verdict == PASS
    assert "phase: pass at all 4 line(s) checked (tolerance ±2 °)" in reasons  # 10 to 1000 Hz


def test_on_the_simulated_stand_a_recorded_dut_keeps_its_own_tolerances() -> None:
    request = RunRequest(dut="piezo", dut_spec=RECORDED)
    assert request.tolerances("sim", 160.0) == request.tolerances("nidaqmx", 160.0)
    # its mass is not on record: the simulated catalogue DUT's (what the stand carries)
    assert request.mass_g("sim") == catalogue_spec("piezo").mass_g
    assert request.mass_g("nidaqmx") is None
    assert RunRequest(dut_spec=RECORDED, dut_mass_g=12.0).mass_g("nidaqmx") == 12.0


def test_prepare_hands_the_spec_tolerances_to_the_procedure(tmp_path: Path) -> None:
    request = RunRequest(dut_spec=RECORDED, periods=3, out=tmp_path, stored_response=False)
    procedure, stand = prepare(request)
    try:
        tolerances = procedure._tolerances()
    finally:
        stand.close()
    assert tolerances.phase == (Band(10.0, 1000.0, 2.0),)
    assert tolerances.nominal_sensitivity_mv_per_ms2 == 9.8
    assert "records: sensor model Maker M-1" in tolerances.source


def test_catalogue_spec_keeps_the_data_sheet_and_a_stated_value_replaces_it() -> None:
    spec = catalogue_spec("piezo")
    assert spec.catalogue == "piezo" and spec.preset == "piezo"
    tol = spec.tolerances(160.0)
    assert tol.sensitivity_percent == 5.0 and tol.phase == (Band(5.0, 5000.0, 5.0),)
    # the catalogue's shape: within 0.1 % of its 10.2 mV/(m/s^2) mid-band at 160 Hz
    assert tol.nominal_sensitivity_mv_per_ms2 == pytest.approx(10.2, rel=1e-3)
    stated = spec.with_options(nominal_mv_per_ms2=11.0, tolerance_percent=2.0)
    tol = stated.tolerances(160.0)
    assert tol.nominal_sensitivity_mv_per_ms2 == 11.0
    assert tol.characteristic == (Band(0.0, math.inf, 2.0),)
    assert tol.source == "data sheet of the simulated 'piezo' model with --tolerance"
    assert catalogue_spec("nonesuch") == DutSpec()
    assert catalogue_spec("capacitive").tolerances(100.0).phase == ()


def test_resolve_dut_by_source() -> None:
    sim = resolve_dut(DutChoice(dut="capacitive", dut_id="X-1"), "sim", {})
    assert sim.spec.catalogue == "capacitive" and sim.dut_id == "X-1"
    assert sim.nominal_mv_per_ms2 is None and sim.level_ms2 == 5.0 and sim.preset is None
    real = resolve_dut(
        DutChoice(level_ms2=3.0), "nidaqmx", {"dut_model": "PCB 352C33", "dut_type": "piezo"}
    )
    assert real.spec.catalogue is None and real.spec.model == "PCB 352C33"
    assert real.spec.tolerances(160.0).empty and real.level_ms2 == 3.0


def test_build_request_from_the_records(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    url = new_records(tmp_path / "lab.sqlite")
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    lab = Lab(open_engine(url), actor="t")
    lab.add_customer("ACME Ltd")
    lab.add_model(
        "Maker",
        "M-2",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=3,
        frequency_min_hz=20,
        frequency_max_hz=2000,
        level_ms2=4.0,
        phase_tolerance_deg=1.5,
    )
    lab.add_sensor("SN-9", model="M-2", owner="ACME Ltd")
    lab.add_reference(  # issue 24: with the records in use the stand's reference is on record
        "REF-8305-SIM",
        model="8305",
        serial="SIM-0001",
        certificate_number="PTB-1",
        calibration_date=date(2026, 1, 1),
        due_date=date(2099, 1, 1),
        table=[(160.0, 1.0, 0.005, None)],
    )
    choice = DutChoice(sensor="SN-9", db=url, records=True, tolerance_percent=None)
    request, notes = build_request(choice, periods=3, out=tmp_path / "runs")
    assert request.dut_id == "SN-9" and request.level_ms2 == 4.0
    assert request.nominal_mv_per_ms2 == 10.0 and request.tolerance_percent == 3
    assert request.tolerances("sim", 160.0).phase == (Band(20.0, 2000.0, 1.5),)
    assert notes[0] == "sensor SN-9: Maker M-2, owner ACME Ltd"
    # what the operator states wins over the record
    stated, _ = build_request(
        DutChoice(sensor="SN-9", db=url, records=True, level_ms2=2.0, nominal_mv_per_ms2=9.0)
    )
    assert stated.level_ms2 == 2.0
    assert stated.tolerances("sim", 160.0).nominal_sensitivity_mv_per_ms2 == 9.0


def test_run_identity_serialises_as_config_json_always_did() -> None:
    request = RunRequest(dut="piezo", dut_id="SN-1", nominal_mv_per_ms2=10.0, level_ms2=4.0)
    expected = {
        "dut": {"catalogue": "piezo", "id": "SN-1", "nominal_sensitivity_mv_per_ms2": 10.0},
        "level_ms2": 4.0,
    }
    assert json.dumps(request.identity("sim").to_dict()) == json.dumps(expected)
    assert request.identity("nidaqmx").to_dict()["dut"]["catalogue"] is None
    assert RunIdentity().to_dict() == {}
    again = RunIdentity.from_dict({**expected, "measuring_amplifier": {"gain": 10.0}})
    assert again.dut == DutIdentity("piezo", "SN-1", 10.0)
    assert again.to_dict() == {**expected, "measuring_amplifier": {"gain": 10.0}}


def test_a_spec_the_face_resolved_is_used_as_it_is() -> None:
    # the GUI's records link read the sensor already: no second look-up (this URL would fail)
    choice = DutChoice(sensor="SN-1", db="sqlite:////nonexistent/lab.sqlite", spec=RECORDED)
    resolved = resolve_dut(choice, "sim", {})
    assert resolved.spec is RECORDED and resolved.dut_id == "SN-1"
    assert resolved.nominal_mv_per_ms2 == 9.8 and resolved.tolerance_percent == 4.0
    assert resolved.level_ms2 == 4.0 and resolved.preset == "piezo"


def test_phases_given_with_the_request_are_the_plans() -> None:
    phases = tuple(0.1 * k for k in range(3))
    request = RunRequest(preset="piezo", frequencies_hz=(40.0, 80.0, 160.0), phases_rad=phases)
    plan = request_plan(request)  # the request is a plain value: its plan is made by run
    assert tuple(plan.phases_rad) == pytest.approx(phases)
    assert tuple(plan.nominal_frequencies_hz) == (40.0, 80.0, 160.0)
