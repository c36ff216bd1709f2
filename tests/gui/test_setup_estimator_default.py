"""Issue 34 point 1: the Setup tab opens on the default estimator (the one-period lpm) and
its periods follow the estimator's default while the operator has not typed a count."""

from __future__ import annotations

import os

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from app.gui.main_window import MainWindow
from dsp.estimators import DEFAULT_ESTIMATOR


@pytest.fixture()
def window(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4)
    qtbot.addWidget(w)
    w.wait_for_plans()
    return w


def test_the_setup_tab_opens_on_the_lpm_and_the_periods_follow_the_estimator(window):
    tab = window.setup_tab
    assert tab.estimator.currentText() == DEFAULT_ESTIMATOR == "lpm"
    assert tab.periods.value() == 1 and tab.periods.minimum() == 1
    assert tab.start_button.isEnabled()
    options = tab.run_options()
    assert options.estimator == "lpm" and options.periods == 1
    tab.estimator.setCurrentText("periodic")
    assert tab.periods.value() == 8  # the averaging estimators' default
    tab.estimator.setCurrentText("lpm")
    assert tab.periods.value() == 1
    tab.periods.setValue(5)  # a count the operator typed stays
    tab.estimator.setCurrentText("h1")
    assert tab.periods.value() == 5
    tab.estimator.setCurrentText("lpm")
    tab.mode.setCurrentText("stepped-sine")  # no lpm there: its default, periodic
    assert tab.estimator.currentText() == "periodic"
    tab.mode.setCurrentText("multisine")
    tab.reset()  # Next sensor: the tab as it opened
    assert tab.estimator.currentText() == "lpm" and tab.periods.value() == 1
