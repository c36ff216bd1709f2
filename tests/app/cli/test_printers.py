"""What the CLI prints for people (issue 27 point 4): plan warnings grouped by kind, progress
lines with the total and the time left, a sweep's level i of n."""

from __future__ import annotations

from app.cli.printers import TerminalProgress, grouped_warnings
from app.procedure import PeriodEstimate, Progress, State, StateChanged


def test_repeated_warnings_one_line_per_kind_with_count_and_lines():
    warnings = [
        "line 20 Hz: the 2nd harmonic of line 10 Hz lands on its bin (distortion adds to it)",
        "line 40 Hz: the 4th harmonic of line 10 Hz lands on its bin (distortion adds to it)",
        "line 40 Hz: the 2nd harmonic of line 20 Hz lands on its bin (distortion adds to it)",
        "line 50 Hz: on the 1st mains harmonic (50 Hz); a periodic average does not remove hum;"
        " shift it one bin to 50.5 Hz",
        "something else entirely",
    ]
    assert grouped_warnings(warnings) == [
        "harmonics of other lines land on the bins of 2 lines (3 cases): 20, 40 Hz; "
        "distortion adds to them",
        warnings[3],  # a kind met once: as it is, with its own advice
        "something else entirely",
    ]


def test_lines_sorted_by_frequency_not_text():
    w = "line {} Hz: the 2nd harmonic of line 5 Hz lands on its bin (distortion adds to it)"
    got = grouped_warnings([w.format(100), w.format(20), w.format(100)])
    assert got == [
        "harmonics of other lines land on the bins of 2 lines (3 cases): 20, 100 Hz; "
        "distortion adds to them"
    ]


class _Line:
    def __init__(self, f: float, a: float) -> None:
        self.nominal_frequency_hz, self.relative_type_a = f, a


class _Results:
    lines = (_Line(40.0, 1e-5), _Line(125.0, 3e-5))


def _estimate(periods: int) -> PeriodEstimate:
    return PeriodEstimate(periods, None, _Results())  # type: ignore[arg-type]


def test_progress_has_total_and_time_left(capsys):
    progress = TerminalProgress()
    progress(_estimate(3))
    progress(Progress(3 / 8, 6.0, 10.0, "period 3"))
    err = capsys.readouterr().err
    assert "period 3 of 8" in err and "about 10 s left" in err and " 38 %" in err
    assert "type A worst 0.003 % at 125 Hz" in err


def test_progress_to_a_target_and_stepped_sine(capsys):
    progress = TerminalProgress()
    progress(_estimate(4))
    progress(Progress(0.25, 8.0, None, "period 4"))
    progress(Progress(0.5, 20.0, None, "line 40 Hz done"))
    err = capsys.readouterr().err.splitlines()
    assert "period 4, to the type A target" in err[0] and "about 24 s left" in err[0]
    assert err[1].startswith("  line 40 Hz done") and "about 20 s left" in err[1]


def test_sweep_says_level_i_of_n(capsys):
    progress = TerminalProgress([2.0, 5.0])
    for _ in range(2):
        progress(StateChanged(State.PREFLIGHT))
    err = capsys.readouterr().err
    assert "level 1 of 2: 2 m/s^2" in err and "level 2 of 2: 5 m/s^2" in err


def test_show_of_the_runs_root_lists_its_runs(complete_run, tmp_path, capsys):
    """`show runs/` says it is a folder of runs and lists them, not "the run was interrupted";
    a folder beside the runs that is no run is not listed."""
    import shutil

    from app.cli import main

    root = tmp_path / "runs"
    shutil.copytree(complete_run, root / complete_run.name)
    (root / "notes").mkdir()
    code = main(["show", str(root)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "a folder of 1 run(s), not a run folder" in out and "interrupted" not in out + err
    assert f"{complete_run.name}  complete" in out and "SN-42" in out
    assert "notes" not in out


def test_a_coherence_that_is_not_defined_prints_n_a_with_the_reason(capsys):
    """One period (LPM): the coherence is NaN; the table says n/a and why, never "nan"."""
    import dataclasses
    import math

    from app.cli.printers import print_results
    from app.formatting import COHERENCE_NOT_AVAILABLE
    from app.procedure.analysis import analyze
    from dsp.multisine import make_plan
    from tests.synthetic import lowpass_response, make_recording

    plan = make_plan([10.0, 80.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)
    results = analyze(make_recording(plan, lowpass_response(), periods=3)).results
    print_results(results)
    assert COHERENCE_NOT_AVAILABLE not in capsys.readouterr().out
    lines = tuple(dataclasses.replace(ln, coherence=math.nan) for ln in results.lines)
    print_results(dataclasses.replace(results, lines=lines))
    out = capsys.readouterr().out
    assert "nan" not in out.lower().replace("nanometre", "")
    assert " n/a " in out and COHERENCE_NOT_AVAILABLE in out


def test_a_line_not_stated_prints_n_s_and_its_reason(capsys):
    """Issue 32 point 5 (run and show print this table): no number with U, the reason."""
    import dataclasses

    from app.cli.printers import print_results
    from app.procedure.analysis import analyze
    from dsp.calibration import not_stated_line
    from dsp.multisine import make_plan
    from tests.synthetic import lowpass_response, make_recording

    plan = make_plan([10.0, 80.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)
    results = analyze(make_recording(plan, lowpass_response(), periods=3)).results
    why = "outside the reference's calibrated range (20-1000 Hz)"
    lines = (not_stated_line(results.lines[0], why), *results.lines[1:])
    print_results(dataclasses.replace(results, lines=lines))
    out = capsys.readouterr().out
    row = next(t.split() for t in out.splitlines() if t.strip().startswith("10 "))
    assert row[2:9] == ["n/s"] * 7 and row[-2:] == ["not", "stated"]
    assert f"n/s (not stated) at 10 Hz: {why}" in out
    assert "nan" not in out.lower()
