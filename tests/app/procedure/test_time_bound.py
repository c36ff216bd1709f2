"""Issue 34 point 5: a run with a type A target is bounded by default (120 s of acquisition,
or 10 periods of a longer plan), --max-time still wins, and a bound that ends a run before
its target is reported: the bound, the lines above the target with their measured type A."""

from __future__ import annotations

import json
import re

import pytest

from app.cli import main
from app.io.vocabulary import Backend
from app.procedure.request import RunRequest
from app.procedure.stopping import (
    DEFAULT_MAX_PERIODS,
    DEFAULT_MAX_TIME_S,
    StoppingRule,
    default_time_bound_s,
    target_not_met,
)
from app.records.warnings import WarningKind, blocking, classify
from dsp.lpm_record import WHOLE_RECORD_PERIODS


def test_the_default_bound_is_120_s_or_ten_periods_of_a_longer_plan():
    assert (DEFAULT_MAX_TIME_S, DEFAULT_MAX_PERIODS) == (120.0, 10)
    assert default_time_bound_s(2.0) == 120.0  # the shipped plans' 2 s period
    assert default_time_bound_s(12.0) == 120.0
    assert default_time_bound_s(22.0) == 220.0  # a 0.4-8 Hz plan's period
    targeted = RunRequest(target_type_a=0.002)
    assert targeted.time_bound_s(2.0) == 120.0
    assert RunRequest(target_type_a=0.002, max_acquisition_s=30.0).time_bound_s(2.0) == 30.0
    assert RunRequest().time_bound_s(2.0) is None  # the periods bound a run without target
    settings = targeted.settings(Backend.SIM, 2.0)
    assert settings.max_acquisition_s == 120.0 and settings.max_acquisition_default
    given = RunRequest(target_type_a=0.002, max_acquisition_s=30.0).settings(Backend.SIM, 2.0)
    assert given.max_acquisition_s == 30.0 and not given.max_acquisition_default
    plain = RunRequest().settings(Backend.SIM, 2.0)
    assert plain.max_acquisition_s is None and not plain.max_acquisition_default


def test_the_report_names_the_bound_the_lines_and_their_type_a():
    rule = StoppingRule(8, 0.002, 120.0)
    labels, type_a = ["10 Hz", "20 Hz", "4000 Hz"], [0.001, 0.0025, 0.03]
    report = target_not_met(
        rule,
        default_bound=True,
        acquired_s=120.0,
        periods=62,
        labels=labels,
        type_a=type_a,
        stated=[True, True, False],
    )
    assert report is not None
    assert report.above == (("20 Hz", 0.0025, True), ("4000 Hz", 0.03, False))
    assert report.needed_s == pytest.approx(120.0 * (0.03 / 0.002) ** 2)
    text = report.text()
    assert text.startswith(
        "type A target 0.2 % not met: the time bound 120 s (the default with a type A target; "
        "--max-time sets another) ended the acquisition after 120 s (62 period(s)); 2 of 3 "
        "lines above the target, their type A as measured: 20 Hz 0.25 %, 4000 Hz 3 % (not "
        "stated: too few LSB); every stated line is stated with the type A measured;"
    )
    assert text.endswith("the worst would need about 27000 s of acquisition")
    warning = classify(text)
    assert warning.kind is WarningKind.TYPE_A_TARGET and not blocking([text])
    given = target_not_met(
        rule, default_bound=False, acquired_s=120.0, periods=62, labels=labels, type_a=type_a
    )
    assert given is not None and "(the default" not in given.text()
    assert "the time bound 120 s ended" in given.text()
    met = [0.001, 0.0019, 0.002]
    kw = {"default_bound": True, "acquired_s": 9.0, "periods": 4, "labels": labels}
    assert target_not_met(rule, type_a=met, **kw) is None
    assert target_not_met(StoppingRule(8, None, 120.0), type_a=type_a, **kw) is None


