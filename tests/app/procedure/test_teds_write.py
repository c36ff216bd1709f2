"""Writing a run's result to the DUT's TEDS (app.procedure.teds_write, `accelcal teds write`): the
sensitivity and date of a complete run written and read back, the sensor on the port checked
against the run's DUT, and writing only after a confirmation."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.cli import main
from app.procedure import teds_write
from app.records.run_folder import load_run
from app.stand import teds as teds_io
from hardware.teds import TedsError, decode


def test_a_complete_run_is_written_to_the_teds_and_read_back(complete_run: Path) -> None:
    record = load_run(complete_run)
    port = teds_io.open_port(None, "piezo", seed=5)
    new = teds_write.calibrated_teds(port.read(), record, "js")
    teds_io.write_checked(port, new)
    assert port.sim.dut_teds.writes == 1
    back = decode(port.read()).accelerometer
    expected = record.results["reference"]["sensitivity_mv_per_ms2"]
    assert back.sensitivity_mv_per_ms2 == pytest.approx(expected, rel=1.5e-4)
    assert str(back.calibration_date) == record.finished_utc[:10]
    assert back.calibration_initials == "JS "


def test_writing_needs_a_confirmation(
    complete_run: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # the simulated piezo's TEDS names serial 10000, the run's DUT is SN-42 (issue 24 point 6)
    assert main(["teds", "write", str(complete_run), "--yes"]) == 2
    captured = capsys.readouterr()
    assert "sensor on simulated" in captured.out and "serial 10000" in captured.out
    assert "the run's DUT is SN-42" in captured.err and "--yes-different-sensor" in captured.err
    other = ["teds", "write", str(complete_run), "--yes-different-sensor", "re-labelled"]
    monkeypatch.setattr("sys.stdin.isatty", lambda: False)
    assert main(other) == 2
    assert "--yes: writing a TEDS needs a confirmation" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin.isatty", lambda: True)
    monkeypatch.setattr("builtins.input", lambda prompt: "n")
    assert main(other) == 0
    captured = capsys.readouterr()
    assert "TEDS not written" in captured.out and "OVERRIDE" not in captured.err
    assert main([*other, "--yes"]) == 0
    captured = capsys.readouterr()
    assert "TEDS written and read back" in captured.out
    assert "OVERRIDE" in captured.err and "override: re-labelled" in captured.err


def test_the_teds_must_name_the_runs_sensor(complete_run: Path) -> None:
    import dataclasses

    from app.records.run_record import DutIdentity

    record = load_run(complete_run)
    teds = decode(teds_io.open_port(None, "piezo", seed=5).read())  # serial 10005
    assert "the run's DUT is SN-42" in teds_write.identity_mismatch(teds, record)
    for serial in ("10005", "SN-10005", f"TEDS-{teds.basic.identity.replace('/', '-')}"):
        same = dataclasses.replace(record, dut=DutIdentity(id=serial))
        assert teds_write.identity_mismatch(teds, same) is None, serial
    assert teds_write.identity_mismatch(teds, record, teds.basic.identity) is None
    other = teds.basic.identity.rsplit("/", 1)[0] + "/10006"
    assert "TEDS identity " + other in teds_write.identity_mismatch(teds, record, other)
    assert teds_write.identity_mismatch(teds, dataclasses.replace(record, dut=None)) is not None


def test_the_plan_names_the_change_and_refuses_a_different_sensor_without_a_reason(
    complete_run: Path,
) -> None:
    record = load_run(complete_run)
    port = teds_io.open_port(None, "piezo", seed=5)  # serial 10005, the run's DUT is SN-42
    plan = teds_write.plan_write(port, record, "js", db=None)
    reference = record.results["reference"]["sensitivity_mv_per_ms2"]
    new = plan.new.accelerometer
    assert new is not None and new.sensitivity_mv_per_ms2 == pytest.approx(reference, rel=1.5e-4)
    assert f"-> {new.sensitivity_mv_per_ms2:.5g} mV/(m/s^2)" in plan.change
    assert f"calibration date {record.finished_utc[:10]}" in plan.change
    assert "serial 10005" in plan.sensor and "the run's DUT is SN-42" in str(plan.mismatch)
    assert "--yes-different-sensor REASON" in str(plan.refusal(None))
    assert plan.refusal("  ") is not None and plan.refusal("re-labelled") is None
    with pytest.raises(TedsError, match="not written"):
        teds_write.write(plan, None, db=None)
    assert port.sim.dut_teds.writes == 0
    said: list[str] = []
    teds_write.write(plan, "re-labelled", db=None, announce=said.append)
    assert port.sim.dut_teds.writes == 1 and len(said) == 1 and "override: re-labelled" in said[0]
