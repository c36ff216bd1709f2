"""What the calibration procedure needs from a stand: small Protocols, one per capability.

Real drivers (hardware/nidaq.py, hardware/visa_amplifiers.py) and the simulated stand (sim/)
implement these; the procedure imports nothing else from either.

Units: volts, hertz, seconds, mV/(m/s^2) for transducer sensitivities.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal, Protocol, runtime_checkable

import numpy as np

from hardware.errors import InputRefused

# "reference", "drive", and a DUT input: "dut" (a single-DUT run) or "dut.<position>" and
# "dut.<position>.<axis>" (several DUTs in one run, issue 36)
ChannelName = str


@dataclass(frozen=True)
class InputChannel:
    """An analog input: logical name, physical channel, +-range in V, coupling, IEPE current."""

    name: ChannelName
    physical: str
    range_v: float
    coupling: Literal["dc", "ac"] = "dc"
    iepe_current_a: float = 0.0
    terminal: Literal["default", "differential", "pseudodifferential", "rse", "nrse"] = "default"

    def __post_init__(self) -> None:
        if not self.range_v > 0:
            raise InputRefused(f"input channel {self.name}: range_v must be > 0 V")
        if self.iepe_current_a < 0 or self.iepe_current_a > 0.02:
            raise InputRefused(f"input channel {self.name}: iepe_current_a must be 0..0.02 A")


@dataclass(frozen=True)
class OutputChannel:
    """The analog output driving the power amplifier: physical channel and +-range in V."""

    physical: str
    range_v: float

    def __post_init__(self) -> None:
        if not self.range_v > 0:
            raise InputRefused("output channel: range_v must be > 0 V")


DUT_CHANNEL = re.compile(r"^dut(\.[A-Za-z0-9_-]{1,16}){0,2}$")


def is_dut_channel(name: str) -> bool:
    """A DUT input's name: 'dut', 'dut.<position>' or 'dut.<position>.<axis>'."""
    return DUT_CHANNEL.fullmatch(name) is not None


@dataclass(frozen=True)
class DaqConfig:
    """Sample rate (Hz), period length (samples), the output and the input channels."""

    sample_rate_hz: float
    period_samples: int
    output: OutputChannel
    inputs: tuple[InputChannel, ...]

    def __post_init__(self) -> None:
        names = [c.name for c in self.inputs]
        if "reference" not in names or not any(is_dut_channel(n) for n in names):
            raise InputRefused(
                "DAQ configuration: needs a 'reference' and at least one DUT input channel"
                " ('dut', or 'dut.<position>')"
            )
        if len(set(names)) != len(names):
            raise InputRefused("DAQ configuration: input channel names must be unique")
        if not self.sample_rate_hz > 0 or self.period_samples < 4:
            raise InputRefused("DAQ configuration: sample rate > 0 Hz and period >= 4 samples")


@dataclass(frozen=True)
class DaqStatus:
    """What a configured DAQ reports back: actual sample rate (Hz) and the DUT channel's sampling
    delay after the reference channel (s; non-zero on multiplexed boards): the first DUT
    channel's in `skew_s`, every input's in `skews_s` (by channel name; empty: a single-DUT
    driver may leave it so, `skew_s` then holds)."""

    actual_sample_rate_hz: float
    skew_s: float
    skews_s: Mapping[str, float] = field(default_factory=dict)


def checked_output_period(period_v: np.ndarray, config: DaqConfig, device: str) -> np.ndarray:
    """One output period as contiguous float64 volts, or ValueError naming what is wrong: its
    length, NaN or inf, or a peak beyond the output range."""
    x = np.asarray(period_v, dtype=float)
    if x.shape != (config.period_samples,):
        raise ValueError(
            f"{device}: output period must have {config.period_samples} samples, got {x.shape}"
        )
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{device}: output period contains NaN or inf")
    peak = float(np.max(np.abs(x)))
    if peak > config.output.range_v:
        raise ValueError(
            f"{device}: output peak {peak:.3g} V exceeds the AO range +-{config.output.range_v:g} V"
        )
    return np.array(x, dtype=float, order="C")  # a copy: the caller's array may change