def _run(tmp_path, capsys, *extra):
    argv = ["run", "--sim", "--dut", "capacitive", "--target-ua", "0.05%", "--json", *extra]
    code = main([*argv, "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    record = json.loads(out)
    folder = tmp_path / record["run_id"]
    config = json.loads((folder / "config.json").read_text())
    results = json.loads((folder / "results.json").read_text())
    return record, config, results


def _report(results):
    texts = [w for w in results["results"]["warnings"] if w.startswith("type A target")]
    assert len(texts) == 1, results["results"]["warnings"]
    return texts[0]


@pytest.mark.integration
def test_the_default_estimators_run_with_a_target_takes_the_default_bound(tmp_path, capsys):
    """The lpm (the default since issue 34) with a type A target gets the same default bound
    (the one stopping rule, app.procedure.stopping; the periodic case below runs to it: an
    lpm record of 60 periods takes 90 s of the suite's time)."""
    argv = ["run", "--sim", "--dut", "piezo", "--target-ua", "0.2%", "--json"]
    assert main([*argv, "--out", str(tmp_path)]) == 0
    record = json.loads(capsys.readouterr().out)
    config = json.loads((tmp_path / record["run_id"] / "config.json").read_text())
    assert config["settings"]["estimator"] == "lpm"
    assert config["settings"]["max_acquisition_s"] == DEFAULT_MAX_TIME_S
    assert config["settings"]["max_acquisition_default"] is True


@pytest.mark.parametrize(
    ("estimator", "reused"),
    # the lpm: 29 s at load average 6 (16 whole records, then 2 batched ones; 90 s before)
    [("periodic", 2), pytest.param("lpm", 0, marks=pytest.mark.long)],
)
def test_an_unreachable_target_ends_at_the_default_bound_with_its_report(
    tmp_path, capsys, estimator, reused
):
    """The capacitive DUT's lines reach 0.13 % (1250 Hz) to 1.4 % (4 kHz, not stated: too
    few LSB) type A in 120 s: 0.05 % is out of reach. Without --max-time the run stops at
    the default bound, in simulated seconds: 120 s of acquisition (periodic: 2 settled periods
    reused, 58-59 read; lpm: one record of 59-60 periods, estimated at checkpoints by the
    batched estimator, dsp.lpm_live), and says which lines are above the target with the
    type A it states for them, and which it does not state. The lpm run's stored lines are
    `analyze`'s of its own recording, bit for bit."""
    record, config, results = _run(tmp_path, capsys, "--estimator", estimator)
    settings = config["settings"]
    assert settings["max_acquisition_s"] == DEFAULT_MAX_TIME_S
    assert settings["max_acquisition_default"] is True
    periods = results["results"]["periods"]
    read_s = 2.0 * (periods - reused)  # the 2 s periods read after the reused ones
    assert DEFAULT_MAX_TIME_S - 2 * 2.0 < read_s <= DEFAULT_MAX_TIME_S
    assert record["excitation_time_s"] < DEFAULT_MAX_TIME_S + 20.0  # + equalisation, fades
    text = _report(results)
    head = re.match(
        r"type A target 0\.05 % not met: the time bound 120 s \(the default with a type A "
        r"target; --max-time sets another\) ended the acquisition after ([\d.]+) s "
        rf"\({periods} period\(s\)\);",
        text,
    )
    assert head is not None, text
    # it stops before a period that would take it past the bound: within one 2 s period
    assert DEFAULT_MAX_TIME_S - 2.0 - 0.01 <= float(head.group(1)) <= DEFAULT_MAX_TIME_S
    listed = dict(re.findall(r"(\d+(?:\.\d+)? Hz) ([\d.]+) %", text.split("as measured: ")[1]))
    lines = results["results"]["lines"]
    stated = [ln for ln in lines if not ln["not_stated"]]  # "" when stated
    above = [ln for ln in stated if ln["relative_type_a"] > 0.0005]
    assert above and all(f"{ln['nominal_frequency_hz']:g} Hz" in listed for ln in above)
    for line in above:  # the type A the report names is the one the results state
        label = f"{line['nominal_frequency_hz']:g} Hz"
        assert float(listed[label]) == pytest.approx(100 * line["relative_type_a"], rel=5e-3)
    for line in lines:  # a line the run does not state is named as such
        if line["not_stated"]:
            label = f"{line['nominal_frequency_hz']:g} Hz"
            assert f"{label} {listed[label]} % (not stated: too few LSB)" in text
    # honest verdict: conformity decided with the measured U, the target not met said
    assert any(r.startswith("type A target not met") for r in results["verdict_reasons"])
    if estimator == "lpm":
        assert periods > WHOLE_RECORD_PERIODS
        _assert_analyze_states_the_same_lines(tmp_path / record["run_id"], results)


def _assert_analyze_states_the_same_lines(folder, results):
    """`analyze` of the run's recording states every line's value, U, type A and phase as
    the run stored them (equal floats: the same batched estimator on the same batches)."""
    from app.procedure.analysis import analyze, read_for_analysis

    again = analyze(read_for_analysis(folder), estimator="lpm").results.to_dict()
    assert again["periods"] == results["results"]["periods"]
    names = (
        "sensitivity_mv_per_ms2",
        "phase_deg",
        "relative_type_a",
        "relative_expanded_uncertainty",
        "phase_expanded_uncertainty_deg",
        "effective_dof",
        "dut_distortion_percent",
    )
    for stored, line in zip(results["results"]["lines"], again["lines"], strict=True):
        assert {n: line[n] for n in names} == {n: stored[n] for n in names}


@pytest.mark.integration
def test_an_explicit_max_time_wins_over_the_default(tmp_path, capsys):
    _, config, results = _run(tmp_path, capsys, "--max-time", "10s")
    assert config["settings"]["max_acquisition_s"] == 10.0
    assert config["settings"]["max_acquisition_default"] is False
    assert 2.0 * (results["results"]["periods"] - 2) <= 10.0
    text = _report(results)
    assert "the time bound 10 s ended the acquisition" in text and "(the default" not in text


@pytest.mark.parametrize("value", ["0", "-5", "nan", "48h", "10 Hz", "inf"])
def test_a_bad_max_time_exits_2_naming_the_option(tmp_path, capsys, value):
    argv = ["run", "--sim", "--target-ua", "0.2", "--max-time", value, "--out", str(tmp_path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--max-time" in err and "Traceback" not in err


def test_the_help_states_the_default_bound(capsys):
    assert main(["run", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "(default with --target-ua: 120 s, or 10 periods of the plan when they are longer;" in (
        text
    )


def test_the_time_left_with_a_target_is_the_pace_capped_by_the_bound(capsys):
    """A run bounded before its target said "about 5000 s left" to the end (the pace to the
    target); the time left is now never past the bound, and the progress line still reads
    as a run to a target."""
    from app.cli.printers import TerminalProgress
    from app.procedure import Progress

    rule = StoppingRule(8, 0.002, 120.0)
    assert rule.remaining_s(10, 2.0, 20.0, 0.004) == pytest.approx(60.0)  # (2^2 - 1) * 20 s
    assert rule.remaining_s(50, 2.0, 100.0, 0.01) == pytest.approx(20.0)  # the bound's rest
    assert StoppingRule(8, 0.002).remaining_s(50, 2.0, 100.0, 0.01) == pytest.approx(2400.0)
    assert rule.remaining_s(3, 2.0) is None  # nothing measured yet
    assert StoppingRule(4).remaining_s(3, 2.0, 6.0, 0.5) == 2.0  # periods: the periods left
    progress = TerminalProgress()
    progress(Progress(0.04, 100.0, 20.0, "period 50", until_target=True))
    err = capsys.readouterr().err
    assert "to the type A target" in err and "about 20 s left" in err and " of " not in err
