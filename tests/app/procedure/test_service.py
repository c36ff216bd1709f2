"""The run service (app.procedure.service, issue 31 point 1): the stand file loaded once, the
stand's [plan] applied before any phase, the preview is the plan that will run, the options
table is the CLI's, the request a plain value, and the exit status of a FAIL verdict."""

from __future__ import annotations

import argparse
import json
from importlib import resources
from pathlib import Path

import pytest

from app.cli import main
from app.cli.parser import build_parser
from app.procedure.options import RUN_OPTIONS, RunOptions, option, parse_option
from app.procedure.outcome import ExitStatus, exit_status
from app.procedure.request import RequestError, RunRequest
from app.procedure.service import RunService, check_options, records_in_use
from app.records.run_record import RunRecord
from app.stand import config as stand_config

FIVE_LINES = (40.0, 80.0, 160.0, 315.0, 630.0)


def _stand_with_plan(tmp_path: Path, lines: tuple[float, ...] = FIVE_LINES) -> Path:
    stand = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
    path = tmp_path / "stand.toml"
    text = ", ".join(f"{f:g}" for f in lines)
    path.write_text(f"{stand}\n[plan]\nfrequencies_hz = [{text}]\n", encoding="utf-8")
    return path


def test_the_preview_is_the_stand_files_plan_and_an_options_lines_win(tmp_path):
    service = RunService(_stand_with_plan(tmp_path))
    preview = service.preview(RunOptions(preset="piezo", level_ms2=5.0))
    assert preview.ok and preview.lines_hz == FIVE_LINES
    assert preview.plan is not None and len(preview.plan.phases_rad) == 5
    assert preview.report is not None
    assert preview.report.peaks.acceleration_ms2 == pytest.approx(
        preview.plan.predicted_peaks().acceleration_ms2
    )  # at the run's level, not scaled afterwards
    own = service.preview(RunOptions(frequencies_hz=(80.0, 160.0, 315.0)))
    assert own.lines_hz == (80.0, 160.0, 315.0)


def test_the_phase_key_is_the_stand_files_lines_at_any_level(tmp_path):
    service = RunService(_stand_with_plan(tmp_path))
    key = service.phase_key(RunOptions(level_ms2=2.0))
    assert key == service.phase_key(RunOptions(level_ms2=7.0))
    assert key.frequencies_hz == FIVE_LINES and key.level_ms2 == 1.0


def test_phases_of_other_lines_are_never_used(tmp_path):
    """The defect behind "phases: 25 values for 5 lines": phases optimised for the preset's
    lines handed to a run of the stand file's lines. The service uses a face's phases only
    when they are the plan of the lines that will run."""
    service = RunService(_stand_with_plan(tmp_path))
    options = RunOptions(records=False, out=tmp_path / "runs")
    preset = RunService(None).unit_plan(RunService(None).phase_key(RunOptions()))
    assert len(preset.lines) != 5
    assert service.prepare(options, unit_plan=preset).request.phases_rad is None
    right = service.unit_plan(service.phase_key(options))
    prepared = service.prepare(options, unit_plan=right)
    assert prepared.request.phases_rad == pytest.approx(tuple(right.phases_rad))
    assert prepared.request.frequencies_hz == FIVE_LINES  # the stand's [plan], resolved once


def test_the_stand_file_is_loaded_once_per_run(tmp_path, monkeypatch):
    loads: list[object] = []
    real = stand_config.load

    def counted(path=None):
        loads.append(path)
        return real(path)

    monkeypatch.setattr(stand_config, "load", counted)
    stand = _stand_with_plan(tmp_path, (80.0, 160.0, 315.0))
    out = tmp_path / "runs"
    args = ["run", "--stand", str(stand), "--periods", "4", "--out", str(out), "--json"]
    assert main(args) == 0
    assert loads == [stand]


def test_a_fail_verdict_exits_4_with_fail_exit(tmp_path, capsys):
    """`run --fail-exit`: a completed run whose verdict is FAIL exits 4 (the simulated piezo
    is 10.2 mV/(m/s^2): 9 +-5 % fails); without the option it exits 0 as before."""
    out = tmp_path / "runs"
    args = ["run", "--sim", "--frequencies", "80,160,315", "--periods", "4", "--json"]
    args += ["--nominal-sensitivity", "9", "--tolerance", "5", "--out", str(out), "--fail-exit"]
    assert main(args) == 4
    record = json.loads(capsys.readouterr().out)
    assert record["status"] == "complete" and record["verdict"] == "FAIL"
    stored = RunRecord.from_dict(record)
    assert exit_status(stored) == ExitStatus.OK  # without --fail-exit: as before
    assert exit_status(stored, fail_exit=True) == ExitStatus.FAIL_VERDICT