def input_ranges(values: object, where: str) -> tuple[float, ...]:
    """+-ranges (V) as a sorted tuple of distinct positive numbers; InputRefused naming `where`
    otherwise."""
    if not isinstance(values, list | tuple) or not values:
        raise InputRefused(f"{where}: must be a non-empty list of +-ranges in V")
    out = set()
    for v in values:
        if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < 1e4:
            raise InputRefused(f"{where}: every range must be a number of volts > 0, got {v!r}")
        out.add(float(v))
    return tuple(sorted(out))


def choose_range(peak_v: float, offered_v: tuple[float, ...], headroom: float) -> float | None:
    """The smallest offered +-range (V) that holds `peak_v` (V) times `headroom` (>= 1); None
    when even the largest does not."""
    if not (math.isfinite(peak_v) and peak_v >= 0) or not headroom >= 1:
        raise InputRefused(f"input range: peak {peak_v!r} V or headroom {headroom!r} not usable")
    for range_v in sorted(offered_v):
        if peak_v * headroom <= range_v:
            return range_v
    return None


@runtime_checkable
class OffersInputRanges(Protocol):
    """A DAQ that says which +-input ranges (V) its analog inputs offer (every range is
    offered on every input channel; DAQmx lists them per device)."""

    def input_ranges_v(self) -> tuple[float, ...]: ...


@runtime_checkable
class Daq(Protocol):
    """One AO channel and its AI channels on one sample clock and start trigger.

    The output is one period, regenerated; `write_period` queues a new period (fades,
    equalisation): periods play in the order written, each from a period boundary and at least
    once, and the last one repeats until another is written. `read_period` returns the next
    whole period of every input channel in volts, in the order of `DaqConfig.inputs`, shape
    (channels, N).
    `stop` brings the output to 0 V and stops; it is safe to call at any time, twice, or after
    an error. `output_v` is the output voltage now, as the device knows it (None if unknown).
    """

    def configure(self, config: DaqConfig) -> DaqStatus: ...

    def start(self, period_v: np.ndarray) -> None: ...

    def write_period(self, period_v: np.ndarray) -> None: ...

    def read_period(self, timeout_s: float) -> np.ndarray: ...

    def stop(self) -> None: ...

    def close(self) -> None: ...

    @property
    def output_v(self) -> float | None: ...


@dataclass(frozen=True)
class ConditioningSettings:
    """A measuring amplifier channel's settings as read back (for the run record).

    `sensitivity_mv_per_ms2` is the transducer sensitivity set on the amplifier, `gain` the
    overall V/V from transducer output to amplifier output, `output_mv_per_ms2` the resulting
    output scaling, filters in Hz (None = off).
    """

    channel: int
    measurement_mode: str
    sensitivity_mv_per_ms2: float
    gain: float
    output_mv_per_ms2: float
    high_pass_hz: float | None
    low_pass_hz: float | None
    identity: str = ""


@runtime_checkable
class MeasuringAmplifier(Protocol):
    """A conditioning amplifier (e.g. B&K 2525) between an accelerometer and the DAQ."""

    def identify(self) -> str: ...

    def configure(
        self,
        channel: int,
        *,
        sensitivity_mv_per_ms2: float,
        gain: float,
        high_pass_hz: float | None = None,
        low_pass_hz: float | None = None,
    ) -> ConditioningSettings: ...

    def read_settings(self, channel: int) -> ConditioningSettings: ...

    def overloaded(self, channel: int) -> bool: ...

    def close(self) -> None: ...


@runtime_checkable
class PowerAmplifier(Protocol):
    """An optional remotely controlled power amplifier driving the exciter."""

    def identify(self) -> str: ...

    def set_output_enabled(self, enabled: bool) -> None: ...

    def set_gain(self, gain: float) -> None: ...

    def gain(self) -> float: ...

    def fault(self) -> str | None: ...

    def interlock_closed(self) -> bool: ...

    def close(self) -> None: ...
