"""The shared stopping rule of the procedure (app.procedure.stopping), on its own."""

from __future__ import annotations

import pytest

from app.procedure import Stop, StoppingRule


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
