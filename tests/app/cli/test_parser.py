"""The `accelcal plan` and `accelcal analyze` commands: output, exit codes, messages."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from app.cli import main, parse_frequencies
from app.io.hdf5 import write_recording
from app.procedure.phase_store import stored_phases
from dsp import iso266
from dsp.multisine import preset_plan
from dsp.uncertainty import Budget, Component, Distribution
from tests.synthetic import lowpass_response, make_recording
from tests.within_u import assert_consistent_with_u


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_plan_json_has_the_documented_keys(capsys):
    code, out, _ = run(capsys, "plan", "--preset", "piezo", "--json")
    assert code == 0
    data = json.loads(out)
    for key in (
        "sample_rate_hz",
        "period_samples",
        "crest_factor",
        "peak_displacement_m",
        "peak_velocity_m_per_s",
        "peak_acceleration_ms2",
    ):
        assert key in data
    assert data["crest_factor"] <= 2.62  # lines moved off the mains harmonics (issue 32)
    assert len(data["lines"]) == 25
    line = data["lines"][1]
    assert (line["nominal_frequency_hz"], line["frequency_hz"], line["bin"]) == (12.5, 12.5, 25)
    line = data["lines"][7]  # 50 Hz, stated at its actual frequency
    assert (line["nominal_frequency_hz"], line["frequency_hz"], line["bin"]) == (50, 50.5, 101)
    code, out, _ = run(capsys, "plan", "--preset", "piezo", "--json", "--exact-mains-bins")
    exact = json.loads(out)
    assert exact["crest_factor"] <= 2.5 and exact["lines"][7]["frequency_hz"] == 50.0


def test_plan_human_output_lists_lines_and_warnings(capsys):
    code, out, _ = run(capsys, "plan", "--preset", "capacitive")
    assert code == 0
    assert "27 lines" in out and "Crest factor" in out and "4000" in out
    assert (  # grouped (#27)
        "warning: 4 lines moved one bin off a mains harmonic: 50, 100, 200, 250 Hz; each stated "
        "at its actual frequency" in out
    )
    code, out, _ = run(capsys, "plan", "--preset", "capacitive", "--exact-mains-bins")
    assert "warning: 4 lines on a mains harmonic: 50, 100, 200, 250 Hz" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--frequencies", "10,160,2700"], "line 2700 Hz: at or above 0.45 fs"),
        (["--frequencies", "10,20,40"], "reference frequency 160 Hz: not among the lines"),
        (["--frequencies", "10,abc"], "--frequencies: 'abc' is not a number"),
        (["--frequencies", "...,160"], "'...' must stand between two frequencies"),
        (["--level", "-1"], "--level: must be in (0, 1000] m/s^2"),
    ],
)
def test_plan_bad_input_exits_2_with_the_reason(capsys, argv, message):
    code, _, err = run(capsys, "plan", *argv)
    assert code == 2
    assert message in err


def test_frequency_ellipsis_fills_iso_266_values():
    assert parse_frequencies("10,12.5,...,2500") == list(iso266.nominal_frequencies(10, 2500))
    assert parse_frequencies("10, 20 ,160") == [10.0, 20.0, 160.0]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A piezo-plan recording of a known low-pass DUT with noise and a type B budget, on the
    seed's exact bins (its segment protocol; a CSV of it is analysed --exact-mains-bins)."""
    plan = preset_plan("piezo", shift_mains_lines=False, optimiser=stored_phases)
    budget = Budget((Component("reference calibration", 0.01, Distribution.NORMAL),))
    rec = make_recording(
        plan,
        lowpass_response(),
        periods=8,
        reference_noise_v=2e-4,
        dut_noise_v=2e-3,
        budget=budget,
        seed=4,
    )
    path = tmp_path_factory.mktemp("rec") / "recording.h5"
    write_recording(path, rec)
    return path, rec


