"""The Run tab's typed live frame and its drawing, without a stand: what a frame keeps of the
worker's events and what the tab shows of it."""

from __future__ import annotations

import dataclasses
import os
import threading

import numpy as np
import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtWidgets import QLabel

from app.gui.run_tab import ElidedLabel, LiveFrame, PhaseSteps, RunTab
from app.gui.worker import RunWorker
from app.procedure import (
    EqualisationStep,
    Finished,
    InputRanges,
    PeriodBlock,
    Progress,
    State,
    StateChanged,
    WarningRaised,
)
from app.records.run_record import RunRecord


def block(index: int, state: State, level: float) -> PeriodBlock:
    samples = np.full((2, 16), level)
    return PeriodBlock(index, state, ("reference", "dut"), samples, np.zeros(16))


def test_a_frame_keeps_the_latest_of_each_kind_and_every_warning():
    frame = LiveFrame()
    frame.take(
        [
            StateChanged(State.EQUALISING, "line 3"),
            EqualisationStep(1, np.zeros(3), 0.1234),
            EqualisationStep(2, np.zeros(3), 0.0056),
            Progress(0.25, 1.0, 30.0),
            Progress(0.5, 2.0, None),
            WarningRaised("first"),
            block(1, State.ACQUIRING, 0.5),
            block(2, State.ACQUIRING, 0.7),
            block(3, State.FADING_OUT, 0.1),  # never shown: the last steady period stays
            StateChanged(State.ACQUIRING, ""),
            WarningRaised("second"),
        ]
    )
    assert frame.state == "acquiring"
    assert frame.equalisation == "equalisation 2: worst line 0.56 %"
    assert frame.progress == (0.0, "acquiring")  # the new phase starts from its beginning
    assert frame.warnings == ["first", "second"]
    assert frame.block is not None and frame.block.index == 2
    frame.take([block(4, State.FADING_OUT, 0.0)])
    assert frame.block.index == 2


def test_the_tab_draws_a_frame_once_and_meters_in_percent_of_range(qtbot):
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.ranges_v = {"reference": 2.0, "dut": 10.0}
    tab.frame = LiveFrame(
        state="acquiring  period 3",
        progress=(0.4, "acquiring 40 %, about 12 s left"),
        block=block(1, State.ACQUIRING, 1.5),  # 1.5 V: 75 % of 2 V, 15 % of 10 V
        warnings=["<hum>"],
    )
    tab.draw()
    assert tab.state.text() == "acquiring  period 3"
    assert tab.progress.value() == 40 and "about 12 s left" in tab.progress.format()
    assert tab.meters["reference"].value() == 75 and tab.meters["dut"].value() == 15
    assert "&lt;hum&gt;" in tab.messages.text()
    assert tab.frame.state is None and tab.frame.block is None and tab.frame.progress is None
    tab.state.setText("kept")
    tab.draw()  # nothing new: nothing redrawn
    assert tab.state.text() == "kept"


def test_the_meters_follow_the_ranges_the_run_picked_and_the_tab_says_them(qtbot):
    """Issue 32 point 2: the run picks each channel's input range; a block read on +-0.1 V
    is metered against 0.1 V, not the +-1 V the run was attached with, and the ranges the
    run states (InputRanges) are shown."""
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.ranges_v = {"reference": 1.0, "dut": 5.0}
    picked = dataclasses.replace(
        block(1, State.ACQUIRING, 0.05), ranges_v={"reference": 0.1, "dut": 0.2}
    )
    tab.frame.take([InputRanges("input ranges: reference +-0.1 V, DUT +-0.2 V"), picked])
    tab.draw()
    assert tab.meters["reference"].value() == 50 and tab.meters["dut"].value() == 25
    assert "±0.1 V" in tab.meters["reference"].format()
    assert "±0.2 V" in tab.meters["dut"].format()
    assert tab.ranges_label.text() == "input ranges: reference +-0.1 V, DUT +-0.2 V"
    tab.clear()
    assert tab.ranges_label.text() == ""