@pytest.mark.parametrize(
    ("status", "verdict", "reason", "fail_exit", "expected"),
    [
        ("complete", "PASS", None, True, 0),
        ("complete", "INDETERMINATE", None, True, 0),
        ("complete", None, None, True, 0),  # no tolerance: no verdict
        ("complete", "FAIL", None, False, 0),
        ("complete", "FAIL", None, True, 4),
        ("aborted", None, "refused before anything moved: level", True, 2),
        ("aborted", None, "stopped by the operator", True, 3),
    ],
)
def test_exit_statuses(status, verdict, reason, fail_exit, expected):
    record = RunRecord(run_id="r", status=status, abort_reason=reason, verdict=verdict)
    assert exit_status(record, fail_exit=fail_exit) == expected


def _run_parser() -> argparse.ArgumentParser:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices["run"]


def test_every_run_option_of_the_table_is_an_option_of_run_with_its_help():
    actions = {s: a for a in _run_parser()._actions for s in a.option_strings}
    for spec in RUN_OPTIONS:
        action = actions[spec.flag]
        assert action.dest == spec.dest
        assert (action.help or "").replace("%%", "%").startswith(spec.help), spec.flag
        if spec.bounds is not None and spec.parse is None:
            assert spec.bounds.describe(spec.unit) in action.help.replace("%%", "%")
        if spec.quantity is not None:  # read with its unit; --help states the range
            assert spec.quantity.describe() in (action.help or "").replace("%%", "%")
            assert action.type("1") == pytest.approx(1.0 / spec.per), spec.flag
    values = vars(_run_parser().parse_args(["--level", "2.5", "--target-ua", "0.2%"]))
    options = RunOptions.from_values(values)
    assert options.level_ms2 == 2.5 and options.target_type_a == pytest.approx(0.002)
    # the defaults: the one-period lpm since issue 34 (periodic and 8 periods before)
    assert options.estimator == "lpm" and options.periods_to_run == 1


def test_one_parser_per_option_names_the_flag():
    assert parse_option("level_ms2", "3") == 3.0
    assert parse_option("periods", "12") == 12
    assert parse_option("max_acquisition_s", "2min") == 120.0
    with pytest.raises(ValueError, match=r"^--level: must be in \(0, 1000\] m/s\^2, got 0$"):
        parse_option("level_ms2", "0")
    with pytest.raises(ValueError, match=r"^--periods: must be in \[1, 10000\]"):
        parse_option("periods", "2.5")
    with pytest.raises(ValueError, match=r"^--estimator: 'x' is not one of periodic, h1"):
        parse_option("estimator", "x")
    assert option("level_ms2").full_help().endswith("(0, 1000] m/s^2")


def test_options_are_typed_and_checked_before_anything_opens(tmp_path):
    assert RunOptions(estimator="lpm").periods_to_run == 1
    with pytest.raises(ValueError, match=r"^mode: 'swept' is not one of multisine"):
        RunOptions(mode="swept")
    with pytest.raises(RequestError, match=r"^--estimator lpm: analyses a multisine record"):
        check_options(RunOptions(estimator="lpm", mode="stepped-sine"))
    with pytest.raises(RequestError, match=r"^--profile velocity: needs --corner \(Hz\)"):
        check_options(RunOptions(profile="velocity"))
    with pytest.raises(RequestError, match=r"^--periods"):
        check_options(RunOptions(estimator="seed", periods=2))


def test_records_in_use(monkeypatch, tmp_path):
    monkeypatch.setenv("ACCELCAL_DB", f"sqlite:///{tmp_path / 'none.sqlite'}")
    assert records_in_use(RunOptions(), lab=object()) is True
    assert records_in_use(RunOptions(records=False)) is False
    assert records_in_use(RunOptions()) is True  # $ACCELCAL_DB names records
    monkeypatch.delenv("ACCELCAL_DB")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))  # no default records file there
    assert records_in_use(RunOptions()) is False
    assert records_in_use(RunOptions(sensor="SN-1")) is True


def test_the_request_is_a_plain_value():
    for factory in ("stand_config", "store", "budget", "plan"):
        assert not hasattr(RunRequest, factory), factory