def test_analyze_recovers_the_known_response_within_its_uncertainty(capsys, recorded):
    path, rec = recorded
    code, out, _ = run(capsys, "analyze", str(path), "--json")
    assert code == 0
    data = json.loads(out)
    truth = np.abs(lowpass_response()(rec.plan.frequencies_hz))
    got = np.array([ln["sensitivity_mv_per_ms2"] for ln in data["lines"]])
    u = np.array([ln["expanded_uncertainty_mv_per_ms2"] for ln in data["lines"]])
    k = np.array([ln["coverage_factor"] for ln in data["lines"]])
    assert_consistent_with_u(("magnitude", got - truth, u, k))  # tests/within_u.py
    assert data["reference"]["coverage_factor"] == pytest.approx(2.0, abs=0.05)


def test_analyze_human_output(capsys, recorded):
    code, out, err = run(capsys, "analyze", str(recorded[0]))
    assert code == 0
    assert "no type B budget" not in err  # the recording carries its budget
    assert "Reference sensitivity at 160 Hz:" in out and "k = " in out and "p = 95.45 %" in out


def test_analyze_csv_with_options_and_seed_segments(capsys, recorded, tmp_path):
    _, rec = recorded
    path = tmp_path / "rec.csv"
    n = 12000  # the seed's protocol: one 2 s record
    np.savetxt(
        path,
        np.column_stack([rec.reference_v[:n], rec.dut_v[:n]]),
        delimiter=",",
        header="reference,dut",
        comments="",
    )
    common = [
        "analyze",
        str(path),
        "--sample-rate",
        "6000",
        "--period",
        "12000",
        "--frequencies",
        "10,12.5,...,2500",
        "--reference-sensitivity",
        "1.0",
        "--reference-frequency",
        "160",
        "--exact-mains-bins",
        "--json",
    ]
    code, out, err = run(capsys, *common, "--segments", "8", "--estimator", "seed")
    assert code == 0, err
    data = json.loads(out)
    assert data["periods"] == 8 and data["estimator"] == "seed"
    assert "warning: no type B budget (--budget): U is stated from type A (noise) only" in err
    assert any("off the 4 Hz segment grid" in w and "12.5 Hz" in w for w in data["warnings"])
    ref = data["reference"]["sensitivity_mv_per_ms2"]
    assert ref == pytest.approx(abs(lowpass_response()(np.array([160.0]))[0]), rel=0.02)
    code, _, err = run(capsys, *common, "--segments", "32")
    assert code == 2
    assert "line 12.5 Hz: shares the 16 Hz bin of line 10 Hz at 32 segments" in err


def test_analyze_refuses_bad_files_and_options(capsys, recorded, tmp_path):
    code, _, err = run(capsys, "analyze", str(tmp_path / "missing.h5"))
    assert code == 2 and "no such file" in err
    code, _, err = run(capsys, "analyze", str(recorded[0]), "--frequencies", "10,160")
    assert code == 2 and "--frequencies: not allowed with an HDF5 recording" in err
    csv = tmp_path / "x.csv"
    csv.write_text("1,2\n")
    code, _, err = run(capsys, "analyze", str(csv), "--reference-sensitivity", "1")
    assert code == 2 and "needs its plan" in err
    code, _, err = run(capsys, "analyze", str(csv), "--preset", "piezo")
    assert code == 2 and "--reference-sensitivity" in err


def test_budget_file_for_csv(capsys, recorded, tmp_path):
    _, rec = recorded
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack([rec.reference_v, rec.dut_v]), delimiter=",")
    budget = tmp_path / "budget.toml"
    budget.write_text(
        '[[component]]\nname = "DAQ gain"\nvalue = 0.003\ndistribution = "rectangular"\n'
    )
    code, out, err = run(
        capsys,
        "analyze",
        str(path),
        "--preset",
        "piezo",
        "--reference-sensitivity",
        "1",
        "--budget",
        str(budget),
        "--json",
    )
    assert code == 0, err
    assert json.loads(out)["lines"][0]["relative_type_b"] == pytest.approx(0.003 / 3**0.5)
    budget.write_text('[[component]]\nname = "DAQ gain"\nvalue = -1\n')
    code, _, err = run(
        capsys,
        "analyze",
        str(path),
        "--preset",
        "piezo",
        "--reference-sensitivity",
        "1",
        "--budget",
        str(budget),
    )
    assert code == 2 and "DAQ gain" in err and "value" in err


