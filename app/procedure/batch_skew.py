"""Each DUT channel's own sampling delay in a run of several DUTs (issue 36).

On a multiplexed DAQ the converter samples the inputs one after another, so every DUT channel
has its own delay after the reference (4 us per channel on the simulated M-series-like board:
the fourth DUT 16 us after the reference, 57.6 degrees at 10 kHz). A member's phase is
corrected with its own channel's delay: the one the driver reports (`DaqStatus.skews_s`),
checked against the stand file's statement for its position (`[[fixture.position]] skew_s`)
within `[daq] skew_tolerance_s`; else the stated one (the position's, else `[daq] skew_s`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum

from app.procedure.errors import PreflightError
from app.stand.config import StandConfig
from app.stand.fixture import FixturePosition

log = logging.getLogger(__name__)


class SkewSource(StrEnum):
    """Where a member's delay comes from (for run.log)."""

    DRIVER = "reported by the DAQ driver"
    POSITION = "the stand file's fixture.position skew_s"
    STAND = "the stand file's daq.skew_s"


@dataclass(frozen=True)
class ChannelSkew:
    """One DUT channel's sampling delay after the reference (s) and where it comes from."""

    channel: str
    skew_s: float
    source: str

    def line(self) -> str:
        """run.log's line: 'skew dut.B: 8 us (reported by the DAQ driver)'."""
        return f"skew {self.channel}: {self.skew_s * 1e6:.6g} us ({self.source})"


def skew_tolerance_s(config: StandConfig) -> float:
    """The stand file's `[daq] skew_tolerance_s` (s, half-width); 0 when it states none (the
    driver's figure and a position's statement must then agree to the nanosecond's tenth)."""
    value = config.raw.get("daq", {}).get("skew_tolerance_s")
    return float(value) if value is not None else 0.0


def member_skews(
    positions: Sequence[FixturePosition],
    reported: Mapping[str, float],
    stated_s: float,
    tolerance_s: float,
) -> dict[str, ChannelSkew]:
    """Each position's channel's delay (by channel name): the driver's `reported` delay (s,
    `DaqStatus.skews_s`) when it gives that channel's, else the position's stated `skew_s`,
    else `stated_s` ([daq] skew_s). PreflightError naming the position when its stated delay
    and the reported one differ by more than `tolerance_s` (s)."""
    out: dict[str, ChannelSkew] = {}
    for position in positions:
        channel = position.channel
        stated = position.skew_s
        if channel in reported:
            skew = float(reported[channel])
            if stated is not None and not _agree(skew, stated, tolerance_s):
                raise PreflightError(
                    f"fixture.position {position.name!r} skew_s: the stand file states "
                    f"{stated * 1e6:.6g} us, the DAQ samples {channel} {skew * 1e6:.6g} us "
                    f"after the reference (beyond daq.skew_tolerance_s "
                    f"{tolerance_s * 1e6:.6g} us): correct the stand file or the channel order"
                )
            out[channel] = ChannelSkew(channel, skew, SkewSource.DRIVER)
        elif stated is not None:
            out[channel] = ChannelSkew(channel, stated, SkewSource.POSITION)
        else:
            out[channel] = ChannelSkew(channel, stated_s, SkewSource.STAND)
    return out


def _agree(reported_s: float, stated_s: float, tolerance_s: float) -> bool:
    """Whether two delays (s) agree within `tolerance_s` (plus 0.1 ns for float noise)."""
    return math.isfinite(reported_s) and abs(reported_s - stated_s) <= tolerance_s + 1e-10
