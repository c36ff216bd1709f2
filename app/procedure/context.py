"""What the phases of one run share: the stand, plan, settings, the stand's I/O, the notes
kept for the run record, and how to tell the listener and run.log."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.procedure.errors import ProcedureError
from app.procedure.events import (
    Event,
    MemberEstimate,
    PeriodEstimate,
    State,
    StateChanged,
    WarningRaised,
)
from app.procedure.ranging import RangePlan
from app.procedure.settings import RunSettings
from app.procedure.stand_io import StandIO
from app.stand.open import Stand
from dsp.calibration import Results, compute_results
from dsp.multisine import Plan
from dsp.spectral import Estimate
from dsp.uncertainty import Budget

log = logging.getLogger(__name__)


@dataclass
class RunNotes:
    """What a run found on its way, for its record: warnings, the worst equalisation error
    per iteration, the background per line (V) and the latest results."""

    warnings: list[str] = field(default_factory=list)
    equalisation: list[float] = field(default_factory=list)
    background: dict[str, list[float]] = field(default_factory=dict)
    results: Results | None = None
    budget: Budget | None = None  # the budget the results used (the stand's until acquisition)
    stand_response: dict[str, Any] | None = None  # where equalisation started (run record)
    measured_response: np.ndarray | None = None  # converged response, (m/s^2)/V per line
    measured_response_error: float | None = None  # its equalisation error (fraction)
    ranges: RangePlan | None = None  # the input ranges per line, from the preflight
    fade_in_s: float | None = None  # the LPM's fade-in (s) the preflight picked and checked


@dataclass
class RunContext:
    """One run's shared state; each phase reads what it needs and returns what it found."""

    stand: Stand
    plan: Plan
    settings: RunSettings
    io: StandIO
    notes: RunNotes
    emit: Callable[[Event], None]
    log: Callable[[str], None]

    def state(self, state: State, message: str = "") -> None:
        """A new state: run.log and the listener."""
        self.log(f"state: {state}{' - ' + message if message else ''}")
        self.emit(StateChanged(state, message))

    def warn(self, text: str) -> None:
        """A warning: kept for the results, run.log and the listener."""
        self.notes.warnings.append(text)
        self.log(f"warning: {text}")
        self.emit(WarningRaised(text))

    def publish(
        self, estimate: Estimate, budget: Budget, members: tuple[MemberEstimate, ...] = ()
    ) -> Results:
        """Results of an estimate over the whole plan: checked, kept and sent to listeners
        (with `members`: the other DUTs' of a run of several, after the same period)."""
        s = self.settings
        results = compute_results(
            estimate,
            self.plan,
            self.stand.chain,
            budget,
            probability=s.probability,
            rule=s.rule,
            tolerance_percent=s.tolerance_percent,
            extra_warnings=tuple(self.notes.warnings),
            cmc=self.stand.config.cmc,
            resonance=s.resonance,
        )
        self.check_plausible(results)
        self.notes.results = results
        self.emit(PeriodEstimate(estimate.periods, estimate, results, members=members))
        return results

    def check_plausible(self, results: Results) -> None:
        """ProcedureError when the DUT's sensitivity is far from its nominal value."""
        nominal = self.settings.dut_nominal_mv_per_ms2
        if nominal is None:
            return
        measured = results.reference.sensitivity_mv_per_ms2
        ratio = measured / nominal
        if not 1 / self.settings.plausible_ratio <= ratio <= self.settings.plausible_ratio:
            raise ProcedureError(
                f"implausible DUT sensitivity {measured:.4g} mV/(m/s^2) against its nominal "
                f"{nominal:g}: channels swapped, wrong DUT channel gain, or wrong DUT"
            )