def test_console_script_and_module_entry_point_help():
    for argv in (["-m", "app", "--help"], ["-m", "app", "analyze", "--help"]):
        done = subprocess.run([sys.executable, *argv], capture_output=True, text=True)
        assert done.returncode == 0 and "usage:" in done.stdout


def test_devices_without_the_ni_driver_says_so_and_exits_non_zero(capsys):
    code = main(["devices"])
    out = capsys.readouterr().out
    assert code == 1
    assert "NI-DAQmx is not installed" in out


def _numeric_actions():
    """(command, action) for every option of every command that takes a typed value."""
    import argparse

    from app.cli import build_parser

    def walk(parser: argparse.ArgumentParser, name: str):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for command, p in action.choices.items():
                    yield from walk(p, f"{name} {command}".strip())
            elif action.option_strings and action.type is not None:
                yield name, action

    commands = {command.split()[0] for command, _ in walk(build_parser(), "")}
    assert {"run", "analyze", "simulate", "sensors", "due", "models"} <= commands
    yield from walk(build_parser(), "")


def test_every_numeric_option_is_bounded_and_its_help_says_so():
    from app.cli import Bounded
    from app.cli.options import QuantityType

    seen = 0
    for command, action in _numeric_actions():
        assert action.type not in (int, float), f"{command} {action.option_strings[0]}: unbounded"
        if isinstance(action.type, Bounded | QuantityType):
            seen += 1
            assert action.type.describe() in action.help.replace("%%", "%"), action.help
    assert seen >= 38


@pytest.mark.parametrize(
    "argv",
    [["--skew", "-2e-06"], ["--skew=-2e-06"], ["--skew", "-2E-6"], ["--skew", "-.000002"]],
)
def test_negative_numbers_are_option_values(argv):
    from app.cli import build_parser

    args = build_parser().parse_args(["analyze", "x.csv", *argv])
    assert args.skew == pytest.approx(-2e-6)


def test_help_states_the_bounds(capsys):
    assert main(["run", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())  # argparse wraps the help lines
    for text in ("(0, 1000] m/s^2", "[1, 10000]", "(0, 100] %", "(0, 24 h]"):
        assert text in out


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"nominal_mv_per_ms2": 0.0}, "nominal sensitivity: must be > 0"),
        ({"nominal_mv_per_ms2": -2.0}, "nominal sensitivity: must be > 0"),
        ({"nominal_mv_per_ms2": float("nan")}, "nominal sensitivity: must be > 0"),
        ({"dut": "nosuch"}, "dut: 'nosuch' is not in the DUT catalogue"),
        ({"level_ms2": float("inf")}, "level: must be > 0"),
        ({"periods": 0}, "periods: at least 1"),  # the lpm (the default since issue 34)
        ({"periods": 1, "estimator": "periodic"}, "periods: at least 2"),
    ],
)
def test_a_bad_request_never_reaches_the_stand(monkeypatch, tmp_path, change, message):
    """The GUI builds RunRequests itself: the same refusals, before the stand is loaded."""
    from app.procedure import PreflightError
    from app.procedure import run as run_module
    from app.procedure.run import RunRequest

    def no_stand(*args, **kwargs):
        raise AssertionError("the stand was loaded")

    from app.stand import config as stand_config  # the request loads it (RunRequest.stand_config)

    monkeypatch.setattr(stand_config, "load", no_stand)
    with pytest.raises(PreflightError, match=message.replace("(", r"\(")):
        run_module.prepare(RunRequest(out=tmp_path / "runs", **change))
    assert not (tmp_path / "runs").exists()
