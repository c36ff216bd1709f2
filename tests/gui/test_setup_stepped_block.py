"""Issue 34 point 5 in the Setup tab: the stepped sine's block is a field of that mode (its
value reaches the run options as `--stepped-block` does; refused text marks the field and keeps
Start off), and the time bound's empty value and tooltip state the default bound."""

from __future__ import annotations

import pytest

from app.gui.main_window import MainWindow
from app.procedure.modes import DEFAULT_STEPPED_BLOCK_S


@pytest.fixture()
def setup(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4)
    qtbot.addWidget(w)
    w.wait_for_plans()
    return w.setup_tab


def test_the_block_is_a_stepped_sine_field_that_reaches_the_run(setup):
    assert setup.mode.currentText() == "multisine"
    assert not setup.stepped_block.isEnabled()
    assert setup.stepped_block.value() == DEFAULT_STEPPED_BLOCK_S
    assert setup.run_options().stepped_block_s is None  # a multisine run has no block
    setup.mode.setCurrentText("stepped-sine")
    assert setup.stepped_block.isEnabled()
    assert setup.run_options().stepped_block_s == DEFAULT_STEPPED_BLOCK_S
    setup.stepped_block.setText("100 ms")
    assert setup.run_options().stepped_block_s == pytest.approx(0.1)
    assert setup.plan_settings().stepped_block_s == pytest.approx(0.1)
    tip = setup.stepped_block.toolTip()
    assert "in s" in tip and "shorter blocks cut each line's fixed cost" in tip


def test_a_refused_block_marks_its_field_and_keeps_start_off(setup):
    setup.mode.setCurrentText("stepped-sine")
    setup.wait_for_plans()
    assert setup.start_button.isEnabled()
    setup.stepped_block.setText("20 s")
    setup.validate()
    assert not setup.start_button.isEnabled()
    assert "stepped block" in setup.field_marks.marked().get("stepped_block", "")
    setup.mode.setCurrentText("multisine")  # not this mode's field: it refuses nothing
    setup.wait_for_plans()
    assert setup.start_button.isEnabled()


def test_the_time_bound_states_the_default_with_a_target(setup):
    assert setup.max_time.value() == 0
    assert "default (120 s with a target" in setup.max_time.specialValueText()
    assert "default with --target-ua: 120 s" in setup.max_time.toolTip()
    setup.target.setValue(0.2)
    assert setup.request().max_acquisition_s is None  # the run applies the default
