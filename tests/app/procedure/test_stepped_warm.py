"""Issue 34 point 5: the stepped sine's block an option, and a warm stepped-sine run (from the
stored stand response) never longer than the cold one (identification, extrapolated lines)."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest

from app.io.vocabulary import Mode
from app.procedure import PeriodBlock, Procedure, Progress, RunSettings, State
from app.procedure.modes import DEFAULT_STEPPED_BLOCK_S
from app.procedure.options import RunOptions
from app.procedure.phase_store import stored_phases
from app.procedure.planning import GRID_TOLERANCE
from app.procedure.request import RunRequest
from app.stand import config as stand_config
from app.stand.open import open_stand
from app.stand.response import ResponseStore
from dsp.multisine import Line, Plan, make_plan, preset_plan
from dsp.sinefit import block_compatible_grid
from tests.within_u import assert_consistent_with_u

CONFIG = stand_config.load()


class PerLine:
    """Excitation (s, first to last non-zero drive sample) and blocks per state, per line
    (a line ends at its "line ... done" progress)."""

    def __init__(self, sample_rate_hz: float):
        self.fs = sample_rate_hz
        self.lines: list[dict[str, tuple[float, int]]] = []
        self._now: dict[str, list[float]] = defaultdict(lambda: [0.0, 0])

    def __call__(self, event: object) -> None:
        if isinstance(event, PeriodBlock):
            moving = np.flatnonzero(event.drive)
            if moving.size:
                entry = self._now[str(event.state)]
                entry[0] += (moving[-1] - moving[0] + 1) / self.fs
                entry[1] += 1
        elif isinstance(event, Progress) and event.message.endswith(" done"):
            self.lines.append({k: (v[0], int(v[1])) for k, v in self._now.items()})
            self._now = defaultdict(lambda: [0.0, 0])


def _stepped(store, plan, block_s):
    stand = open_stand(CONFIG, dut="piezo", seed=5, systematic=False)
    per_line = PerLine(plan.sample_rate_hz)
    settings = RunSettings(
        mode=Mode.STEPPED_SINE,
        target_type_a=0.002,
        max_acquisition_s=600.0,
        dut_mass_g=10.0,
        stepped_block_s=block_s,
    )
    try:
        finished = Procedure(stand, plan, settings, listener=per_line, response_store=store).run()
    finally:
        stand.close()
    assert finished.status == "complete", finished.abort_reason
    return finished, per_line, stand


def fair_seed_plan(block_s: float) -> Plan:
    """The seed's 25 piezo lines at 5 m/s^2 on the stepped sine's block-compatible frequencies
    (bench/excitation_time.py's `stepped_plan`: within 2 % of nominal, off the mains
    harmonics, the shortest block of whole cycles of the line and the mains)."""
    plan = preset_plan("piezo", optimiser=stored_phases)
    nominal = plan.nominal_frequencies_hz
    grid = block_compatible_grid(
        nominal,
        plan.sample_rate_hz,
        block_s,
        mains_hz=plan.mains_frequency_hz,
        mains_harmonics=plan.mains_harmonics,
        tolerance=GRID_TOLERANCE,
        within_hz=(float(nominal.min()), float(nominal.max())),
    )
    lines = tuple(
        Line(line.nominal_frequency_hz, f, b, line.amplitude_ms2, 0.0)
        for line, f, b in zip(plan.lines, grid.frequencies_hz, grid.bins, strict=True)
    )
    return Plan(
        plan.sample_rate_hz,
        grid.period_samples,
        lines,
        plan.reference_frequency_hz,
        plan.mains_frequency_hz,
        plan.mains_harmonics,
    )


SHORT_PLAN = ([16.0, 20.0, 25.0, 40.0, 80.0, 125.0, 160.0], 6000.0, 12000, 5.0, 160.0)


@pytest.mark.integration
@pytest.mark.parametrize(
    ("plan_name", "block_s"), [("fair seed plan", 0.25), ("7 lines", DEFAULT_STEPPED_BLOCK_S)]
)
def test_a_warm_stepped_sine_is_never_longer_than_the_cold_one(tmp_path, plan_name, block_s):
    """Same plan, seed and stand: the warm run (stored response) takes at most the cold run's
    excitation. Before issue 34 every warm line paid a check burst at 20 % of the level (its
    crossfade and a check block) before the level: 5 level-loop blocks a line against a cold
    line's 3 when one extrapolated step lands, and the warm run was the longer one on the
    fair seed plan (52.34 s against 52.16 s at 0.25 s blocks). Now only the first line is checked
    at 20 %; the later lines start at the level from their stored response and their first
    step is the check."""
    plan = fair_seed_plan(block_s) if plan_name == "fair seed plan" else make_plan(*SHORT_PLAN)
    store = ResponseStore(tmp_path / "responses")
    cold, cold_lines, _ = _stepped(store, plan, block_s)
    warm, warm_lines, stand = _stepped(store, plan, block_s)
    assert cold.record.stand_response["source"] == "identified"
    assert warm.record.stand_response["source"] == "stored"
    assert warm.record.excitation_time_s <= cold.record.excitation_time_s
    # no identification warm, and no line after the first pays more level loop than cold
    assert all(State.IDENTIFYING.value not in line for line in warm_lines.lines)
    for k, (w, c) in enumerate(zip(warm_lines.lines[1:], cold_lines.lines[1:], strict=True)):
        warm_blocks = w[State.EQUALISING.value][1]
        assert warm_blocks <= c[State.EQUALISING.value][1], plan.lines[k + 1].label
        assert warm_blocks == 3, plan.lines[k + 1].label  # crossfade, two settled blocks
    # the values stand: within U of the simulated stand's truth (one line's rms each)
    lines = warm.results.lines
    truth = np.array(
        [
            stand.truth(np.array([f]), a / np.sqrt(2))[0]
            for f, a in zip(plan.frequencies_hz, plan.amplitudes_ms2, strict=True)
        ]
    )
    assert_consistent_with_u(
        (
            "magnitude",
            np.array([ln.sensitivity_mv_per_ms2 for ln in lines]) - np.abs(truth),
            np.array([ln.expanded_uncertainty_mv_per_ms2 for ln in lines]),
            np.array([ln.coverage_factor for ln in lines]),
        )
    )


def test_the_block_is_an_option_of_the_request_and_the_settings():
    """--stepped-block reaches RunSettings through the request; unset, the default block."""
    assert RunRequest().settings(CONFIG.backend).stepped_block_s == DEFAULT_STEPPED_BLOCK_S
    request = RunRequest(mode=Mode.STEPPED_SINE, stepped_block_s=0.1)
    assert request.settings(CONFIG.backend).stepped_block_s == 0.1
    with pytest.raises(ValueError, match=r"stepped block: must be between 0\.01 and 10 s"):
        RunSettings(stepped_block_s=0.001)
    with pytest.raises(ValueError, match="stepped block"):
        RunSettings(stepped_block_s=float("nan"))
    with pytest.raises(ValueError, match=r"--stepped-block: .* --mode multisine"):
        RunOptions(stepped_block_s=0.1)  # a multisine run has no block
    assert RunOptions(mode=Mode.STEPPED_SINE, stepped_block_s=0.1).stepped_block_s == 0.1


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--mode", "stepped-sine", "--stepped-block", "20"], "--stepped-block: must be in"),
        (["--mode", "stepped-sine", "--stepped-block", "5 Hz"], "--stepped-block: '5 Hz'"),
        (["--mode", "stepped-sine", "--stepped-block", "nan"], "--stepped-block: must be a"),
        (["--stepped-block", "0.1"], "--stepped-block: the stepped sine's block"),
    ],
)
def test_a_bad_block_exits_2_naming_the_option(tmp_path, capsys, argv, message):
    from app.cli import main

    assert main(["run", "--sim", *argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_the_help_states_the_block_its_unit_default_and_trade(capsys):
    from app.cli import main

    assert main(["run", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--stepped-block" in text
    assert f"in s, e.g. 0.05 or 50ms (default {DEFAULT_STEPPED_BLOCK_S:g} s;" in text
    assert "shorter blocks cut each line's fixed cost" in text
    assert "[0.01, 10] s" in text
