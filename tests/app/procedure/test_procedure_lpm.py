"""Issue 26 points 3-5: the lpm estimator in the procedure, the whole range from the CLI, the
stroke refusal, the resonance search (simulated stand, known truth)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import h5py
import numpy as np
import pytest

from app.cli import main
from app.io.vocabulary import RunStatus
from app.procedure import Procedure, RunSettings
from app.procedure.analysis import analyze, read_for_analysis
from app.procedure.phase_store import stored_phases
from app.procedure.planning import PlanRequest, build_plan, choose_period
from app.procedure.record_run import fade_in_samples
from app.procedure.stopping import Stop, StoppingRule
from app.stand.config import load
from app.stand.open import open_stand
from app.stand.response import ResponseStore
from dsp import iso266
from dsp.multisine import PlanError, preset_plan
from tests.within_u import assert_consistent_with_u

LOW = [
    "--frequencies", "0.4,...,8", "--level", "1.5", "--reference-frequency", "8",
    "--exciter", "long-stroke", "--profile", "displacement", "--corner", "3",
    "--sample-rate", "200", "--nominal-sensitivity", "10.2",  # sizes the DUT's input range
]  # fmt: skip


def _run_folder(out: Path) -> Path:
    (folder,) = [p for p in out.iterdir() if p.is_dir()]
    return folder


def _errors(folder: Path) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """(name, error, U, k) per line, magnitude and phase, against the stand's stored truth,
    for tests.within_u.assert_consistent_with_u."""
    data = json.loads((folder / "results.json").read_text())
    lines = data.get("results", data)["lines"]
    with h5py.File(folder / "recording.h5") as f:
        s_true = f["truth/sensitivity_mv_per_ms2"][:]
        p_true = f["truth/phase_deg"][:]

    def column(key: str) -> np.ndarray:
        return np.array([line[key] for line in lines])

    s, p = column("sensitivity_mv_per_ms2"), column("phase_deg")
    return [
        (
            "magnitude",
            s - s_true,
            column("expanded_uncertainty_mv_per_ms2"),
            column("coverage_factor"),
        ),
        (
            "phase",
            (p - p_true + 180) % 360 - 180,
            column("phase_expanded_uncertainty_deg"),
            column("phase_coverage_factor"),
        ),
    ]


@pytest.mark.integration
def test_low_frequency_run_from_the_cli_is_consistent_with_u_at_every_line(tmp_path, capsys):
    """Every line's error within the bound one realisation meets with probability 0.999
    (tests/within_u.py: 2.1 U here); that 95 % of lines are within U is a claim over many
    runs, benched by `bench/lpm_coverage.py low`."""
    out = tmp_path / "runs"
    code = main(["run", "--sim", *LOW, "--estimator", "lpm", "--fresh-response", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    folder = _run_folder(out)
    config = json.loads((folder / "config.json").read_text())
    nominal = [line["nominal_frequency_hz"] for line in config["plan"]["lines"]]
    assert nominal == list(iso266.nominal_frequencies(0.4, 8))  # 0.5, 0.63, 0.8 kept
    results = json.loads((folder / "results.json").read_text())
    lines = results.get("results", results)["lines"]
    actual = np.array([line["frequency_hz"] for line in lines])
    assert np.all(np.abs(actual / np.array(nominal) - 1) <= 0.02)  # non-uniform grid, stated
    assert not np.allclose(actual, nominal)
    assert_consistent_with_u(*_errors(folder))
    assert "1 period, estimator lpm" in text
    # issue 32 point 5: the 0.4 Hz line is played inside the reference's calibrated range
    # (0.4 Hz up), so it is stated, within U of the truth (this seed), U within ISO's limit
    assert actual[0] >= 0.4 and lines[0]["not_stated"] == ""
    (magnitude, error, expanded, _), *_ = _errors(folder)
    assert magnitude == "magnitude" and abs(error[0]) <= expanded[0]
    # its U carries the converter's resolution (issue 32 point 2: the 0.4 Hz line is some 45 LSB
    # on the DUT's +-0.2 V range at this level, the README's; at 2 m/s^2 the DUT channel needs
    # +-0.5 V, 15 LSB, and the line is not stated), so ISO's 2 % limit is judged on that U
    line = lines[0]
    over = line["relative_expanded_uncertainty"] > line["iso_limit"]
    assert line["iso_verdict"] == ("over" if over else "within")
    # ... with the long-stroke exciter's own budget: its rocking mode, guidance errors and
    # the reference's low-frequency term, not the small exciter's terms growing above 2 kHz
    names = {c["name"] for c in results["budget"]}
    assert "transverse motion: long-stroke rocking mode (60 Hz)" in names
    assert "reference frequency response below 2 Hz (high-pass, interpolation)" in names
    assert "transverse motion" not in names


@pytest.mark.integration
def test_wide_plan_at_51k2_is_consistent_with_u_at_every_line(tmp_path, capsys):
    """Every line within the bound one realisation meets (tests/within_u.py)."""
    out = tmp_path / "runs"
    code = main(
        [
            "run",
            "--sim",
            "--frequencies",
            "10,...,10000",
            "--sample-rate",
            "51200",
            "--estimator",
            "lpm",
            "--fresh-response",
            "--out",
            str(out),
        ]
    )
    assert code == 0, capsys.readouterr().out
    folder = _run_folder(out)
    checks = _errors(folder)
    assert checks[0][1].size == len(iso266.nominal_frequencies(10, 10000))
    assert_consistent_with_u(*checks)
    # the stored recording re-analyses to the same numbers (its record follows the fade-in)
    stored = json.loads((folder / "results.json").read_text())
    stored = stored.get("results", stored)["lines"]
    again = analyze(read_for_analysis(folder), estimator="lpm").results.lines
    np.testing.assert_allclose(
        [line.sensitivity_mv_per_ms2 for line in again],
        [line["sensitivity_mv_per_ms2"] for line in stored],
        rtol=1e-12,
    )


@pytest.mark.integration
def test_resonance_search_reports_the_piezo_mounted_resonance(tmp_path, capsys):
    """Issue 32 point 5: f0 within 2 % of the simulated piezo's 25 kHz with its U (the truth
    inside it), Q with its U; the lines beyond the reference's certificate (20 kHz) are not
    stated, and no mounting is blamed."""
    code = main(
        [
            "run",
            "--sim",
            "--frequencies",
            "1000,...,20000,22400,25000,28000,31500,35500",
            "--reference-frequency",
            "1000",
            "--sample-rate",
            "102400",
            "--level",
            "1",
            "--estimator",
            "lpm",
            "--resonance",
            "--fresh-response",
            "--out",
            str(tmp_path / "runs"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    line = next(t for t in out.splitlines() if t.startswith("resonance:"))
    match = re.search(r"f0 = \(([\d.]+) ± ([\d.]+)\) Hz, Q = ([\d.]+) ± ([\d.]+)", line)
    assert match, line
    f0, u_f0, q, u_q = (float(g) for g in match.groups())
    assert abs(f0 - 25000) <= 0.02 * 25000 and abs(f0 - 25000) <= u_f0 < 0.05 * 25000
    assert abs(q - 35) <= u_q  # the simulated piezo's Q 35
    assert "mounting" not in out
    rows = [t.split() for t in out.splitlines() if t.strip().startswith(("25000 ", "31500 "))]
    assert rows and all(row[2:9] == ["n/s"] * 7 for row in rows)


@pytest.mark.integration
def test_seed_lines_warm_and_cold_excitation_with_lpm(tmp_path):
    """Issue 26 point 3: 0.2 % type A at 5 m/s^2 on the seed's lines, warm <= 4 s (3 s
    stretch), cold <= 10 s of excitation, every line consistent with U (tests/within_u.py)."""
    store = ResponseStore(tmp_path / "store")
    plan = preset_plan("piezo", level_ms2=5.0, optimiser=stored_phases)
    times = []
    for _ in ("cold", "warm"):
        stand = open_stand(load(), dut="piezo", seed=5, systematic=False)
        settings = RunSettings(estimator="lpm", periods=1, target_type_a=0.002, dut_mass_g=10.0)
        try:
            finished = Procedure(stand, plan, settings, response_store=store).run()
        finally:
            stand.close()
        assert finished.status == RunStatus.COMPLETE, finished.abort_reason
        assert finished.record.final_output_v == 0.0
        results = finished.results
        assert results is not None and results.estimator == "lpm" and results.periods == 1
        assert max(line.relative_type_a for line in results.lines) <= 0.002
        truth = stand.truth(plan.frequencies_hz, float(np.sqrt(np.sum(plan.amplitudes_ms2**2) / 2)))
        s = np.array([line.sensitivity_mv_per_ms2 for line in results.lines])
        u = np.array([line.expanded_uncertainty_mv_per_ms2 for line in results.lines])
        k = np.array([line.coverage_factor for line in results.lines])
        assert_consistent_with_u(("magnitude", s - np.abs(truth), u, k))
        assert not any("one period only" in w for w in results.warnings)
        times.append(finished.record.excitation_time_s)
    cold, warm = times
    assert warm <= 3.0 and cold <= 10.0, times


def test_plan_over_the_stroke_is_refused_naming_line_and_travel(capsys):
    code = main(["plan", "--frequencies", "0.4,...,8", "--level", "5", "--reference-frequency",
                 "8", "--exciter", "long-stroke", "--sample-rate", "200"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    # the grid keeps 0.4 Hz inside the nominal span (issue 32): the line and travel of that plan
    assert "line 1.6 Hz" in err and "356 mm peak-to-peak" in err and "150 mm stroke" in err


def test_run_over_the_stroke_is_refused_before_anything_moves(tmp_path, capsys):
    out = tmp_path / "runs"
    code = main(["run", "--sim", "--frequencies", "0.4,...,8", "--level", "5",
                 "--reference-frequency", "8", "--exciter", "long-stroke", "--sample-rate",
                 "200", "--estimator", "lpm", "--out", str(out)])  # fmt: skip
    assert code == 2
    assert "150 mm stroke" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())  # no run folder: nothing moved


def test_profile_clips_lines_to_half_the_stroke_and_says_so():
    plan = build_plan(
        PlanRequest(
            frequencies_hz=(0.4, 4.0, 8.0),
            sample_rate_hz=200.0,
            level_ms2=1.0,
            reference_frequency_hz=8.0,
        ),
        stroke_peak_to_peak_m=0.15,
    )
    # 0.4 Hz: half of 150 mm p-p is 37.5 mm peak: 0.0375 (2 pi f)^2 at the actual frequency
    f0 = plan.frequencies_hz[0]
    assert plan.amplitudes_ms2[0] < 1.0
    assert plan.amplitudes_ms2[0] == pytest.approx(0.0375 * (2 * np.pi * 0.4) ** 2, rel=1e-9)
    assert abs(f0 / 0.4 - 1) <= 0.02
    assert plan.amplitudes_ms2[-1] == 1.0
    assert any("clipped by the exciter's stroke at 0.4 Hz" in w for w in plan.warnings)


def test_choose_period_keeps_the_preset_and_goes_non_uniform_below_1_hz():
    seed = iso266.nominal_frequencies(10, 2500)
    assert choose_period(seed, 6000.0, 12000) == 12000
    # 10 Hz - 10 kHz at 51.2 kS/s: 12.5 Hz needs a 2 s period exactly
    assert choose_period(iso266.nominal_frequencies(10, 10000), 51200.0, 12000) == 102400
    low = iso266.nominal_frequencies(0.4, 8)
    period = choose_period(low, 200.0, 12000)
    assert period < 100 * 200  # the exact ISO bins would need 100 s
    actual = np.rint(np.array(low) * period / 200.0) * 200.0 / period
    assert np.all(np.abs(actual / np.array(low) - 1) <= 0.02)
    assert not np.allclose(actual, low)
    with pytest.raises(PlanError, match=r"period: line 95 Hz: at or above 0\.45 fs"):
        choose_period((0.4, 95.0), 200.0, 12001)  # not exact on the preset period


def test_fade_in_is_one_cycle_of_the_lowest_line_within_one_period():
    """Issue 34 point 2: one cycle (was two: 0.1 s before the seed's record, was 0.2 s)."""
    assert fade_in_samples(10.0, 6000.0, 12000, None) == 600
    assert fade_in_samples(0.4, 200.0, 300, None) == 300  # capped at one period
    assert fade_in_samples(10.0, 6000.0, 12000, 0.05) == 300


def test_stopping_rule_trusts_the_lpm_target_from_one_period():
    assert StoppingRule(1, 0.002, None, min_periods=1).decide(1, 0.001, 2.0, 2.0) is Stop.TARGET
    assert StoppingRule(1, 0.002, None).decide(1, 0.001, 2.0, 2.0) is None  # 3 by default


def test_periods_1_refused_for_periodic_accepted_for_lpm(tmp_path, capsys):
    code = main(["run", "--periods", "1", "--estimator", "periodic", "--out", str(tmp_path)])
    assert code == 2  # (the default estimator is the lpm since issue 34: named here)
    assert "--periods: the periodic estimator needs at least 3 periods" in capsys.readouterr().err
    with pytest.raises(ValueError, match="multisine"):
        RunSettings(estimator="lpm", periods=1, mode="stepped-sine")


@pytest.mark.integration
def test_an_abort_during_the_lpm_record_fades_out_to_0_v(tmp_path):
    """The drive ends at 0 V on every path: an operator's stop while the record grows."""
    from app.procedure import PeriodEstimate

    plan = preset_plan("piezo", level_ms2=5.0, optimiser=stored_phases)
    stand = open_stand(load(), dut="piezo", seed=2, systematic=False)
    box: dict[str, Procedure] = {}
    played: list[np.ndarray] = []

    def listener(event: object) -> None:
        if isinstance(event, PeriodEstimate):
            box["p"].abort("stopped by the operator")
        drive = getattr(event, "drive", None)
        if drive is not None:
            played.append(np.asarray(drive))

    settings = RunSettings(estimator="lpm", periods=5, dut_mass_g=10.0)
    procedure = Procedure(stand, plan, settings, listener=listener)
    box["p"] = procedure
    try:
        finished = procedure.run()
    finally:
        stand.close()
    assert finished.status == RunStatus.ABORTED
    assert finished.record.final_output_v == 0.0
    assert played[-1][-1] == 0.0 and np.max(np.abs(played[-2])) > 0  # faded, not cut


def _stand_file(tmp_path: Path, plan: str) -> Path:
    from importlib import resources

    text = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
    path = tmp_path / "stand.toml"
    path.write_text(text + "\n[plan]\n" + plan, encoding="utf-8")
    return path


def test_a_stand_file_plan_is_used_where_the_run_states_nothing(tmp_path):
    from app.procedure.run import RunRequest, prepare

    stand_file = _stand_file(
        tmp_path,
        "frequencies_hz = [10.0, 20.0, 40.0, 80.0, 160.0, 5000.0]\nsample_rate_hz = 51200.0\n",
    )
    procedure, stand = prepare(RunRequest(stand_file=stand_file, estimator="lpm", periods=1))
    stand.close()
    assert procedure.plan.sample_rate_hz == 51200.0
    assert list(procedure.plan.nominal_frequencies_hz) == [10, 20, 40, 80, 160, 5000]
    own = RunRequest(stand_file=stand_file, frequencies_hz=(10.0, 160.0, 1000.0))
    procedure, stand = prepare(own)  # the run's own lines win, the stand's rate stays
    stand.close()
    assert list(procedure.plan.nominal_frequencies_hz) == [10, 160, 1000]
    assert procedure.plan.sample_rate_hz == 51200.0


def test_a_bad_stand_file_plan_is_refused_naming_the_key(tmp_path, capsys):
    stand_file = _stand_file(tmp_path, 'profile = "jerk"\n')
    code = main(["run", "--stand", str(stand_file), "--out", str(tmp_path / "runs")])
    assert code == 2
    assert "plan.profile" in capsys.readouterr().err
