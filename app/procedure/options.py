"""Every option of a calibration run, once: `RunOptions` (typed values, units in the names) and
`RUN_OPTIONS`, the table of each option's flag, unit, bounds, help and parser, from which
`accelcal run`'s parser (app.cli.parser) and the GUI's Setup tab bindings are made.

Parsing text is one callable per option (`OptionSpec.parse`, ValueError naming the fault); a
quantity (`OptionSpec.quantity`) is read with its unit or as a bare number in the field's unit
by app.io.quantities (`0.5g`, `100mV/g`, `2min`), and every percent option reads a bare number
as percent (`0.2` and `0.2%` are 0.2 %). Levels in m/s^2 peak per line, sensitivities in
mV/(m/s^2), masses in g, times in s, the type A target as a fraction (the percent typed / 100,
converted here, once).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.io import quantities
from app.io.quantities import Quantity
from app.io.vocabulary import Mode
from app.lines import parse_frequencies
from app.procedure.modes import DEFAULT_STEPPED_BLOCK_S
from app.procedure.stopping import DEFAULT_TIME_BOUND_TEXT
from app.procedure.switches import CAPACITY_NOTE, EXACT_MAINS_HELP
from app.stand.simulated import CATALOGUE, EXCITERS
from dsp.estimators import DEFAULT_ESTIMATOR, Estimator, default_estimator, default_periods
from dsp.multisine import PRESETS
from dsp.profiles import Profile

if TYPE_CHECKING:
    from app.stand.dut import DutSpec
    from app.stand.simulated import DrivenHum, Fault


@dataclass(frozen=True)
class Bounds:
    """A closed or open interval [low, high] of a numeric option; `whole`: integers only."""

    low: float
    high: float
    open_low: bool = False
    open_high: bool = False
    whole: bool = False

    def describe(self, unit: str = "") -> str:
        """The range as --help and the GUI's tooltips print it, e.g. '(0, 1000] m/s^2'."""
        left, right = "(" if self.open_low else "[", ")" if self.open_high else "]"
        spec = "d" if self.whole else "g"
        low, high = (int(self.low), int(self.high)) if self.whole else (self.low, self.high)
        return f"{left}{low:{spec}}, {high:{spec}}{right}" + (f" {unit}" if unit else "")

    def contains(self, value: float) -> bool:
        too_low = value <= self.low if self.open_low else value < self.low
        too_high = value >= self.high if self.open_high else value > self.high
        return math.isfinite(value) and not (too_low or too_high)


def _lines(text: str) -> tuple[float, ...]:
    return tuple(parse_frequencies(text))


@dataclass(frozen=True)
class OptionSpec:
    """One run option: its RunOptions field `name`, command-line `flag`, `unit`, `bounds`
    (numbers), `choices` (words), `help`, and `parse` (text -> value; ValueError says why),
    or `quantity` (a number with its unit, within the quantity's range; the field's value is
    it divided by `per`). Neither: a number within `bounds` (the face's own bounded parser)."""

    name: str
    flag: str
    help: str
    unit: str = ""
    bounds: Bounds | None = None
    choices: tuple[str, ...] = ()
    parse: Callable[[str], Any] | None = None
    metavar: str | None = None
    quantity: Quantity | None = None  # read with its unit (app.io.quantities), in range
    per: float = 1.0  # the field holds the quantity / per (the type A target: % / 100)

    @property
    def dest(self) -> str:
        """The argparse destination the flag makes (--dut-id -> dut_id)."""
        return self.flag.lstrip("-").replace("-", "_")

    def full_help(self) -> str:
        """The help with the bounds, as --help and the GUI's tooltip show it."""
        if self.quantity is not None:
            return f"{self.help}; {self.quantity.describe()}"
        if self.bounds is None:
            return self.help
        return f"{self.help}; {self.bounds.describe(self.unit)}"


# The help of the run's switches (the command line's flags, the GUI's check boxes): one text
# each (EXACT_MAINS_HELP in app.procedure.switches, which `accelcal plan` reads light)
RESONANCE_HELP = (
    "after the run, search the DUT's mounted resonance in its response (a plan to "
    "20 kHz+ at a low level, e.g. --frequencies 1000,...,25000 --sample-rate 102400)"
)


