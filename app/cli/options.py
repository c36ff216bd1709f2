"""Command-line option types and values shared by the `accelcal` commands: bounded numbers
whose --help states their range (issue 12 point 7), and the checks of option values that
argparse cannot make (a UsageError naming the option)."""

from __future__ import annotations

import argparse
import difflib
import math
import re
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app import lines
from app.cli.exits import UsageError
from app.files import FileExistsRefusal, check_target
from app.io import quantities
from app.io.quantities import Quantity, QuantityError

if TYPE_CHECKING:
    from app.stand.simulated import DrivenHum, Fault
    from dsp.multisine import Plan

# the plan, the catalogue and the simulated stand are imported by the functions that use them:
# they import numpy, which the records commands never need (issue 34)


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


class QuantityType:
    """An argparse type: a quantity with its unit or a bare number in the quantity's unit
    (app.io.quantities), within its range, divided by `per`; the reason of a refusal is
    argparse's message."""

    def __init__(self, quantity: Quantity, *, per: float = 1.0) -> None:
        self.quantity, self.per = quantity, per  # the value is the quantity / per (% -> 1)
        self.__name__ = quantity.dimension.noun.split()[-1]  # argparse names the type

    def describe(self) -> str:
        """The range and the units accepted, as printed in --help."""
        dimension = self.quantity.dimension
        if dimension is quantities.PERCENT:  # its help states the percent rule
            return self.quantity.describe()
        return f"{self.quantity.describe()} (units: {dimension.accepted})"

    def __call__(self, text: str) -> float:
        try:
            return self.quantity.parse(text, "") / self.per
        except QuantityError as exc:
            raise argparse.ArgumentTypeError(exc.reason) from None


def numeric_option(
    p: argparse.ArgumentParser | argparse._ArgumentGroup,
    flag: str,
    bounded: Bounded | QuantityType,
    help: str,
    **kwargs: Any,
) -> None:
    """Add a numeric option whose --help states its bounds."""
    bounds = bounded.describe().replace("%", "%%")  # argparse %-formats help texts
    p.add_argument(flag, type=bounded, help=f"{help}; {bounds}", **kwargs)


# The bounds of every numeric option (also in docs/reliability.md).
SAMPLE_RATE = QuantityType(quantities.SAMPLE_RATE)

PERIOD = Bounded(int, 4, 2**24, unit="samples")  # 100 s at 102.4 kS/s fits

FADE_IN = QuantityType(quantities.FADE_IN)

LEVEL = QuantityType(quantities.LEVEL)

FREQUENCY = QuantityType(quantities.LINE_FREQUENCY)

MAINS = QuantityType(quantities.MAINS)

SEGMENTS = Bounded(int, 1, 10_000)

COVERAGE = Bounded(float, 0.0, 1.0, open_low=True, open_high=True)

TOLERANCE = QuantityType(quantities.TOLERANCE)

SENSITIVITY = QuantityType(quantities.NOMINAL_SENSITIVITY)

DUT_MASS = QuantityType(quantities.DUT_MASS)

GAIN = Bounded(float, 0.0, 1e6, open_low=True, unit="V/V")

SKEW = QuantityType(quantities.SKEW)

SETTLE_PERIODS = Bounded(int, 0, 10_000)

RANGE = Bounded(float, 0.0, 1000.0, open_low=True, unit="V")

RUN_PERIODS = Bounded(int, 1, 10_000)  # the estimator's own minimum: dsp.spectral

SIM_PERIODS = Bounded(int, 1, 10_000)

SIM_SETTLE = Bounded(int, 0, 1000)

SEED = Bounded(int, 0, 2**32 - 1)

TEMPERATURE = Bounded(float, -50.0, 150.0, unit="deg C")


def parse_frequencies(text: str) -> list[float]:
    """--frequencies: a line list (see app.lines.parse_frequencies)."""
    try:
        return lines.parse_frequencies(text)
    except ValueError as exc:
        raise UsageError(f"--frequencies: {exc}") from None


def positive(name: str, value: float | None) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise UsageError(f"{name}: must be > 0, got {value:g}")


