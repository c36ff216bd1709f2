"""The stand file's fixture (issue 36): `[fixture]` and its `[[fixture.position]]` entries, the
positions several DUTs are mounted at in one run.

Without `[fixture]` a stand is a single-DUT stand. With it, each position names its DAQ input
(`physical`, or `axes = {x, y, z}` for a triaxial DUT); the inputs take [daq.dut]'s settings
(range, coupling, IEPE current, terminal) and are named `dut.<position>` (`dut.<position>.x`
...). The stated relative motion of a position against the reference axis (standard
uncertainty, percent, log-log interpolated between the stated frequencies, held flat outside)
and the fixture's stated crosstalk are type B components of that position's DUT's budget.
Masses in kg as the stand file states them; refusals are ConfigError naming the key.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from app.stand.schema import POSITION_KEYS, SCHEMA
from dsp.uncertainty import (
    Budget,
    Component,
    Distribution,
    Law,
    Quantity,
    iso_16063_21_limit,
)
from hardware.interfaces import InputChannel

POSITION_NAME = re.compile(r"^[A-Za-z0-9_-]{1,16}$")
AXES = ("x", "y", "z")
MOTION_NAME = "fixture relative motion"  # each component's name begins so (one per segment)
CROSSTALK_NAME = "fixture crosstalk"


class FixtureError(ValueError):
    """A [fixture] entry that cannot be used: '<key>: <why>'."""


@dataclass(frozen=True)
class MotionTable:
    """A stated term against frequency: (Hz, value) points, log-log interpolated between them
    and held flat outside; values in the table's unit (percent, or degrees)."""

    points: tuple[tuple[float, float], ...] = ()

    def at(self, frequency_hz: float) -> float:
        """The value at `frequency_hz` (Hz); 0 for an empty table."""
        pts = self.points
        if not pts:
            return 0.0
        if frequency_hz <= pts[0][0]:
            return pts[0][1]
        for (f1, v1), (f2, v2) in itertools.pairwise(pts):
            if frequency_hz <= f2:
                if v1 <= 0 or v2 <= 0:  # a zero point: linear in log f
                    t = math.log(frequency_hz / f1) / math.log(f2 / f1)
                    return v1 + t * (v2 - v1)
                n = math.log(v2 / v1) / math.log(f2 / f1)
                return v1 * (frequency_hz / f1) ** n
        return pts[-1][1]