def test_an_aborted_run_says_why_and_where_its_data_is(qtbot, tmp_path):
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.out = tmp_path
    record = RunRecord(run_id="r-1", status="aborted", abort_reason="cable", final_output_v=0.0)
    with qtbot.waitSignal(tab.ended) as blocker:
        tab.finish(Finished("aborted", "cable", None, record))
    assert blocker.args[0].abort_reason == "cable"
    assert tab.state.text() == "ABORTED: cable" and not tab.stop_button.isEnabled()
    assert str(tmp_path / "r-1") in tab.messages.text() and "0.0 V" in tab.messages.text()


def test_progress_moves_through_background_and_equalisation_and_says_aborted(qtbot, tmp_path):
    """Each phase has its own progress (not 0 % until acquisition), and an abort never leaves
    a stale acquisition estimate on the bar."""
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.ranges_v = {"reference": 2.0, "dut": 2.0}
    tab.out = tmp_path
    tab.frame = LiveFrame(steps=PhaseSteps(background_periods=4, equalisation_iterations=8))
    shown = []

    def feed(*events):
        tab.frame.take(list(events))
        tab.draw()
        shown.append((tab.progress.value(), tab.progress.format()))

    feed(StateChanged(State.BACKGROUND, "drive at 0 V"))
    feed(block(1, State.BACKGROUND, 0.0))
    feed(block(2, State.BACKGROUND, 0.0), block(3, State.BACKGROUND, 0.0))
    feed(StateChanged(State.EQUALISING, "closed loop, tolerance 1 %"))
    feed(block(4, State.EQUALISING, 0.1), EqualisationStep(1, np.zeros(3), 0.2))
    feed(EqualisationStep(2, np.zeros(3), 0.02))
    feed(StateChanged(State.ACQUIRING, ""), Progress(0.37, 3.0, 10.0))
    assert shown == [
        (0, "background: period 0 of 4"),
        (25, "background: period 1 of 4"),
        (75, "background: period 3 of 4"),
        (0, "equalisation 0 of at most 8"),
        (12, "equalisation 1 of at most 8"),
        (25, "equalisation 2 of at most 8"),
        (37, "acquiring 37 %, about 10 s left"),
    ]
    record = RunRecord(run_id="r-2", status="aborted", abort_reason="operator", final_output_v=0.0)
    tab.finish(Finished("aborted", "operator", None, record))
    assert tab.progress.format() == "aborted" and "left" not in tab.progress.text()


def test_phase_steps_come_from_the_procedures_settings():
    from app.procedure.settings import RunSettings

    class Stub:
        settings = RunSettings(background_periods=5, max_equalisation_iterations=3)

    assert PhaseSteps.of(Stub()) == PhaseSteps(5, 3)
    assert PhaseSteps.of(object()) == PhaseSteps()


def test_a_long_state_is_cut_only_with_the_whole_text_in_its_tooltip(qtbot):
    label = ElidedLabel()
    qtbot.addWidget(label)
    label.show()
    label.resize(120, 20)
    text = "equalising: closed loop, tolerance 0.5 %"
    label.setText(text)
    assert label.text() == text and label.toolTip() == text  # cut: the tooltip has it all
    assert QLabel.text(label) != text
    label.resize(2000, 20)
    qtbot.waitUntil(lambda: label.width() == 2000)
    assert QLabel.text(label) == text and label.toolTip() == ""  # whole: no tooltip needed


@pytest.mark.parametrize("fill_v, colour", [(1.89, "#27ae60"), (1.9, "#c0392b")])
def test_a_meter_turns_red_from_95_percent_of_range(qtbot, fill_v, colour):
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.ranges_v = {"reference": 2.0, "dut": 2.0}
    tab.frame = LiveFrame(block=block(1, State.ACQUIRING, fill_v))
    tab.draw()
    assert colour in tab.meters["reference"].styleSheet()


