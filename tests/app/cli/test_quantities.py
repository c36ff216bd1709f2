"""Quantities as people write them (issue 31 point 3): a number with its unit read through
pint (app.io.quantities), the same for every option; percent options read a bare number as
percent; hostile input refused naming the option, exit 2."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from app.cli import build_parser, main
from app.io import quantities
from app.io.quantities import (
    STANDARD_GRAVITY_MS2,
    QuantityError,
    parse_frequency,
    parse_level,
    parse_mass,
    parse_percent,
    parse_seconds,
    parse_sensitivity,
    parse_tolerance,
)


@pytest.mark.parametrize(
    ("parse", "text", "expected"),
    [
        (parse_level, "5", 5.0),
        (parse_level, " 5 ", 5.0),
        (parse_level, "0.5g", 4.903325),
        (parse_level, "0.5 g", 4.903325),
        (parse_level, "0.5 gn", 4.903325),
        (parse_level, ".5g", 4.903325),
        (parse_level, "5 m/s^2", 5.0),
        (parse_level, "5 m/s²", 5.0),
        (parse_level, "5 m/s**2", 5.0),
        (parse_level, "2e1 m/s^2", 20.0),
        (parse_sensitivity, "10.2", 10.2),
        (parse_sensitivity, "100mV/g", 100 / STANDARD_GRAVITY_MS2),
        (parse_sensitivity, "100 mV/g", 100 / STANDARD_GRAVITY_MS2),
        (parse_sensitivity, "0.1 V/g", 100 / STANDARD_GRAVITY_MS2),
        (parse_sensitivity, "10 mV/(m/s^2)", 10.0),
        (parse_seconds, "45", 45.0),
        (parse_seconds, "30s", 30.0),
        (parse_seconds, "2 min", 120.0),
        (parse_seconds, "2min", 120.0),
        (parse_seconds, "1.5h", 5400.0),
        (parse_seconds, "500 ms", 0.5),
        (parse_frequency, "160", 160.0),
        (parse_frequency, "1.6 kHz", 1600.0),
        (parse_mass, "25", 25.0),  # a bare mass is in gram
        (parse_mass, "25 g", 25.0),  # and g is the gram for a mass, not gravity
        (parse_mass, "0.1 kg", 100.0),
        (parse_percent, "0.2", 0.2),  # a bare number is percent: never 20 %
        (parse_percent, "0.2%", 0.2),
        (parse_percent, "0.2 %", 0.2),
        (parse_percent, "2000 ppm", 0.2),
        (parse_tolerance, "5", 5.0),
        (parse_tolerance, "5%", 5.0),
    ],
)
def test_a_quantity_is_read_in_the_unit_the_program_works_in(parse, text, expected):
    assert parse(text, "--x") == pytest.approx(expected, rel=1e-12)


def test_standard_gravity_is_exact():
    assert parse_level("1g", "--level") == 9.80665
    assert parse_sensitivity("100mV/g", "--n") == pytest.approx(10.197162129779, rel=1e-12)


@pytest.mark.parametrize(
    ("parse", "text", "reason"),
    [
        (parse_level, "nan", "must be a finite number, got 'nan'"),
        (parse_level, "inf", "must be a finite number"),
        (parse_level, "-inf g", "'-inf g' is not a number nor an acceleration"),
        (parse_level, "1e400", "must be a finite number"),
        (parse_level, "1e400 g", "must be a finite number"),
        (parse_level, "0.5gg", "'0.5gg' is not an acceleration (m/s^2 or g): unknown unit 'gg'"),
        (parse_level, "g/s", "'g/s' is not an acceleration (m/s^2 or g)"),
        (parse_level, "5 kg", "kg is a mass"),
        (parse_level, "5 mg", "mg is a mass"),  # milligram, not milli-gravity
        (parse_level, "5 Hz", "Hz is a frequency"),
        (parse_level, "-5", "must be in (0, 1000] m/s^2, got -5"),
        (parse_level, "-0.5g", "must be in (0, 1000] m/s^2, got -0.5g = -4.90332 m/s^2"),
        (parse_level, "0", "must be in (0, 1000] m/s^2"),
        (parse_level, "200 g", "must be in (0, 1000] m/s^2, got 200 g = 1961.33 m/s^2"),
        (parse_level, "five", "'five' is not a number nor an acceleration"),
        (parse_level, "g", "'g': a number is missing"),
        (parse_level, "", "empty"),
        (parse_level, "5 g*2", "cannot be read as a unit"),  # no arithmetic
        (parse_level, "2**10**10", "cannot be read as a unit"),
        (parse_level, "1/2", "cannot be read as a unit"),
        (parse_level, "__import__('os')", "is not a number nor an acceleration"),
        (parse_level, "5 " + "m" * 80, "too long for a quantity"),
        (parse_sensitivity, "10 pC/(m/s^2)", "is a charge sensitivity"),
        (parse_sensitivity, "10 pC/g", "is a charge sensitivity"),
        (parse_sensitivity, "10 mV", "mV is a voltage"),
        (parse_sensitivity, "0 mV/g", "must be in (0, 1e+06] mV/(m/s^2)"),
        (parse_seconds, "48h", "must be in (0, 24 h], got 48h = 172800 s"),
        (parse_seconds, "5 Hz", "'5 Hz' is not a time (s, min or h): Hz is a frequency"),
        (parse_seconds, "-30s", "must be in (0, 24 h]"),
        (parse_frequency, "5 s", "s is a time"),
        (parse_mass, "5 m/s^2", "m/s^2 is an acceleration"),
        (parse_percent, "0%", "must be in (0, 100] %, got 0%"),
        (parse_percent, "150", "must be in (0, 100] %, got 150"),
        (parse_percent, "0.2 g", "is not a percentage"),
        (parse_percent, "nan%", "is not a number nor a percentage"),
    ],
)
def test_a_bad_quantity_is_refused_naming_the_option_and_why(parse, text, reason):
    with pytest.raises(QuantityError) as caught:
        parse(text, "--opt")
    assert str(caught.value).startswith("--opt: ")
    assert reason in str(caught.value)
    assert caught.value.option == "--opt" and reason in caught.value.reason


@pytest.mark.integration  # a fresh interpreter
def test_bare_numbers_never_import_pint():
    """Commands given plain numbers do not pay for the units library (issue 31: lazy)."""
    code = (
        "import sys; from app.cli import build_parser; "
        "a = build_parser().parse_args(['run', '--level', '5', '--tolerance', '5', "
        "'--nominal-sensitivity', '10.2']); "
        "from app.io.quantities import parse_percent; parse_percent('0.2', '--t'); "
        "print('pint' in sys.modules)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


def test_the_registry_is_built_once():
    assert quantities.registry() is quantities.registry()


def test_the_run_options_take_units():
    args = build_parser().parse_args(
        [
            "run",
            "--level", "0.5g",
            "--nominal-sensitivity", "100mV/g",
            "--tolerance", "5%",
            "--dut-mass", "0.025 kg",
            "--sample-rate", "51.2 kHz",
            "--reference-frequency", "160 Hz",
            "--fade-in", "500 ms",
        ]
    )  # fmt: skip
    assert args.level == pytest.approx(4.903325)
    assert args.nominal_sensitivity == pytest.approx(10.197162129779283)
    assert args.tolerance == 5.0
    assert args.dut_mass == pytest.approx(25.0)
    assert args.sample_rate == pytest.approx(51200.0)
    assert args.reference_frequency == 160.0
    assert args.fade_in == pytest.approx(0.5)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["run", "--level", "0.5gg"], "--level: '0.5gg' is not an acceleration (m/s^2 or g)"),
        (["run", "--level", "g/s"], "--level: 'g/s' is not an acceleration (m/s^2 or g)"),
        (["run", "--level", "-1g"], "--level: must be in (0, 1000] m/s^2"),
        (["run", "--level", "1e400"], "--level: must be a finite number"),
        (["run", "--levels", "0.4g,0.5gg"], "--levels: '0.5gg': '0.5gg' is not an acceleration"),
        (["run", "--nominal-sensitivity", "10pC/(m/s^2)"], "--nominal-sensitivity: '10pC"),
        (["run", "--target-ua", "0.2 g"], "--target-ua: '0.2 g' is not a percentage"),
        (["run", "--target-ua", "inf%"], "--target-ua: "),
        (["run", "--target-ua", "-0.2"], "--target-ua: must be in (0, 100] %"),
        (["run", "--max-time", "30 Hz"], "--max-time: '30 Hz' is not a time"),
        (["run", "--tolerance", "5 m"], "--tolerance: '5 m' is not a percentage"),
        (["analyze", "x.csv", "--tolerance", "nan%"], "--tolerance: "),
        (["simulate", "--level", "0.5 kg"], "--level: '0.5 kg' is not an acceleration"),
        (["models", "add", "A", "B", "--nominal", "1", "--unit", "mV/g", "--tolerance",
          "5 s", "--fmin", "1", "--fmax", "2"], "--tolerance: '5 s' is not a percentage"),
    ],
)  # fmt: skip
def test_the_cli_refuses_a_bad_quantity_naming_the_option_exit_2(argv, message, capsys, tmp_path):
    assert main([*argv, "--out", str(tmp_path)] if argv[0] in ("run",) else argv) == 2
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_every_percent_option_states_the_percent_rule(capsys):
    for command in (["run"], ["analyze"], ["models", "add"]):
        assert main([*command, "--help"]) == 0
        out = " ".join(capsys.readouterr().out.split())
        assert "5 and 5% both mean 5 % (a bare number is percent, never a fraction)" in out


def test_target_ua_0_2_is_0_2_percent_in_the_options_the_cli_builds(tmp_path):
    """The run takes the type A target as a fraction: 0.2 % is 0.002, not 0.2."""
    from app.cli.run import run_options
    from app.procedure.options import parse_option

    for text in ("0.2", "0.2%", "2000ppm"):
        argv = ["run", "--target-ua", text, "--max-time", "2min", "--out", str(tmp_path)]
        options = run_options(build_parser().parse_args(argv))
        assert options.target_type_a == pytest.approx(0.002, rel=1e-12), text
        assert options.max_acquisition_s == 120.0
        assert parse_option("target_type_a", text) == options.target_type_a  # the GUI's way
    argv = ["run", "--level", "0.5 g", "--target-ua", "5", "--out", str(tmp_path)]
    options = run_options(build_parser().parse_args(argv))
    assert options.target_type_a == pytest.approx(0.05)
    assert options.level_ms2 == pytest.approx(4.903325, rel=1e-12)
    with pytest.raises(ValueError, match=r"--target-ua: must be in \(0, 100\] %"):
        parse_option("target_type_a", "150")


@pytest.mark.integration
def test_a_run_at_0_5g_runs_at_4_903_m_s2_and_stores_it(tmp_path, capsys):
    """The acceptance line of issue 31: `--level 0.5g` runs at 4.903 m/s^2 (stored in the
    run's config.json), `--target-ua 0.2` is 0.2 %, `100mV/g` is 10.197 mV/(m/s^2)."""
    argv = ["run", "--sim", "--dut", "piezo", "--level", "0.5g", "--target-ua", "0.2"]
    argv += ["--max-time", "2 s", "--nominal-sensitivity", "100mV/g", "--json"]
    assert main([*argv, "--out", str(tmp_path)]) == 0
    record = json.loads(capsys.readouterr().out)
    config = json.loads((tmp_path / record["run_id"] / "config.json").read_text())
    assert config["identity"]["level_ms2"] == pytest.approx(4.903325, rel=1e-12)
    assert config["settings"]["target_type_a"] == pytest.approx(0.002, rel=1e-12)
    assert config["settings"]["max_acquisition_s"] == 2.0
    assert config["settings"]["dut_nominal_mv_per_ms2"] == pytest.approx(10.197162, rel=1e-6)