# The run options that are numbers, words or lists (flags stay as `accelcal run` always had them).
RUN_OPTIONS: tuple[OptionSpec, ...] = (
    OptionSpec("dut", "--dut", "simulated DUT from the catalogue", choices=tuple(CATALOGUE)),
    OptionSpec("dut_id", "--dut-id", "serial number / identification of the DUT"),
    OptionSpec(
        "technician",
        "--technician",
        "who runs the calibration (stored with the run; the certificate's Prepared by)",
        metavar="NAME",
    ),
    OptionSpec(
        "nominal_mv_per_ms2",
        "--nominal-sensitivity",
        "DUT nominal, e.g. 10.2 (mV/(m/s^2)) or 100mV/g",
        unit="mV/(m/s^2)",
        quantity=quantities.NOMINAL_SENSITIVITY,
    ),
    OptionSpec("preset", "--preset", "plan (default: by DUT kind)", choices=tuple(sorted(PRESETS))),
    OptionSpec(
        "level_ms2",
        "--level",
        "peak acceleration per line, e.g. 5 or 0.5g (default 5)",
        unit="m/s^2",
        quantity=quantities.LEVEL,
    ),
    OptionSpec(
        "periods",
        "--periods",
        "periods to acquire (default 1 with lpm, one record; 8 with periodic, h1, seed)",
        bounds=Bounds(1, 10_000, whole=True),
    ),
    OptionSpec(
        "frequencies_hz",
        "--frequencies",
        "line list in Hz, e.g. 0.4,...,8 (ISO 266 fill)",
        unit="Hz",
        parse=_lines,
    ),
    OptionSpec(
        "sample_rate_hz",
        "--sample-rate",
        f"sample rate in Hz ({CAPACITY_NOTE})",
        unit="Hz",
        quantity=quantities.SAMPLE_RATE,
    ),
    OptionSpec(
        "period_samples",
        "--period",
        f"period in samples (default: the shortest that fits; {CAPACITY_NOTE})",
        unit="samples",
        bounds=Bounds(4, 2**24, whole=True),
    ),
    OptionSpec(
        "reference_frequency_hz",
        "--reference-frequency",
        "reference frequency in Hz",
        unit="Hz",
        quantity=quantities.LINE_FREQUENCY,
    ),
    OptionSpec(
        "profile",
        "--profile",
        "per-line level: constant acceleration, or constant velocity or displacement below "
        "--corner (then --level above it); every line clipped by the exciter's stroke",
        choices=tuple(p.value for p in Profile),
    ),
    OptionSpec(
        "corner_hz",
        "--corner",
        "corner frequency of the profile, Hz",
        unit="Hz",
        quantity=quantities.LINE_FREQUENCY,
    ),
    OptionSpec(
        "exciter",
        "--exciter",
        "simulated stand's exciter (long-stroke: 150 mm, 0.4 Hz up); its stroke clips and "
        "checks the plan",
        choices=tuple(EXCITERS),
    ),
    OptionSpec(
        "fade_in_s",
        "--fade-in",
        "lpm: fade-in before the record, s (default one cycle of the lowest line, longer "
        "near the stroke)",
        unit="s",
        quantity=quantities.FADE_IN,
    ),
    OptionSpec(
        "target_type_a",
        "--target-ua",
        f"stop at this relative type A, {quantities.PERCENT_RULE}",
        unit="%",
        quantity=quantities.TARGET_UA,
        per=100.0,  # RunOptions holds the fraction
    ),
    OptionSpec(
        "max_acquisition_s",
        "--max-time",
        f"bound on the acquisition time, e.g. 30s or 2min ({DEFAULT_TIME_BOUND_TEXT})",
        unit="s",
        quantity=quantities.MAX_TIME,
    ),
    OptionSpec(
        "estimator",
        "--estimator",
        "line estimator (default: lpm, one period, for a multisine; periodic for a stepped sine)",
        choices=tuple(e.value for e in Estimator),
    ),
    OptionSpec("mode", "--mode", "excitation", choices=tuple(m.value for m in Mode)),
    OptionSpec(
        "stepped_block_s",
        "--stepped-block",
        f"stepped sine: the shortest block of one sine fit, in s, e.g. 0.05 or 50ms (default "
        f"{DEFAULT_STEPPED_BLOCK_S:g} s; rounded up to whole cycles of the line and of the "
        "mains): shorter blocks cut each line's fixed cost (its fade-in, level loop and settle "
        "are counted in blocks), longer ones average more noise per fit and per settle test",
        unit="s",
        quantity=quantities.STEPPED_BLOCK,
    ),
    OptionSpec(
        "tolerance_percent",
        "--tolerance",
        f"DUT tolerance of the characteristic, {quantities.PERCENT_RULE}",
        unit="%",
        quantity=quantities.TOLERANCE,
    ),
    OptionSpec(
        "dut_mass_g",
        "--dut-mass",
        "DUT mass in g: its class picks the stand's stored response (default: the simulated "
        "DUT's catalogue mass; on real hardware not stated)",
        unit="g",
        quantity=quantities.DUT_MASS,
    ),
    OptionSpec(
        "seed", "--seed", "simulated stand: random seed", bounds=Bounds(0, 2**32 - 1, whole=True)
    ),
    OptionSpec(
        "reference_override",
        "--reference-override",
        "with records in use: use a reference standard past its due date or not in the "
        "records, for this stated reason (recorded in results.json, the audit trail and on "
        "the certificate)",
        metavar="REASON",
    ),
)

OPTION_BY_NAME: Mapping[str, OptionSpec] = {spec.name: spec for spec in RUN_OPTIONS}


def option(name: str) -> OptionSpec:
    """The spec of RunOptions field `name` (KeyError: no such option)."""
    return OPTION_BY_NAME[name]


