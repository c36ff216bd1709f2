"""When acquisition stops: one rule for the multisine and every stepped-sine line.

A run with a type A target is always bounded in time: by --max-time, else by
`default_time_bound_s` (DEFAULT_MAX_TIME_S of acquisition, or DEFAULT_MAX_PERIODS periods of
the plan when they are longer). When the bound ends it before the target, `TargetNotMet` says
so: the bound, which lines are above the target with their measured type A (and which of them
the run does not state: too few LSB above the converter's step), and what the worst would need
at the noise measured; the lines are stated with that type A.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

NO_PERIOD_LIMIT = 10**6  # with a type A target the periods are bounded by time (or this)
MIN_PERIODS_FOR_TARGET = 3  # a type A target is trusted from 3 periods on

# The default bound on the acquisition of a run with a type A target and no --max-time.
# 120 s: twenty times the 6 s (three 2 s periods) in which the shipped plans (piezo,
# capacitive) reach any target their noise allows at the seed level, and above the 114 s of
# acquisition the hardest row of docs/benchmarks.md table 2 needs (0.02 % at every line, each
# line only about 60 dB above the noise); a target that needs more is one the noise cannot
# reach in a run a lab would wait for (a capacitive run went on for 384 s until stopped).
DEFAULT_MAX_TIME_S = 120.0
# ... or ten periods of a long plan (0.4-8 Hz: 20-40 s periods): room for its type A to fall
# sqrt(10/3) = 1.8x below what the three periods a target needs give
DEFAULT_MAX_PERIODS = 10
DEFAULT_TIME_BOUND_TEXT = (
    f"default with --target-ua: {DEFAULT_MAX_TIME_S:g} s, or {DEFAULT_MAX_PERIODS} periods of "
    "the plan when they are longer; the run then reports the lines above the target with "
    "their measured type A"
)
MAX_LINES_LISTED = 12  # a report names at most this many lines (the rest are counted)


def default_time_bound_s(period_s: float) -> float:
    """The acquisition time bound (s) of a run with a type A target and no --max-time:
    DEFAULT_MAX_TIME_S, or DEFAULT_MAX_PERIODS periods of `period_s` (s) when longer."""
    return max(DEFAULT_MAX_TIME_S, DEFAULT_MAX_PERIODS * period_s)


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

    def remaining_s(
        self,
        count: int,
        period_s: float,
        elapsed_s: float = 0.0,
        worst_type_a: float | None = None,
    ) -> float | None:
        """Acquisition time still to go (s): the periods left; with a target, at the pace so
        far (type A falls as 1/sqrt(time)) after `elapsed_s` at `worst_type_a`, never past
        the time bound; None with a target and nothing measured yet."""
        target = self.target_type_a
        if target is None:
            return (self.period_limit - count) * period_s
        if worst_type_a is None or not (worst_type_a > 0 and elapsed_s > 0):
            return None
        pace = elapsed_s * max(0.0, (worst_type_a / target) ** 2 - 1.0)
        if self.max_time_s is not None:
            pace = min(pace, max(0.0, self.max_time_s - elapsed_s))
        return pace


@dataclass(frozen=True)
class TargetNotMet:
    """A time bound ended acquisition before the type A target (fractions, s): the lines
    above the target as (label, measured relative type A, stated) of `line_count`, the bound
    and whether it was the default, and the acquisition it allowed (`acquired_s`, `periods`;
    the stepped sine: per line, its share of the bound)."""

    target_type_a: float
    bound_s: float
    default_bound: bool
    acquired_s: float
    periods: int
    above: tuple[tuple[str, float, bool], ...]
    line_count: int
    per_line: bool = False  # the stepped sine: the bound shared out among its lines

    @property
    def worst_type_a(self) -> float:
        return max((a for _, a, _ in self.above), default=math.nan)

    @property
    def needed_s(self) -> float:
        """The acquisition the worst line would need at the noise measured (s): type A falls
        as 1/sqrt(time), so acquired * (worst / target)^2."""
        return self.acquired_s * (self.worst_type_a / self.target_type_a) ** 2

    def text(self) -> str:
        """The warning the run states (app.records.warnings: "type A target not met")."""
        if self.per_line:
            total = self.bound_s * self.line_count
            bound = (
                f"the time bound {self.bound_s:.3g} s per line ({total:.4g} s shared among "
                f"the {self.line_count} lines"
            )
            ended = f"ended the worst line's acquisition after {self.acquired_s:.3g} s"
        else:
            bound = f"the time bound {self.bound_s:g} s ("
            ended = f"ended the acquisition after {self.acquired_s:.3g} s"
        if self.default_bound:
            bound += "; " if self.per_line else ""
            bound += "the default with a type A target; --max-time sets another)"
        else:
            bound = bound.removesuffix(" (") + (")" if self.per_line else "")
        listed = [
            f"{label} {100 * a:.3g} %" + ("" if stated else " (not stated: too few LSB)")
            for label, a, stated in self.above[:MAX_LINES_LISTED]
        ]
        more = len(self.above) - len(listed)
        if more > 0:
            listed.append(f"and {more} more (their type A in the results)")
        return (
            f"type A target {100 * self.target_type_a:g} % not met: {bound} {ended} "
            f"({self.periods} period(s)); {len(self.above)} of {self.line_count} lines above "
            f"the target, their type A as measured: {', '.join(listed)}; every stated line is "
            "stated with the type A measured; at the noise measured the worst would need "
            f"about {_seconds(self.needed_s)} s of acquisition"
        )


def _seconds(value: float) -> str:
    """A time in s as the report prints it: 3 significant digits, whole seconds from 100 s."""
    return f"{value:.0f}" if value >= 100 else f"{value:.3g}"


def target_not_met(
    rule: StoppingRule,
    *,
    default_bound: bool,
    acquired_s: float,
    periods: int,
    labels: Sequence[str],
    type_a: Sequence[float],
    stated: Sequence[bool] | None = None,
) -> TargetNotMet | None:
    """The report of a run `rule` bounded before its target (None: no target, no bound, or
    every line within the target): `labels` and measured relative `type_a` per line, and
    whether each line is `stated` (None: all)."""
    target, bound = rule.target_type_a, rule.max_time_s
    if target is None or bound is None:
        return None
    flags = [True] * len(labels) if stated is None else [bool(x) for x in stated]
    above = tuple(
        (label, float(a), flag)
        for label, a, flag in zip(labels, type_a, flags, strict=True)
        if float(a) > target  # NaN: no type A, left out (as the stopping rule's nanmax)
    )
    if not above:
        return None
    return TargetNotMet(target, bound, default_bound, acquired_s, periods, above, len(labels))
