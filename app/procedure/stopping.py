"""When acquisition stops: one rule for the multisine and every stepped-sine line."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

NO_PERIOD_LIMIT = 10**6  # with a type A target the periods are bounded by time (or this)
MIN_PERIODS_FOR_TARGET = 3  # a type A target is trusted from 3 periods on


class Stop(StrEnum):
    PERIODS = "periods"  # the requested number of periods is acquired
    TARGET = "target"  # the worst line's type A reached the target
    TIME_BOUND = "time bound"  # another period would exceed the time bound


@dataclass(frozen=True)
class StoppingRule:
    """L periods, or until a relative type A target (from `min_periods` on), within an optional
    bound on the acquisition's excitation time (s)."""

    periods: int
    target_type_a: float | None = None
    max_time_s: float | None = None
    min_periods: int = MIN_PERIODS_FOR_TARGET  # the lpm states type A from one period

    @property
    def period_limit(self) -> int:
        """Periods after which acquisition stops whatever the estimate."""
        return self.periods if self.target_type_a is None else NO_PERIOD_LIMIT

    def decide(
        self, count: int, worst_type_a: float, elapsed_s: float, period_s: float
    ) -> Stop | None:
        """Why to stop after `count` periods (worst relative type A `worst_type_a`, `elapsed_s`
        of acquisition so far, `period_s` per further period), or None to go on."""
        if count >= self.period_limit:
            return Stop.PERIODS
        target = self.target_type_a
        if target is not None and worst_type_a <= target and count >= self.min_periods:
            return Stop.TARGET
        if self.max_time_s is not None and elapsed_s + period_s > self.max_time_s:
            return Stop.TIME_BOUND
        return None

    def fraction(self, count: int, worst_type_a: float) -> float:
        """Progress 0..1: periods done, or how close the type A is to its target."""
        if self.target_type_a is None:
            return min(1.0, count / self.period_limit)
        return min(1.0, (self.target_type_a / worst_type_a) ** 2)

    def remaining_s(self, count: int, period_s: float) -> float | None:
        """Acquisition time still to go (s); None when a target decides."""
        if self.target_type_a is not None:
            return None
        return (self.period_limit - count) * period_s
