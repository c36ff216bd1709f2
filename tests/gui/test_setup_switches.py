"""The Setup tab's switches reach the run as the command line's flags do (issue 32 points 3
and 5): lines kept on exact mains harmonics (the preview's plan changes with it), the resonance
search, and the simulated stand's hum while driven given to `accelcal gui --sim-hum`."""

from __future__ import annotations

import pytest

from app.cli.options import sim_hum_option
from app.gui.main_window import MainWindow


@pytest.fixture()
def setup(qtbot, tmp_path):
    hum = sim_hum_option(["1mV@50.3Hz"])
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4, sim_hum=hum)
    qtbot.addWidget(w)
    w.wait_for_plans()
    return w.setup_tab


def _lines_near_50_hz(setup) -> list[float]:
    setup.wait_for_plans()
    assert setup.preview is not None
    return [f for f in setup.preview.plan.frequencies_hz if 45.0 < f < 55.0]


def test_exact_mains_bins_moves_the_previewed_line_back_onto_50_hz(setup, qtbot):
    setup.preset.setCurrentText("piezo")
    assert _lines_near_50_hz(setup) != [50.0]  # by default one bin off the mains harmonic
    assert not setup.run_options().exact_mains_bins
    setup.exact_mains_bins.click()
    assert _lines_near_50_hz(setup) == [50.0]
    assert setup.run_options().exact_mains_bins
    assert "exact bins" in setup.exact_mains_bins.toolTip()


def test_the_resonance_search_and_the_hum_while_driven_reach_the_run_options(setup):
    options = setup.run_options()
    assert not options.resonance
    assert [(h.frequency_hz, h.dut_v) for h in options.sim_hum] == [(50.3, 0.001)]
    setup.resonance.click()
    assert setup.run_options().resonance


def test_the_checks_say_what_the_plan_does_with_the_mains_lines(setup, qtbot):
    """The checks beside the fields speak of the lines as they will be played: moved one bin
    off the mains harmonics by default, kept on them (with the hum warning) when asked."""
    setup.preset.setCurrentText("piezo")
    setup.wait_for_plans()
    text = setup.checks.text()
    assert "line 50 Hz: moved one bin off the 1st mains harmonic (50 Hz) to 50.5 Hz" in text
    assert "a periodic average does not remove hum" not in text
    setup.exact_mains_bins.click()
    setup.wait_for_plans()
    text = setup.checks.text()
    assert "line 50 Hz: on the 1st mains harmonic (50 Hz)" in text
    assert "moved one bin" not in text
