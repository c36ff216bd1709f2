"""Command-line option types shared by every `accelcal` command: bounded numbers whose
--help states their range (issue 12 point 7)."""

from __future__ import annotations

import argparse
import math
from typing import Any


class Bounded:
    """An argparse type: a finite number between `low` and `high` (inclusive unless `open_low`
    / `open_high`); an int type also takes integral float notation such as 1e3."""

    def __init__(
        self,
        kind: type,
        low: float,
        high: float,
        *,
        open_low: bool = False,
        open_high: bool = False,
        unit: str = "",
    ) -> None:
        self.kind, self.low, self.high = kind, low, high
        self.open_low, self.open_high, self.unit = open_low, open_high, unit
        self.__name__ = kind.__name__  # argparse names the type in its messages

    def describe(self) -> str:
        """The range as printed in --help, e.g. '(0, 1000] m/s^2'."""
        unit = f" {self.unit}" if self.unit else ""
        left, right = "(" if self.open_low else "[", ")" if self.open_high else "]"
        spec = "d" if self.kind is int else "g"
        return f"{left}{self.low:{spec}}, {self.high:{spec}}{right}{unit}"

    def __call__(self, text: str) -> float | int:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
        if self.kind is int:
            if value != int(value):
                raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}")
        too_low = value <= self.low if self.open_low else value < self.low
        too_high = value >= self.high if self.open_high else value > self.high
        if too_low or too_high:
            raise argparse.ArgumentTypeError(f"must be in {self.describe()}, got {text}")
        return int(value) if self.kind is int else value


def numeric_option(
    p: argparse.ArgumentParser | argparse._ArgumentGroup,
    flag: str,
    bounded: Bounded,
    help: str,
    **kwargs: Any,
) -> None:
    """Add a numeric option whose --help states its bounds."""
    bounds = bounded.describe().replace("%", "%%")  # argparse %-formats help texts
    p.add_argument(flag, type=bounded, help=f"{help}; {bounds}", **kwargs)