@dataclass(frozen=True)
class FixturePosition:
    """One mounting position: its name, DAQ input(s), distance from the reference axis (mm),
    mass limit (kg; None: only the fixture's total), stated relative motion (percent) and its
    phase term (degrees)."""

    name: str
    physical: str | None = None
    axes: Mapping[str, str] | None = None  # triaxial: {"x": physical, "y": ..., "z": ...}
    distance_mm: float = 0.0
    azimuth_deg: float = 0.0
    mass_limit_kg: float | None = None
    relative_motion: MotionTable = MotionTable()
    relative_motion_phase_deg: MotionTable = MotionTable()
    # its input's stated sampling delay after the reference (s; None: [daq] skew_s holds)
    skew_s: float | None = None
    # a triaxial position: the table's acceleration along a transverse axis of the sensor per
    # axial acceleration (exciter's transverse motion, mounting alignment), standard
    # uncertainty, percent, at frequencies (Hz); dsp.triaxial's `table_transverse`
    transverse_motion: MotionTable = MotionTable()

    def transverse_budget(self) -> Budget:
        """The stated transverse motion as magnitude components (fractions)."""
        return Budget(
            tuple(_segments(f"table transverse motion {self.name}", self.transverse_motion, 0.01))
        )

    @property
    def channels(self) -> tuple[str, ...]:
        """Its input channels' names: dut.<name>, or dut.<name>.x/.y/.z."""
        if self.axes:
            return tuple(f"dut.{self.name}.{axis}" for axis in AXES)
        return (f"dut.{self.name}",)

    @property
    def channel(self) -> str:
        """The channel a single-axis DUT at this position is read on."""
        return self.channels[0]

    def inputs(self, dut: InputChannel) -> tuple[InputChannel, ...]:
        """Its inputs with [daq.dut]'s settings (`dut`) and this position's physical channels."""
        if self.axes:
            return tuple(
                dataclasses.replace(dut, name=f"dut.{self.name}.{axis}", physical=self.axes[axis])
                for axis in AXES
            )
        assert self.physical is not None
        return (dataclasses.replace(dut, name=self.channel, physical=self.physical),)

    def budget(self, crosstalk_db: float | None, crosstalk_ratio: float = 1.0) -> Budget:
        """This position's type B components: the stated relative motion (magnitude and phase;
        a power law per segment of the table, flat outside it) and the crosstalk term
        u = 10^(dB/20) x `crosstalk_ratio` (the largest other channel's voltage over this
        one's), magnitude (fraction) and phase (degrees)."""
        parts = list(_segments(f"{MOTION_NAME} {self.name}", self.relative_motion, 0.01))
        parts += _segments(
            f"{MOTION_NAME} {self.name} (phase)",
            self.relative_motion_phase_deg,
            1.0,
            Quantity.PHASE,
        )
        if crosstalk_db is not None:
            u = 10 ** (crosstalk_db / 20) * crosstalk_ratio
            note = f"{crosstalk_db:g} dB x {crosstalk_ratio:.3g} (other channel / this one)"
            parts.append(
                Component(f"{CROSSTALK_NAME} {self.name}", u, Distribution.STANDARD, note=note)
            )
            parts.append(
                Component(
                    f"{CROSSTALK_NAME} {self.name} (phase)",
                    math.degrees(u),
                    Distribution.STANDARD,
                    quantity=Quantity.PHASE,
                    note=note,
                )
            )
        return Budget(tuple(parts))

    def owns(self, component_name: str) -> bool:
        """Whether a budget component of that name is one of this position's (`budget`)."""
        crosstalk = f"{CROSSTALK_NAME} {self.name}"
        return component_name.startswith(f"{MOTION_NAME} {self.name} ") or component_name in (
            crosstalk,
            f"{crosstalk} (phase)",
        )

    def over_limit_hz(self, frequencies_hz: Sequence[float]) -> list[float]:
        """The lines (Hz) at which this position's stated relative motion alone (k = 2) makes U
        exceed the ISO 16063-21 limit of the band."""
        out = []
        for f in frequencies_hz:
            limit = iso_16063_21_limit(f)
            if limit is not None and 2 * self.relative_motion.at(f) / 100 > limit:
                out.append(float(f))
        return out

    def limit_check(self, frequencies_hz: Sequence[float]) -> tuple[str | None, tuple[str, ...]]:
        """(why the plan is refused at this position, or None; the warnings of the lines it
        affects): refused when the stated relative motion alone makes U exceed the ISO 16063-21
        limit at every line of the plan, else a warning naming the lines where it does."""
        over = self.over_limit_hz(frequencies_hz)
        if over and len(over) == len(frequencies_hz):
            return (
                f"fixture.position {self.name!r} relative_motion: its stated relative "
                "motion alone exceeds the ISO 16063-21 limit at every line of the plan"
            ), ()
        if not over:
            return None, ()
        lines = ", ".join(f"{f:g}" for f in over)
        return None, (
            f"fixture position {self.name}: its stated relative motion alone exceeds "
            f"the ISO 16063-21 limit at {lines} Hz",
        )


@dataclass(frozen=True)
class Fixture:
    """The stand's fixture: name, own mass (kg), mass limit of all DUTs together (kg), stated
    channel-to-channel crosstalk (dB; None: not stated) and its positions in order."""

    name: str
    mass_kg: float
    mass_limit_kg: float
    positions: tuple[FixturePosition, ...]
    crosstalk_db: float | None = None

    def position(self, name: str) -> FixturePosition:
        """The position `name` (KeyError naming the fixture's positions)."""
        for p in self.positions:
            if p.name == name:
                return p
        raise KeyError(
            f"position {name!r} is not on the fixture ({', '.join(p.name for p in self.positions)})"
        )

    def inputs(
        self, dut: InputChannel, names: Sequence[str] | None = None
    ) -> tuple[InputChannel, ...]:
        """The DUT inputs of the positions `names` (None: all), in the fixture's order."""
        wanted = None if names is None else set(names)
        return tuple(
            channel
            for p in self.positions
            if wanted is None or p.name in wanted
            for channel in p.inputs(dut)
        )

    def mass_problems(self, masses_kg: Mapping[str, float]) -> list[str]:
        """What the DUTs' masses (kg, by position) break: the fixture's total limit, a
        position's own limit; empty when within."""
        problems = []
        total = sum(masses_kg.values())
        if total > self.mass_limit_kg:
            problems.append(
                f"fixture.mass_limit_kg: the DUTs weigh {total:.3g} kg together, above "
                f"{self.mass_limit_kg:g} kg"
            )
        for name, mass in masses_kg.items():
            limit = self.position(name).mass_limit_kg
            if limit is not None and mass > limit:
                problems.append(
                    f"fixture.position {name!r} mass_limit_kg: its DUT weighs {mass:.3g} kg, "
                    f"above {limit:g} kg"
                )
        return problems