@dataclass(frozen=True)
class RunOptions:
    """What the operator asks of one run, every option once (None: not given, the DUT's or
    the stand file's value or the default applies). Units in the names."""

    stand_file: Path | None = None  # None: the simulated stand
    dut: str = "piezo"  # the simulated stand's catalogue DUT
    dut_id: str | None = None
    sensor: str | None = None  # a serial in the records: the DUT's settings from there
    dut_spec: DutSpec | None = None  # resolved already (the GUI's serial look-up)
    teds: bool = False  # identify the DUT by its TEDS
    technician: str | None = None
    nominal_mv_per_ms2: float | None = None
    tolerance_percent: float | None = None
    dut_mass_g: float | None = None
    preset: str | None = None
    level_ms2: float | None = None  # None: the DUT's, else 5 m/s^2
    periods: int | None = None  # None: 1 with lpm, else 8 (dsp.estimators.default_periods)
    frequencies_hz: tuple[float, ...] | None = None
    sample_rate_hz: float | None = None
    period_samples: int | None = None
    reference_frequency_hz: float | None = None
    profile: Profile = Profile.ACCELERATION
    corner_hz: float | None = None
    exciter: str | None = None
    fade_in_s: float | None = None
    target_type_a: float | None = None  # fraction: 0.002 = 0.2 %
    max_acquisition_s: float | None = None  # None: with a target, the default bound
    estimator: Estimator = DEFAULT_ESTIMATOR
    mode: Mode = Mode.MULTISINE
    stepped_block_s: float | None = None  # None: DEFAULT_STEPPED_BLOCK_S
    stored_response: bool = True  # start equalisation from the stand's stored response
    seed: int = 0
    paced: bool = False
    faults: tuple[Fault, ...] = ()
    sim_hum: tuple[DrivenHum, ...] = ()  # simulated stand: hum only while driven (--sim-hum)
    exact_mains_bins: bool = False  # keep lines on mains harmonics (--exact-mains-bins)
    out: Path = Path("runs")
    db: str | None = None  # records URL (None: $ACCELCAL_DB, else the default file)
    records: bool | None = None  # records in use; None: when a sensor or a records file is
    reference_override: str | None = None  # the reason to go past the reference check
    fail_exit: bool = False  # a completed run whose verdict is FAIL exits EXIT_FAIL_VERDICT
    resonance: bool = False  # search the mounted resonance in the response (dsp.resonance)

    def __post_init__(self) -> None:
        for name, enum in (("estimator", Estimator), ("mode", Mode), ("profile", Profile)):
            value = getattr(self, name)
            try:
                object.__setattr__(self, name, enum(value))
            except ValueError:
                words = ", ".join(m.value for m in enum)
                raise ValueError(f"{name}: {value!r} is not one of {words}") from None
        if self.stepped_block_s is not None and self.mode != Mode.STEPPED_SINE:
            raise ValueError(
                f"--stepped-block: the stepped sine's block; this run is --mode {self.mode} "
                f"(add --mode {Mode.STEPPED_SINE} or leave it out)"
            )

    @property
    def periods_to_run(self) -> int:
        """The periods acquired: as given, else one record of one period (lpm) or 8."""
        if self.periods is not None:
            return self.periods
        return default_periods(self.estimator)

    def replace(self, **changes: Any) -> RunOptions:
        return dataclasses.replace(self, **changes)

    @classmethod
    def from_values(cls, values: Mapping[str, Any], **more: Any) -> RunOptions:
        """Options from parsed values keyed by the table's argparse destinations (a face's
        parsed command line: None and absent are "not given"), and `more` by field name."""
        given: dict[str, Any] = {}
        for spec in RUN_OPTIONS:
            value = values.get(spec.dest)
            if value is not None:
                given[spec.name] = value
        given.update(more)
        if given.get("estimator") is None:  # not given: the mode's (lpm for a multisine)
            given["estimator"] = default_estimator(str(given.get("mode") or Mode.MULTISINE))
        return cls(**given)


def parse_option(name: str, text: str) -> Any:
    """`text` parsed as the option `name` (ValueError naming its flag): the option's own
    parser, else a number within its bounds."""
    spec = option(name)
    if spec.quantity is not None:  # its refusal names the flag already
        return spec.quantity.parse(text, spec.flag) / spec.per
    try:
        if spec.parse is not None:
            return spec.parse(text)
        if spec.choices:
            if text not in spec.choices:
                raise ValueError(f"{text!r} is not one of {', '.join(spec.choices)}")
            return text
        if spec.bounds is None:
            return text
        value = float(text)
    except ValueError as exc:
        raise ValueError(f"{spec.flag}: {exc}") from None
    if not spec.bounds.contains(value) or (spec.bounds.whole and value != int(value)):
        raise ValueError(f"{spec.flag}: must be in {spec.bounds.describe(spec.unit)}, got {text}")
    return int(value) if spec.bounds.whole else value


__all__ = [
    "CAPACITY_NOTE",
    "EXACT_MAINS_HELP",
    "OPTION_BY_NAME",
    "RESONANCE_HELP",
    "RUN_OPTIONS",
    "Bounds",
    "OptionSpec",
    "RunOptions",
    "option",
    "parse_option",
]