def test_the_live_plots_say_no_run_yet_until_a_period_and_name_their_traces(qtbot):
    from dsp.multisine import make_plan

    tab = RunTab()
    qtbot.addWidget(tab)
    live = tab.live
    assert not live.widget.showing_chart and "No run yet" in live.widget.message.text()
    legend = [label.text for _sample, label in live.wave_plot.legend.items]
    assert legend == ["reference", "DUT"]
    assert [label.text for _s, label in live.spec_plot.legend.items][:2] == ["reference", "DUT"]
    plan = make_plan([100.0, 200.0], 1000.0, 1000, 1.0, 100.0, phases_rad=np.zeros(2))
    x = np.sin(2 * np.pi * 100 * np.arange(1000) / 1000)
    live.draw_period(x, 0.5 * x, plan)
    assert live.widget.showing_chart
    tab.clear()  # a new run (or the next sensor): no plots of the last one, the line again
    assert not live.widget.showing_chart


def test_a_period_is_drawn_at_two_points_per_pixel_column_keeping_every_peak():
    from app.gui.plots import peak_decimated

    n = 51_200
    t = np.arange(n) / 51_200.0
    y = np.zeros(n)
    y[12_345], y[40_000] = 3.0, -2.0  # single-sample peaks
    xd, yd = peak_decimated(t, y, 640)
    assert yd.size <= 2 * 640 and yd.max() == 3.0 and yd.min() == -2.0
    assert np.all(np.diff(xd) >= 0)  # in time order
    assert xd[np.argmax(yd)] == t[12_345]
    _small_x, small_y = peak_decimated(t[:1000], y[:1000], 640)  # fewer than 4 per column
    assert small_y.size == 1000


def test_an_axis_moves_only_when_the_data_leaves_it_or_shrinks_far_inside():
    import pyqtgraph as pg

    from app.gui.plots import follow_y

    plot = pg.PlotItem()
    plot.disableAutoRange()
    assert follow_y(plot, -1.0, 1.0)
    low, high = plot.getViewBox().viewRange()[1]
    assert low == pytest.approx(-1.2) and high == pytest.approx(1.2)
    assert not follow_y(plot, -0.9, 1.05)  # inside: the axis (and its text) stays
    assert follow_y(plot, -0.9, 1.5)  # out: it follows
    assert follow_y(plot, -0.01, 0.01)  # far inside: it zooms in


class _OneShotProcedure:
    """A procedure's part for the worker: announces one state, then ends aborted at 0 V."""

    def __init__(self, plan) -> None:
        self.plan = plan
        self.listener = None

    def run(self) -> Finished:
        self.listener(StateChanged(State.ACQUIRING, "one shot"))
        record = RunRecord(run_id=None, status="aborted", abort_reason="done", final_output_v=0.0)
        return Finished("aborted", "done", None, record)

    def abort(self, reason: str = "") -> None:
        pass

    def close(self) -> None:
        pass


class _NoStand:
    def close(self) -> None:
        pass


def test_a_live_run_freezes_older_objects_out_of_the_collector_and_thaws_them_at_its_end(qtbot):
    """A full garbage collection over the window's objects stalls the GUI thread 50-90 ms
    (measured by bench/gui_responsiveness.py): during a run only the run's objects are scanned."""
    import gc

    from dsp.multisine import make_plan

    gc.unfreeze()
    tab = RunTab()
    qtbot.addWidget(tab)
    plan = make_plan([100.0, 1000.0], 10_000.0, 1000, 1.0, 100.0, phases_rad=np.zeros(2))
    tab.attach(_OneShotProcedure(plan), _NoStand(), {"reference": 2.0, "dut": 2.0})
    try:
        assert gc.get_freeze_count() > 1000
        # the charts are laid out with the plan's axes before the first period
        assert tab.live.widget.showing_chart
        low, high = tab.live.wave_plot.getViewBox().viewRange()[0]
        assert low < 0.0 < 0.0999 < high < 0.11  # 0 .. 999 / 10 kHz, 2 % padding
        low, high = tab.live.spec_plot.getViewBox().viewRange()[0]
        assert low < 1.0 < 3.69 < high < 3.8  # log10(10 Hz) .. log10(5 kHz)
        with qtbot.waitSignal(tab.ended, timeout=5000):
            pass
    finally:
        gc.unfreeze()
    tab.attach(_OneShotProcedure(plan), _NoStand(), {"reference": 2.0, "dut": 2.0})
    with qtbot.waitSignal(tab.ended, timeout=5000):
        pass
    assert gc.get_freeze_count() == 0


