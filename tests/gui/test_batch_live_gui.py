"""The Run tab shows every DUT of a run of several live (issue 36 point 4): each period the run's
own estimate carries the other DUTs' (app.procedure.batch_live), the worker makes each one's
view off the GUI thread, the tab draws one deviation curve per DUT (labelled by position and
serial, its own colour, in the legend) and a level meter per DUT channel. Simulated stand
sim/stand-fixture4-physics.toml: its positions see different motion, so the DUTs' curves differ
and a curve drawn from another DUT's estimate is caught."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from app.gui.run_tab import RunTab
from app.gui.worker import ShownEstimate
from app.procedure import MemberEstimate, PeriodEstimate
from tests.gui.test_batch_gui import _run, _serials, _window

ROOT = Path(__file__).resolve().parents[2]
PHYSICS = ROOT / "sim" / "stand-fixture4-physics.toml"


def _deviations(results) -> list[float]:
    return [ln.deviation_percent for ln in results.lines if ln.stated]


def test_a_batch_run_draws_each_duts_own_live_curve_and_meter(qtbot, tmp_path):
    w = _window(qtbot, tmp_path, stand=PHYSICS)
    _serials(w, A="SN-1", B="SN-2", C="SN-3", D="SN-4")
    tab = w.run_tab
    seen: list[ShownEstimate] = []
    take = tab.take

    def spy(events):
        seen.extend(e for e in events if isinstance(e, ShownEstimate))
        take(events)

    tab.take = spy  # what the worker queued for the tab, as the tab takes it
    finished = _run(qtbot, w, 4)
    assert [f.status for f in finished] == ["complete"] * 4, [
        f.record.abort_reason for f in finished
    ]
    # every live estimate of the run's own DUT (A: the window's listener gets it unmarked)
    # carried B, C and D's, each with its view
    live = [s for s in seen if s.estimate.member in ("", "A")]
    assert len(live) >= 4  # periods 4: one per period
    for shown in live:
        assert [m.position for m in shown.estimate.members] == ["B", "C", "D"]
        assert list(shown.members) == ["B", "C", "D"]
    # one curve per DUT, labelled by position and serial, each its own colour
    curves = tab.live.member_curves
    assert list(curves) == ["A", "B", "C", "D"]
    legend = tab.live.sens_plot.legend
    assert [label.text for _, label in legend.items] == [
        "A · SN-1",
        "B · SN-2",
        "C · SN-3",
        "D · SN-4",
    ]
    colours = {curve.opts["pen"].color().name() for curve in curves.values()}
    assert len(colours) == 4
    # each curve ends at its own DUT's stored deviations at the lines
    stored = {f.record.dut.id: f.results for f in finished}
    for position, serial in zip("ABCD", ("SN-1", "SN-2", "SN-3", "SN-4"), strict=True):
        x, y = curves[position].getData()
        lines = [ln for ln in stored[serial].lines if ln.stated]
        assert len(lines) == 4  # every line of the plan drawn
        # (the x of a logarithmic axis is kept as log10 of the frequency)
        assert list(10**x) == pytest.approx([ln.frequency_hz for ln in lines], rel=1e-9)
        assert list(y) == pytest.approx(_deviations(stored[serial]), rel=1e-9, abs=1e-12), position
    # the DUTs differ (the fixture's positions move differently): no curve is another's
    drawn = [np.asarray(curves[p].getData()[1]) for p in "ABCD"]
    for i in range(4):
        for j in range(i + 1, 4):
            assert np.max(np.abs(drawn[i] - drawn[j])) > 1e-5, ("ABCD"[i], "ABCD"[j])
    # a level meter per DUT channel, named as its curve, beside the reference's
    assert list(tab.meters) == ["reference", "dut.A", "dut.B", "dut.C", "dut.D"]
    for name, bar in tab.meters.items():
        assert bar.value() > 0, name
    assert tab.meters["dut.C"].format().startswith("C · SN-3 %p % of ±")
    assert tab.live.sens_curve.isVisible() is False
    # the run's own DUT's U (error bars) is not drawn over every DUT's curve; its phase and
    # traces say whose they are
    assert not tab.live.sens_err.isVisible()
    assert tab.live.phase_plot.titleLabel.text == "Phase (A · SN-1)"
    names = [label.text for _, label in tab.live.wave_plot.legend.items]
    assert names == ["reference", "DUT A · SN-1"]
    assert tab.coherence.text().startswith("A · SN-1: ")


def _results(deviations: list[float]):
    """Results at 10/80/160/630 Hz (a synthetic recording's) with these deviations (%)."""
    import dataclasses

    from app.procedure.analysis import analyze
    from dsp.multisine import make_plan
    from tests.synthetic import lowpass_response, make_recording

    plan = make_plan([10.0, 80.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)
    base = analyze(make_recording(plan, lowpass_response(), periods=3)).results
    lines = [
        dataclasses.replace(ln, deviation_percent=d)
        for ln, d in zip(base.lines, deviations, strict=True)
    ]
    return dataclasses.replace(base, lines=tuple(lines))


def test_each_member_estimate_in_the_runs_own_event_draws_its_own_curve(qtbot):
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.labels = {"A": "A · SN-1", "B": "B · SN-2", "C": "C · SN-3"}
    tab.live.members(tab.labels)
    tab.frame.lead = "A"
    a = _results([0.1, 0.2, 0.0, 0.3])
    b = _results([1.0, 2.0, 0.0, 3.0])
    c = _results([-1.0, -2.0, 0.0, -3.0])
    event = PeriodEstimate(
        3, None, a, "A", (MemberEstimate("B", "dut.B", b), MemberEstimate("C", "dut.C", c))
    )
    tab.take([event])  # as queued without views: the tab makes them
    tab.draw()
    shown = {p: list(curve.getData()[1]) for p, curve in tab.live.member_curves.items()}
    assert shown["A"] == pytest.approx([0.1, 0.2, 0.0, 0.3])
    assert shown["B"] == pytest.approx([1.0, 2.0, 0.0, 3.0])
    assert shown["C"] == pytest.approx([-1.0, -2.0, 0.0, -3.0])
    # the next period: only the newer estimates move the curves
    later = PeriodEstimate(4, None, a, "A", (MemberEstimate("C", "dut.C", b),))
    tab.take([later])
    tab.draw()
    assert list(tab.live.member_curves["C"].getData()[1]) == pytest.approx([1.0, 2.0, 0.0, 3.0])
    assert list(tab.live.member_curves["B"].getData()[1]) == pytest.approx([1.0, 2.0, 0.0, 3.0])


def test_member_curves_are_kept_for_the_same_duts_and_gone_for_one(qtbot):
    from app.gui.plots import LivePlots

    plots = LivePlots()
    qtbot.addWidget(plots.widget)
    labels = {"A": "A · SN-1", "B": "B · SN-2"}
    plots.members(labels)
    made = dict(plots.member_curves)
    plots.member_curves["B"].setData([10.0, 100.0], [0.1, 0.2])
    plots.clear()  # the next run of the same DUTs: the same curves, emptied
    plots.members(dict(labels))
    assert plots.member_curves == made
    assert all(made[p] is plots.member_curves[p] for p in made)
    assert plots.member_curves["B"].getData()[1] is None or not len(
        plots.member_curves["B"].getData()[1]
    )
    assert plots.sens_plot.titleLabel.text.endswith(", per DUT")
    plots.members({"A": "A · SN-9"})  # other DUTs: made anew
    assert list(plots.member_curves) == ["A"] and plots.member_curves["A"] is not made["A"]
    assert [label.text for _, label in plots.sens_plot.legend.items] == ["A · SN-9"]
    plots.members({})  # one DUT: its own curve, U and titles as ever
    assert plots.member_curves == {}
    assert plots.sens_curve.isVisible() and plots.sens_err.isVisible()
    assert plots.phase_plot.titleLabel.text == "Phase"
    assert [label.text for _, label in plots.wave_plot.legend.items] == ["reference", "DUT"]
