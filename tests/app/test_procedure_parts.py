"""The procedure's small parts on their own: the shared stopping rule and the one preflight."""

from __future__ import annotations

import pytest

from app.procedure import PreflightError, Stop, StoppingRule, check_preflight
from app.stand import config as stand_config
from app.stand.open import open_stand
from dsp.multisine import preset_plan

CONFIG = stand_config.load()


def test_a_fixed_number_of_periods_stops_at_that_count():
    rule = StoppingRule(periods=4)
    assert [rule.decide(n, 0.5, 0.0, 2.0) for n in (3, 4)] == [None, Stop.PERIODS]
    assert rule.fraction(2, 0.5) == 0.5 and rule.remaining_s(3, 2.0) == 2.0


def test_a_type_a_target_needs_three_periods_and_then_stops():
    rule = StoppingRule(periods=8, target_type_a=0.002)
    assert rule.decide(2, 0.001, 0.0, 2.0) is None  # met, but too few periods to trust it
    assert rule.decide(3, 0.001, 0.0, 2.0) is Stop.TARGET
    assert rule.decide(30, 0.003, 0.0, 2.0) is None  # the period count no longer bounds it
    assert rule.remaining_s(3, 2.0) is None and rule.fraction(3, 0.004) == pytest.approx(0.25)


def test_the_time_bound_stops_before_a_period_that_would_exceed_it():
    rule = StoppingRule(periods=8, target_type_a=0.001, max_time_s=10.0)
    assert rule.decide(3, 0.01, 8.0, 2.0) is None  # 8 + 2 = 10 s: still within
    assert rule.decide(4, 0.01, 8.5, 2.0) is Stop.TIME_BOUND
    assert StoppingRule(periods=8, max_time_s=5.0).decide(3, 0.01, 4.0, 2.0) is Stop.TIME_BOUND


def test_preflight_reports_peaks_and_scales_with_the_level():
    stand = open_stand(CONFIG, dut="piezo")
    try:
        plan = preset_plan("piezo", level_ms2=1.0)
        ok = check_preflight(plan, stand.config, stand.chain)
        assert ok.ok and ok.summary().startswith("preflight: peaks")
        at_50 = check_preflight(plan, stand.config, stand.chain, level_scale=50.0)
        assert at_50.peaks.acceleration_ms2 == pytest.approx(50 * ok.peaks.acceleration_ms2)
        assert any("exceeds the exciter's 8 mm" in p for p in at_50.problems)
        with pytest.raises(PreflightError, match="displacement"):
            at_50.raise_if_refused()
    finally:
        stand.close()
