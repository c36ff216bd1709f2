"""The typed events a run sends to its listener (the CLI's progress line, the GUI)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING

import numpy as np

from app.io.vocabulary import RunStatus
from dsp.calibration import Results
from dsp.spectral import Estimate

if TYPE_CHECKING:
    from app.records.run_record import RunRecord


class State(StrEnum):
    PREFLIGHT = "preflight"
    BACKGROUND = "background"
    IDENTIFYING = "identifying"
    EQUALISING = "equalising"
    ACQUIRING = "acquiring"
    FADING_OUT = "fading out"
    FINISHED = "finished"
    ABORTED = "aborted"


@dataclass(frozen=True)
class StateChanged:
    state: State
    message: str = ""


@dataclass(frozen=True)
class Progress:
    """Overall progress 0..1, the excitation time so far and an estimate of what remains (s)."""

    fraction: float
    elapsed_s: float
    remaining_s: float | None
    message: str = ""
    # the fraction is how close the type A is to its target (not a share of the periods);
    # remaining_s then estimates the pace so far, capped by the time bound
    until_target: bool = False


@dataclass(frozen=True)
class PeriodBlock:
    """One period as read (volts, channels in DaqConfig order), what was played, and the
    input range (+-V) each channel was read on (the run picks them: issue 32 point 2)."""

    index: int
    state: State
    channels: tuple[str, ...]
    samples: np.ndarray
    drive: np.ndarray
    ranges_v: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class EqualisationStep:
    """Per-line relative amplitude error of the table acceleration after an iteration."""

    iteration: int
    errors: np.ndarray
    worst: float


@dataclass(frozen=True)
class MemberEstimate:
    """The live results of another DUT of a run of several (issue 36) after the same period
    as the run's own: its position, its input channel ("dut.<position>") and its results
    (app.procedure.batch_live; the stand's budget with its position's terms)."""

    position: str
    channel: str
    results: Results


@dataclass(frozen=True)
class PeriodEstimate:
    """The live estimate after another acquired period."""

    periods: int
    estimate: Estimate
    results: Results
    member: str = ""  # several DUTs in one run (issue 36): the DUT's position; "": the one DUT
    # the run's own estimate in a run of several DUTs: the other DUTs' after the same period
    # (in the fixture's order; a DUT whose estimate could not be made is left out); () alone
    members: tuple[MemberEstimate, ...] = ()


@dataclass(frozen=True)
class WarningRaised:
    text: str


@dataclass(frozen=True)
class InputRanges:
    """The input ranges the run uses and each channel's fewest LSB per line (after the
    preflight), or a stepped-sine line re-ranged from its measured amplitude."""

    text: str


@dataclass(frozen=True)
class Finished:
    """How the run ended; `record` is what results.json holds (app.records.run_record.RunRecord)."""

    status: RunStatus
    abort_reason: str | None
    results: Results | None
    record: RunRecord


Event = (
    StateChanged
    | Progress
    | PeriodBlock
    | EqualisationStep
    | PeriodEstimate
    | WarningRaised
    | InputRanges
    | Finished
)
Listener = Callable[[Event], None]