def test_a_meter_is_restyled_only_when_its_colour_changes(qtbot, monkeypatch):
    """A new style sheet re-polishes the widget: not once per frame."""
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.ranges_v = {"reference": 2.0, "dut": 2.0}
    bar = tab.meters["reference"]
    calls = []
    original = bar.setStyleSheet
    monkeypatch.setattr(bar, "setStyleSheet", lambda s: (calls.append(s), original(s)))
    for level in (0.5, 0.6, 0.7, 1.95, 1.96, 0.5):
        tab.frame = LiveFrame(block=block(1, State.ACQUIRING, level))
        tab.draw()
    assert len(calls) == 3 and "#27ae60" in calls[0] and "#c0392b" in calls[1]


def test_a_one_period_estimate_says_coherence_n_a_and_why(qtbot):
    """LPM (one period): NaN coherence at every line; the tab says n/a with the reason, and a
    run with coherence names its lowest line."""
    import dataclasses
    import math

    from app.formatting import COHERENCE_NOT_AVAILABLE
    from app.procedure.analysis import analyze
    from dsp.multisine import make_plan
    from tests.synthetic import lowpass_response, make_recording

    tab = RunTab()
    qtbot.addWidget(tab)
    plan = make_plan([10.0, 80.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)
    results = analyze(make_recording(plan, lowpass_response(), periods=3)).results
    tab.draw_characteristic(results)
    assert tab.coherence.text().startswith("coherence >= ")
    lines = tuple(dataclasses.replace(ln, coherence=math.nan) for ln in results.lines)
    tab.draw_characteristic(dataclasses.replace(results, lines=lines))
    assert tab.coherence.text() == COHERENCE_NOT_AVAILABLE


class _Opened:
    """A procedure's part: its plan, and a run that notes whether the tab had laid its plots
    out for the plan when the run began (then ends aborted at once)."""

    def __init__(self, plan, prepared: threading.Event) -> None:
        self.plan, self.listener, self.prepared = plan, None, prepared
        self.began_prepared: bool | None = None

    def run(self) -> Finished:
        self.began_prepared = self.prepared.is_set()
        record = RunRecord(run_id=None, status="aborted", abort_reason="done", final_output_v=0.0)
        return Finished("aborted", "done", None, record)

    def abort(self, reason: str = "") -> None:
        pass

    def close(self) -> None:
        pass


def test_a_run_begins_once_the_tab_has_painted_its_opened_plots(qtbot, tmp_path, monkeypatch):
    """Issue 34.6: the opened run waits for the tab's first paint of its plots, so that paint
    (tens of ms on the GUI thread) never competes with the run's start for the interpreter."""
    from dsp import iso266
    from dsp.multisine import make_plan

    freqs = iso266.nominal_frequencies(10, 1000)
    plan = make_plan(freqs, 8192.0, 8192, 1.0, 160.0, phases_rad=np.zeros(len(freqs)))
    prepared = threading.Event()
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.out = tmp_path
    laid_out = tab.live.prepare

    def prepare(plan_):
        laid_out(plan_)
        prepared.set()

    monkeypatch.setattr(tab.live, "prepare", prepare)
    procedure = _Opened(plan, prepared)
    worker = RunWorker.opening(lambda: (procedure, procedure))
    tab._start(worker, {"reference": 2.0, "dut": 2.0}, None)
    assert not worker.view_ready.is_set()  # cleared: the run will wait for the tab
    qtbot.waitUntil(lambda: worker.done, timeout=10_000)
    assert procedure.began_prepared is True
    assert tab.live.widget.showing_chart


def test_a_run_nobody_paints_for_waits_only_a_bounded_time(monkeypatch):
    from app.gui import worker as worker_module

    monkeypatch.setattr(worker_module, "VIEW_WAIT_S", 0.05)
    procedure = _Opened(None, threading.Event())
    worker = RunWorker.opening(lambda: (procedure, procedure))
    worker.view_ready.clear()  # as the tab does, but no tab will set it
    worker.start()
    assert worker.join(5.0)
    assert procedure.began_prepared is False and worker.finished is not None
