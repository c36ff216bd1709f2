"""The Run tab's typed live frame and its drawing, without a stand: what a frame keeps of the
worker's events and what the tab shows of it."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from app.gui.run_tab import LiveFrame, RunTab
from app.procedure import (
    EqualisationStep,
    Finished,
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
    assert frame.state == f"{State.ACQUIRING}  "
    assert frame.equalisation == "equalisation 2: worst line 0.56 %"
    assert frame.progress == (0.5, None)
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
        progress=(0.4, 12.0),
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


@pytest.mark.parametrize("fill_v, colour", [(1.89, "#27ae60"), (1.9, "#c0392b")])
def test_a_meter_turns_red_from_95_percent_of_range(qtbot, fill_v, colour):
    tab = RunTab()
    qtbot.addWidget(tab)
    tab.ranges_v = {"reference": 2.0, "dut": 2.0}
    tab.frame = LiveFrame(block=block(1, State.ACQUIRING, fill_v))
    tab.draw()
    assert colour in tab.meters["reference"].styleSheet()