def plan_from_options(args: argparse.Namespace, *, optimise: bool) -> Plan:
    """The plan the options describe: a preset, with any of its fields overridden."""
    from app.procedure.phase_store import stored_phases
    from dsp.multisine import PRESETS, make_plan

    preset = PRESETS[args.preset or "piezo"]
    freqs = (
        parse_frequencies(args.frequencies)
        if args.frequencies is not None
        else list(preset.nominal_frequencies_hz)
    )
    for name in ("sample_rate", "level", "reference_frequency", "mains"):
        positive("--" + name.replace("_", "-"), getattr(args, name))
    if args.period is not None and args.period < 4:
        raise UsageError(f"--period: must be >= 4 samples, got {args.period}")
    return make_plan(
        freqs,
        args.sample_rate or preset.sample_rate_hz,
        args.period or preset.period_samples,
        args.level or preset.level_ms2,
        args.reference_frequency or preset.reference_frequency_hz,
        mains_frequency_hz=args.mains if args.mains is not None else 50.0,
        shift_mains_lines=not getattr(args, "exact_mains_bins", False),
        phases_rad=None if optimise else [0.0] * len(freqs),
        optimiser=stored_phases,
    )


def dut_name(text: str) -> str:
    """--dut: a DUT of the simulated stand's catalogue (argparse type)."""
    from app.stand.simulated import CATALOGUE

    if text in CATALOGUE:
        return text
    close = difflib.get_close_matches(text, list(CATALOGUE), n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise argparse.ArgumentTypeError(
        f"{text!r} is not in the DUT catalogue ({', '.join(CATALOGUE)}){hint}"
    )


def dut_entry(text: str) -> str | tuple[str, str]:
    """--dut: a catalogue DUT (MODEL), or one DUT of several in one run (POSITION=SERIAL:
    a position of the stand file's fixture and the DUT's serial); argparse type."""
    if "=" not in text:
        return dut_name(text)
    position, serial = (part.strip() for part in text.split("=", 1))
    if not re.fullmatch(r"[A-Za-z0-9_-]{1,16}", position):
        raise argparse.ArgumentTypeError(
            f"{text!r}: POSITION must be 1-16 of A-Z a-z 0-9 _ - (a [[fixture.position]] name)"
        )
    if not serial:
        raise argparse.ArgumentTypeError(f"{text!r}: no SERIAL after '='")
    return position, serial


def sim_hum_option(texts: list[str]) -> tuple[DrivenHum, ...]:
    """--sim-hum AMPLITUDE@FREQUENCY options as hum of the simulated stand while driven."""
    from app.stand.simulated import parse_sim_hum

    try:
        return parse_sim_hum(texts)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def faults_option(texts: list[str]) -> tuple[Fault, ...]:
    """--fault KIND@SECONDS options as faults of the simulated stand."""
    from app.stand.simulated import parse_faults

    try:
        return parse_faults(texts)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def levels_option(text: str) -> list[float]:
    """--levels: a comma-separated list, every item within the bounds of --level."""
    levels = []
    for item in text.split(","):
        if not item.strip():
            raise UsageError(f"--levels: {text!r} has an empty item")
        try:
            levels.append(LEVEL(item.strip()))
        except argparse.ArgumentTypeError as exc:
            raise UsageError(f"--levels: {item.strip()!r}: {exc}") from None
    return levels


def writable_folder(folder: Path, option: str) -> None:
    """UsageError naming `option` unless files can be created in `folder` (made if missing):
    its nearest existing ancestor must be a folder in which a file can really be created (a
    probe, so that read-only file systems are caught even when running as root)."""
    probe = folder
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise UsageError(f"{option}: {folder}: cannot be created ({probe} is not a folder)")
    try:
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise UsageError(f"{option}: {folder}: not writable ({reason})") from None


def output_target(
    target: Path, option: str, inputs: tuple[Path | None, ...], overwrite: bool
) -> None:
    """UsageError naming `option` when `target` is an input, inside a run folder, or exists
    without --overwrite."""
    from app.records.run_folder import refuse_in_run_folder

    try:
        check_target(target, inputs=inputs, overwrite=overwrite)
        refuse_in_run_folder(target)
    except FileExistsRefusal as exc:
        raise UsageError(f"{option}: {exc} (--overwrite replaces it)") from None
    except ValueError as exc:
        raise UsageError(f"{option}: {exc}") from None
