"""Issue 34 point 1: the one-period LPM is the default estimator of a new multisine run; a
stored run is read and re-analysed with the estimator it names."""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.cli.readers import recorded_estimator
from app.procedure.options import RunOptions
from app.records.run_folder import load_run
from dsp.estimators import DEFAULT_ESTIMATOR, Estimator, default_periods

EXAMPLE_RUN = Path(__file__).resolve().parents[3] / "examples" / "runs"
LEGACY_RUNS = Path(__file__).resolve().parents[2] / "data" / "legacy" / "runs"
LEGACY_RUN = LEGACY_RUNS / "20261125T061413Z-LEG-1-2d8db0"


def test_the_default_estimator_is_the_lpm_with_one_period():
    assert DEFAULT_ESTIMATOR == Estimator.LPM
    assert RunOptions().estimator == Estimator.LPM and RunOptions().periods_to_run == 1
    assert RunOptions(estimator=Estimator.PERIODIC).periods_to_run == 8
    assert [default_periods(e) for e in Estimator] == [8, 8, 8, 1]


def test_the_command_lines_estimator_follows_the_mode_when_not_given():
    """A stepped sine has no lpm (a multisine record's estimator): not given, it is periodic;
    given, the refusal stands (tests/app/procedure/test_service.py)."""
    from app.cli.parser import build_parser

    def options(*argv: str) -> RunOptions:
        return RunOptions.from_values(vars(build_parser().parse_args(["run", "--sim", *argv])))

    assert options().estimator == Estimator.LPM and options().periods_to_run == 1
    stepped = options("--mode", "stepped-sine")
    assert stepped.estimator == Estimator.PERIODIC and stepped.periods_to_run == 8
    assert options("--estimator", "h1").estimator == Estimator.H1
    assert options("--mode", "stepped-sine", "--estimator", "lpm").estimator == Estimator.LPM


def _json_run(capsys, out: Path, *more: str) -> dict:
    code = main(["run", "--sim", "--dut", "piezo", "--target-ua", "0.2%", "--out", str(out),
                 "--json", *more])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out)


@pytest.mark.slow  # reason: two simulated runs through the CLI (10-20 s on two shared cores)
def test_a_run_without_an_estimator_option_is_the_one_period_lpm_and_fast_warm(tmp_path, capsys):
    """The acceptance's command, cold then warm: the lpm from one period; warm 2.55 s of
    excitation (the 0.3 s check burst of the stored response, 0.1 s fade-in, the 2 s period,
    0.15 s fade-out), cold 6.75 s; every line within the bound of tests/within_u.py."""
    from app.io.hdf5 import read_recording
    from tests.within_u import assert_consistent_with_u

    out = tmp_path / "runs"
    cold = _json_run(capsys, out)
    warm = _json_run(capsys, out)
    for run in (cold, warm):
        assert run["settings"]["estimator"] == "lpm" and run["results"]["estimator"] == "lpm"
        assert run["results"]["periods"] == 1
        truth = read_recording(out / run["run_id"] / "recording.h5").truth
        lines = run["results"]["lines"]
        s = np.array([line["sensitivity_mv_per_ms2"] for line in lines])
        u = np.array([line["expanded_uncertainty_mv_per_ms2"] for line in lines])
        k = np.array([line["coverage_factor"] for line in lines])
        assert_consistent_with_u(("magnitude", s - truth.sensitivity_mv_per_ms2, u, k))
    assert warm["stand_response"]["source"] == "stored"
    assert warm["excitation_time_s"] <= 2.56 and cold["excitation_time_s"] <= 7.0


def test_a_stored_periodic_run_reads_and_analyses_as_periodic(tmp_path, capsys):
    """The example run (periodic, 8 periods, stored before the default changed): its
    results.json names periodic, and `analyze` without --estimator gives exactly what
    `--estimator periodic` gives, not what another estimator (h1) gives."""
    folder = next(EXAMPLE_RUN.iterdir())
    assert load_run(folder).analysis.estimator == Estimator.PERIODIC
    outputs = {}
    for name, extra in (("default", []), ("periodic", ["--estimator", "periodic"]),
                        ("h1", ["--estimator", "h1"])):  # fmt: skip
        assert main(["analyze", str(folder), "--json", *extra]) == 0
        outputs[name] = json.loads(capsys.readouterr().out)
    assert outputs["default"] == outputs["periodic"]
    assert outputs["default"]["estimator"] == "periodic"
    assert outputs["h1"]["estimator"] == "h1" and outputs["h1"] != outputs["periodic"]


def test_the_estimator_analyze_uses_is_the_one_the_recording_names(tmp_path):
    def args(file: Path, estimator: str | None = None, segments: int | None = None):
        return argparse.Namespace(file=file, estimator=estimator, segments=segments)

    example = next(EXAMPLE_RUN.iterdir())
    assert recorded_estimator(args(example)) == Estimator.PERIODIC
    assert recorded_estimator(args(example / "recording.h5")) == Estimator.PERIODIC
    assert recorded_estimator(args(LEGACY_RUN)) == Estimator.PERIODIC
    assert recorded_estimator(args(example, "h1")) == Estimator.H1  # the option wins
    copy = tmp_path / example.name
    shutil.copytree(example, copy)
    config = json.loads((copy / "config.json").read_text())
    config["settings"]["estimator"] = "lpm"
    (copy / "config.json").write_text(json.dumps(config))
    assert recorded_estimator(args(copy)) == Estimator.LPM
    assert recorded_estimator(args(copy, segments=8)) == Estimator.PERIODIC  # seed's protocol
    del config["settings"]["estimator"]  # a run from before the setting
    (copy / "config.json").write_text(json.dumps(config))
    assert recorded_estimator(args(copy)) == Estimator.PERIODIC
    assert recorded_estimator(args(tmp_path / "recording.csv")) == Estimator.PERIODIC


@pytest.mark.slow  # reason: one simulated run through the CLI
def test_a_stored_lpm_run_analyses_as_lpm_to_the_same_numbers(tmp_path, capsys):
    """A new run (lpm, one period) re-analysed by `accelcal analyze <run folder>` without
    --estimator: the lpm, to the numbers the run stored (its recorded drive, the ADC's
    quantised loopback, is not taken for a fade: dsp.lpm's drive check)."""
    out = tmp_path / "runs"
    run = _json_run(capsys, out)
    assert main(["analyze", str(out / run["run_id"]), "--json"]) == 0
    analysed = json.loads(capsys.readouterr().out)
    assert analysed["estimator"] == "lpm"
    stated = [line["sensitivity_mv_per_ms2"] for line in run["results"]["lines"]]
    again = [line["sensitivity_mv_per_ms2"] for line in analysed["lines"]]
    assert again == pytest.approx(stated, rel=1e-9)