def _segments(
    name: str, table: MotionTable, scale: float, quantity: Quantity = Quantity.MAGNITUDE
) -> list[Component]:
    """A table (values x `scale`: percent to fraction, or degrees) as standard-uncertainty
    components: flat below its first and above its last frequency, a power law between each
    pair of points (ranges end just below the next point so none counts twice)."""
    pts = [(f, v * scale) for f, v in table.points]
    if not pts:
        return []
    below = math.nextafter(pts[0][0], 0.0)
    out = [
        Component(
            f"{name} <{pts[0][0]:g} Hz",
            pts[0][1],
            Distribution.STANDARD,
            quantity=quantity,
            max_frequency_hz=below,
        )
    ]
    for (f1, v1), (f2, v2) in itertools.pairwise(pts):
        hi = math.nextafter(f2, 0.0)
        where = f"{name} {f1:g}-{f2:g} Hz"
        if v1 <= 0 or v2 <= 0 or v1 == v2:
            out.append(
                Component(
                    where,
                    max(v1, v2),
                    Distribution.STANDARD,
                    quantity=quantity,
                    min_frequency_hz=f1,
                    max_frequency_hz=hi,
                )
            )
        elif v2 > v1:
            n = math.log(v2 / v1) / math.log(f2 / f1)
            out.append(
                Component(
                    where,
                    v1,
                    Distribution.STANDARD,
                    quantity=quantity,
                    min_frequency_hz=f1,
                    max_frequency_hz=hi,
                    law=Law.POWER,
                    law_frequency_hz=f1,
                    law_exponent=min(n, 4.0),
                )
            )
        else:
            n = math.log(v1 / v2) / math.log(f2 / f1)
            out.append(
                Component(
                    where,
                    v2,
                    Distribution.STANDARD,
                    quantity=quantity,
                    min_frequency_hz=f1,
                    max_frequency_hz=hi,
                    law=Law.POWER_BELOW,
                    law_frequency_hz=f2,
                    law_exponent=min(n, 4.0),
                )
            )
    out.append(
        Component(
            f"{name} >={pts[-1][0]:g} Hz",
            pts[-1][1],
            Distribution.STANDARD,
            quantity=quantity,
            min_frequency_hz=pts[-1][0],
        )
    )
    return out


def _number(
    value: Any, where: str, *, positive: bool = False, minimum: float | None = None
) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise FixtureError(f"{where}: must be a finite number, got {value!r}")
    if positive and not value > 0:
        raise FixtureError(f"{where}: must be > 0, got {value!r}")
    if minimum is not None and value < minimum:
        raise FixtureError(f"{where}: must be >= {minimum:g}, got {value!r}")
    return float(value)


def _table(value: Any, where: str) -> MotionTable:
    """[[f_hz, value], ...] with rising frequencies > 0 and values >= 0."""
    if not isinstance(value, list) or not value:
        raise FixtureError(f"{where}: must be a non-empty list of [frequency_hz, value] pairs")
    points: list[tuple[float, float]] = []
    for i, pair in enumerate(value):
        if not isinstance(pair, list) or len(pair) != 2:
            raise FixtureError(f"{where}[{i}]: must be a pair [frequency_hz, value]")
        f = _number(pair[0], f"{where}[{i}] frequency", positive=True)
        v = _number(pair[1], f"{where}[{i}] value", minimum=0.0)
        if points and f <= points[-1][0]:
            raise FixtureError(
                f"{where}[{i}]: frequencies must rise, {f:g} Hz after {points[-1][0]:g}"
            )
        points.append((f, v))
    return MotionTable(tuple(points))


def _unknown(table: Mapping[str, Any], known: frozenset[str], where: str) -> None:
    for key in table:
        if key not in known:
            raise FixtureError(f"{where}.{key}: unknown key (known: {', '.join(sorted(known))})")


