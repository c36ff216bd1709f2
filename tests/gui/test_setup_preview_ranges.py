"""The Setup tab's preview states the input ranges and each channel's fewest LSB per line, and
names a line predicted too few LSB above the converter's step (issue 32 point 2)."""

from __future__ import annotations

from app.gui.setup_tab import describe_preview
from app.procedure.preflight import check_preflight
from app.procedure.service import PlanPreview
from app.stand import config as stand_config
from dsp.calibration import ReferenceChain
from dsp.multisine import make_plan

CONFIG = stand_config.load()
CHAIN = ReferenceChain((0.4, 20000.0), (1.0, 1.0), (0.0, 0.0), reference_gain=10.0)


def test_the_preview_shows_the_ranges_and_the_lines_too_few_lsb():
    plan = make_plan([0.5, 2.0, 8.0], 1000.0, 40000, [0.0005, 0.3, 5.0], 8.0, optimiser=None)
    report = check_preflight(plan, CONFIG, CHAIN, 10.2, per_line=True)
    text = describe_preview(PlanPreview(plan, report, (), ()), CONFIG.limits)
    assert "input ranges chosen from the predicted peaks: reference +-0.1 V" in text
    assert "DUT +-0.1 V (0.5-2 Hz), +-0.2 V (8-8 Hz)" in text
    assert "predicted: line 0.5 Hz: reference channel" in text
    assert "crest factor" in text  # what it showed before stays
