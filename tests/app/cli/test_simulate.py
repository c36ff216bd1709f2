"""`accelcal simulate` then `accelcal analyze`: the simulated truth recovered within U."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from app.io.hdf5 import read_recording
from app.procedure.analysis import analyze
from app.procedure.simulate import simulate


def within(results, truth) -> tuple[np.ndarray, np.ndarray]:
    s = np.array([ln.sensitivity_mv_per_ms2 for ln in results.lines])
    u = np.array([ln.expanded_uncertainty_mv_per_ms2 for ln in results.lines])
    phase = np.array([ln.phase_deg for ln in results.lines])
    u_phase = np.array([ln.phase_expanded_uncertainty_deg for ln in results.lines])
    phase_error = (phase - truth.phase_deg + 180) % 360 - 180
    return np.abs(s - truth.sensitivity_mv_per_ms2) <= u, np.abs(phase_error) <= u_phase


@pytest.mark.parametrize(
    ("dut", "level", "seed"),
    [("piezo", 5.0, 11), ("capacitive", 7.0, 12), ("loose", 5.0, 13), ("piezo", 3.0, 14)],
)
def test_truth_within_the_stated_uncertainty(tmp_path, dut, level, seed):
    """Stand at its nominal values: physics, noise and the estimator must stay within U at
    every line but the odd one (the budget's type B part is then conservative)."""
    run = simulate(
        tmp_path / "rec.h5", dut=dut, level_ms2=level, periods=8, seed=seed, systematic=False
    )
    recording = read_recording(run.path)
    assert recording.truth is not None and recording.drive_v is not None
    assert recording.settle_periods == 3 and recording.periods == 11
    results = analyze(recording).results
    magnitude_ok, phase_ok = within(results, recording.truth)
    assert magnitude_ok.mean() >= 0.95, magnitude_ok
    assert phase_ok.mean() >= 0.95, phase_ok
    # the estimate is not simply vague: it resolves the DUT's response
    if dut == "capacitive":
        lines = {ln.nominal_frequency_hz: ln for ln in results.lines}
        assert lines[200.0].sensitivity_mv_per_ms2 / lines[10.0].sensitivity_mv_per_ms2 == (
            pytest.approx(2**-0.5, rel=0.02)
        )


@pytest.mark.parametrize("dut", ["piezo", "capacitive"])
def test_truth_within_u_with_the_stand_drawing_its_systematic_deviations(tmp_path, dut):
    """The stand draws its deviations from its budget per seed; the analysis knows only the
    certificate and nominal values. Deviations are common to all lines of a run, so the check
    is pooled over seeds (the full coverage statistics are in bench/coverage.py)."""
    inside = []
    for seed in range(21, 27):
        run = simulate(tmp_path / f"{seed}.h5", dut=dut, level_ms2=5.0, periods=4, seed=seed)
        recording = read_recording(run.path)
        magnitude_ok, phase_ok = within(analyze(recording).results, recording.truth)
        inside += [magnitude_ok.mean(), phase_ok.mean()]
    assert np.mean(inside) >= 0.9, inside


def test_dead_dut_is_refused_by_the_analysis(tmp_path, capsys):
    assert main(["simulate", "--dut", "dead", "--out", str(tmp_path / "d.h5")]) == 0
    capsys.readouterr()
    assert main(["analyze", str(tmp_path / "d.h5")]) == 2
    assert "DUT channel: no signal at most lines" in capsys.readouterr().err


def test_cli_simulate_list_json_and_errors(tmp_path, capsys):
    assert main(["simulate", "--list"]) == 0
    out = capsys.readouterr().out
    assert "capacitive" in out and "loose" in out and "150 Hz" in out
    assert (
        main(
            [
                "simulate",
                "--dut",
                "piezo",
                "--periods",
                "2",
                "--seed",
                "1",
                "--json",
                "--out",
                str(tmp_path / "p.h5"),
            ]
        )
        == 0
    )
    summary = json.loads(capsys.readouterr().out)
    assert summary["periods"] == 2 and summary["ranges_v"]["reference"] == 1.0
    assert main(["analyze", str(tmp_path / "p.h5"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["periods"] == 2
    for argv, message in [
        (["--dut", "nope", "--out", "x.h5"], "--dut: 'nope' is not in the DUT catalogue"),
        (["--dut", "piezo"], "--out: the recording to write is required"),
        (["--out", "x.csv"], "must end in .h5"),
        (["--fault", "meteor@1", "--out", str(tmp_path / "f.h5")], "unknown kind"),
        (["--level", "500", "--out", str(tmp_path / "l.h5")], "--level"),
    ]:
        assert main(["simulate", *argv]) == 2, argv
        assert message in capsys.readouterr().err


def test_injected_fault_stops_the_simulation_with_its_error(tmp_path, capsys):
    code = main(["simulate", "--fault", "device-lost@7", "--out", str(tmp_path / "f.h5")])
    assert code == 3  # an aborted recording, as an aborted run (README's exit codes; issue 27)
    assert "DeviceLostError" in capsys.readouterr().err
    partial = read_recording(tmp_path / "f.h5")  # what was acquired is still readable
    assert partial.periods == 3 and partial.status == "aborted"
