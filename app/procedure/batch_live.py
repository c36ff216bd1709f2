"""The other DUTs' live estimates in a run of several DUTs (issue 36 point 4: the Run tab shows
each DUT's live deviation).

The run's own DUT (the first member) is estimated live as a single run's is
(app.procedure.acquisition). Each other member is estimated here from the same periods: its own
accumulator (with the LPM its own record) on the pair (reference, dut.<position>), the run's
estimator, the run's reference
chain with its own channel delay, and the stand's budget with its own position's terms (not yet
its own background and resolution terms: its stored results, made at the end from its own
recording, have them). Its results go out in the run's own `PeriodEstimate` (`members`), so a
listener that reads only the run's own estimate sees nothing new, and a single-DUT run's events
are unchanged. Only a face that draws them asks for them (`Procedure.batch_live`: the GUI's Run
tab); the CLI's batch runs as before (bench/batch_live.py: the LPM's members cost the run's
thread about 70 ms of CPU per member and 2 s period). A member whose estimate cannot be made
(a dead channel, say) is left out and logged once: a live view never ends the run; its stored
analysis says why.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from app.procedure.events import MemberEstimate
from dsp.calibration import AnalysisError, ReferenceChain, compute_results
from dsp.lpm_live import LiveRecord
from dsp.lpm_record import hum_bins
from dsp.spectral import Estimate, SpectralAccumulator
from dsp.uncertainty import Budget

if TYPE_CHECKING:
    from app.procedure.context import RunContext
    from app.procedure.procedure import Procedure

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LiveMember:
    """Another DUT of the run as its live estimate needs it: its position, its input channel,
    its reference chain (its own channel delay) and budget (its position's terms), and whether
    its signal is a triaxial sensor's cross axis (exempt from the dead-channel refusal)."""

    position: str
    channel: str
    chain: ReferenceChain
    budget: Budget
    transverse: bool = False


def live_members(procedure: Procedure, *, record: bool = False) -> LiveMembers | None:
    """The other DUTs of `procedure`'s run as its acquisition estimates them live (`record`:
    the LPM's one record, app.procedure.record_run; else the accumulated periods). None: a
    single-DUT run, or a run of several whose face does not draw them (`Procedure.batch_live`
    off: the CLI's; their estimates would cost the run's thread CPU for nobody)."""
    run: Any = procedure.batch
    others = getattr(run, "others", None)
    if not others or not procedure.batch_live:
        return None
    from app.procedure.batch import member_budget

    stand = procedure.stand
    members = [
        LiveMember(
            m.position.name,
            m.channel,
            run.member_chain(procedure, m),
            member_budget(stand.budget, run.lead.position, m.terms),
            m.transverse,
        )
        for m in others
    ]
    return LiveMembers(procedure.ctx, members, record=record)


class LiveMembers:
    """Each other member's estimate over the periods the run's own estimate takes (`add`), and
    its results when the run's own are made (`estimates`). With `record` (the LPM), each
    member's periods make one record (dsp.lpm_live.LiveRecord), estimated on the run's own
    record's schedule (`follow`); else a spectral accumulator per member. Close it."""

    def __init__(self, ctx: RunContext, members: Sequence[LiveMember], *, record: bool) -> None:
        self.ctx = ctx
        plan = ctx.plan
        self.members = list(members)
        self.record = record
        self._records: dict[str, LiveRecord] = {}
        self._accumulators: dict[str, SpectralAccumulator] = {}
        for m in self.members:
            if record:
                self._records[m.channel] = LiveRecord(plan, target=ctx.settings.target_type_a)
            else:
                self._accumulators[m.channel] = SpectralAccumulator(
                    plan.period_samples, plan.bins, nonlinear_excluded_bins=hum_bins(plan)
                )
        self._failed: set[str] = set()  # channels whose estimate failed (logged once)

    def __enter__(self) -> LiveMembers:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Free the records' spools."""
        for live in self._records.values():
            live.close()

    def add(
        self,
        block: np.ndarray,
        played: np.ndarray | None = None,
        recorded_drive: np.ndarray | None = None,
    ) -> None:
        """One period as read (every channel, in the DAQ's order; V); with `record` the drive
        as played and as recorded (as the run's own record takes them)."""
        index = self.ctx.io.channel_index
        reference = block[index["reference"]]
        for member in self.members:
            dut = block[index[member.channel]]
            if self.record:
                drive = played if played is not None else np.zeros_like(reference)
                self._records[member.channel].add(reference, dut, drive, recorded_drive)
            else:
                self._accumulators[member.channel].add_period(reference, dut)

    def follow(self, worst_type_a: float, last: int | None) -> None:
        """With `record`: the run's own record measured `worst_type_a` and ends at period
        `last`; each member's record takes the same checkpoints (estimated when the run's is,
        from the record fed meanwhile: LiveRecord)."""
        for live in self._records.values():
            live.last = last
            live.measured(worst_type_a)

    def _estimate(self, channel: str) -> Estimate:
        if self.record:
            return self._records[channel].estimate().estimate
        return self._accumulators[channel].estimate(self.ctx.settings.estimator)

    def estimates(self) -> tuple[MemberEstimate, ...]:
        """Each member's results over the periods added so far, with the run's estimator and
        rules (a member whose results cannot be made is left out)."""
        s, plan = self.ctx.settings, self.ctx.plan
        out = []
        for member in self.members:
            try:
                results = compute_results(
                    self._estimate(member.channel),
                    plan,
                    member.chain,
                    member.budget,
                    probability=s.probability,
                    rule=s.rule,
                    tolerance_percent=s.tolerance_percent,
                    cmc=self.ctx.stand.config.cmc,
                    transverse=member.transverse,
                )
            except (AnalysisError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
                if member.channel not in self._failed:
                    self._failed.add(member.channel)
                    log.warning("live estimate of %s not made: %s", member.channel, exc)
                continue
            out.append(MemberEstimate(member.position, member.channel, results))
        return tuple(out)