def _position(entry: Any, index: int) -> FixturePosition:
    where = f"fixture.position[{index}]"
    if not isinstance(entry, dict):
        raise FixtureError(f"{where}: must be a table ([[fixture.position]])")
    _unknown(entry, POSITION_KEYS, where)
    name = entry.get("name")
    if not isinstance(name, str) or not POSITION_NAME.fullmatch(name):
        raise FixtureError(f"{where}.name: must be 1-16 of A-Z a-z 0-9 _ -, got {name!r}")
    where = f"fixture.position {name!r}"
    physical, axes = entry.get("physical"), entry.get("axes")
    if (physical is None) == (axes is None):
        raise FixtureError(f"{where}: give either physical (one input) or axes (x, y, z)")
    if physical is not None and (not isinstance(physical, str) or not physical.strip()):
        raise FixtureError(f"{where}.physical: must be a DAQ input name, got {physical!r}")
    if axes is not None:
        if (
            not isinstance(axes, dict)
            or set(axes) != set(AXES)
            or not all(isinstance(v, str) and v.strip() for v in axes.values())
        ):
            raise FixtureError(f"{where}.axes: must be {{ x = ..., y = ..., z = ... }} DAQ inputs")
        axes = {axis: axes[axis] for axis in AXES}
        if "skew_s" in entry:  # three inputs, three delays: the DAQ reports each channel's
            raise FixtureError(
                f"{where}.skew_s: a triaxial position (axes) has three inputs, so no one delay; "
                "leave it out (each channel's delay is the DAQ driver's, else [daq] skew_s)"
            )
    limit = entry.get("mass_limit_kg")
    return FixturePosition(
        name=name,
        physical=physical,
        axes=axes,
        distance_mm=_number(entry.get("distance_mm", 0.0), f"{where}.distance_mm", minimum=0.0),
        azimuth_deg=_number(entry.get("azimuth_deg", 0.0), f"{where}.azimuth_deg"),
        mass_limit_kg=None
        if limit is None
        else _number(limit, f"{where}.mass_limit_kg", positive=True),
        relative_motion=(
            _table(entry["relative_motion"], f"{where}.relative_motion")
            if "relative_motion" in entry
            else MotionTable()
        ),
        relative_motion_phase_deg=(
            _table(entry["relative_motion_phase_deg"], f"{where}.relative_motion_phase_deg")
            if "relative_motion_phase_deg" in entry
            else MotionTable()
        ),
        skew_s=_skew(entry.get("skew_s"), f"{where}.skew_s"),
        transverse_motion=(
            _table(entry["transverse_motion"], f"{where}.transverse_motion")
            if "transverse_motion" in entry
            else MotionTable()
        ),
    )


def _skew(value: Any, where: str) -> float | None:
    """A position's stated sampling delay (s), 0 to 1 ms as [daq] skew_s; None: not stated."""
    if value is None:
        return None
    skew = _number(value, where, minimum=0.0)
    if skew >= 1e-3:
        raise FixtureError(f"{where}: must be between 0 and 1 ms, got {skew:g} s")
    return skew


def parse_fixture(
    data: Mapping[str, Any], dut: InputChannel | None, used: Mapping[str, str]
) -> Fixture | None:
    """The stand file's [fixture] (`data`: the whole file; `dut`: its [daq.dut] input, whose
    settings the positions take; `used`: physical channel -> the input already on it) or
    None without one. FixtureError '<key>: <why>' on anything that cannot be used."""
    table = data.get("fixture")
    if table is None:
        return None
    if not isinstance(table, dict):
        raise FixtureError("fixture: must be a table")
    _unknown(table, SCHEMA["fixture"], "fixture")
    if dut is None:
        raise FixtureError("fixture: needs [daq.dut] (its inputs take its settings)")
    name = table.get("name")
    if not isinstance(name, str) or not name.strip():
        raise FixtureError(f"fixture.name: must be a non-empty string, got {name!r}")
    entries = table.get("position")
    if not isinstance(entries, list) or not entries:
        raise FixtureError("fixture.position: needs at least one [[fixture.position]]")
    positions = tuple(_position(e, i) for i, e in enumerate(entries))
    seen_names: set[str] = set()
    seen_physical = {k.strip().lower(): v for k, v in used.items() if v != "dut"}
    for p in positions:
        if p.name in seen_names:
            raise FixtureError(f"fixture.position {p.name!r}: named twice")
        seen_names.add(p.name)
        for channel in p.inputs(dut):
            key = channel.physical.strip().lower()
            if key in seen_physical:
                raise FixtureError(
                    f"fixture.position {p.name!r}: {channel.physical!r} is also the "
                    f"{seen_physical[key]} input; each input needs its own physical channel"
                )
            seen_physical[key] = channel.name
    crosstalk = table.get("crosstalk_db")
    if crosstalk is not None:
        crosstalk = _number(crosstalk, "fixture.crosstalk_db")
        if crosstalk >= 0:
            raise FixtureError(f"fixture.crosstalk_db: must be < 0 dB, got {crosstalk:g}")
    return Fixture(
        name=name,
        mass_kg=_number(table.get("mass_kg", 0.0), "fixture.mass_kg", minimum=0.0),
        mass_limit_kg=_number(table.get("mass_limit_kg"), "fixture.mass_limit_kg", positive=True)
        if "mass_limit_kg" in table
        else math.inf,
        positions=positions,
        crosstalk_db=crosstalk,
    )
