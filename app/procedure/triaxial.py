"""A triaxial DUT's run in one orientation (issue 36 point 3): `accelcal run --stand FILE --dut
T=SERIAL --orientation x|y|z` on a stand file position with `axes`.

The exciter moves along the sensor's axis o. One excitation, the three channels dut.T.x/.y/.z
recorded beside the reference, each estimated as a batch member is (app.procedure.batch): the
channel along o is the run's own (the live estimate, the equalisation and the level at the
reference as always), the other two are members whose signal is the transverse one (exempt
from the dead-channel refusal, dsp.calibration.compute_results `transverse`). Each channel is
a complete run folder and the orientation a batch folder (batch.json names the three), so the
three orientations' batches make one certificate (app.certificate.triaxial_issue). The three
channels share the position's terms (its crosstalk ratio the main axis's). The runs name no
catalogue model (the simulated sensor is sim/triaxial.py's): the certificate takes
--dut-model.

A cross channel carries no verdict (its sensitivity is a transverse one: the certificate's
ratio), and its run's config.json batch link says so (`orientation`, `transverse`), so that
`accelcal analyze` of that run analyses it as the run did. Each channel's input range is the
smallest that holds its own predicted peak: the main axis's from the nominal, a cross
channel's from TRANSVERSE_BOUND of it (TriaxialRun.member_ranges).
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from app.io.vocabulary import Backend
from app.procedure.batch import (
    BatchFinished,
    BatchRun,
    Member,
    MemberChoice,
    OpenedBatch,
    _member_spec,
    listener_for,
    new_batch_folder,
    refuse_mode,
)
from app.procedure.errors import PreflightError
from app.procedure.ranging import RangePlan, member_ranges
from app.procedure.request import RequestError, RunIdentity, RunRequest
from app.records.run_folder import RunFolder
from app.records.run_start import BatchLink
from app.stand.config import StandConfig
from app.stand.fixture import AXES, Fixture, FixturePosition
from app.stand.simulated import reference_sensitivity_mv_per_ms2, triaxial_spec

if TYPE_CHECKING:
    from app.procedure import Listener, Procedure
    from app.procedure.service import BatchOutcome, PreparedRun, RunService

log = logging.getLogger(__name__)

TRIAXIAL_SIM_MODEL = "triaxial@"  # sim.fixture_stand's triaxial DUT: "triaxial@<orientation>"
#: A cross channel's predicted peak per the main axis's (fraction): the largest transverse
#: sensitivity a triaxial accelerometer's data sheet usually states (<= 5 %); the table's own
#: transverse motion (under 1 % of the axial on a stand fit for it) and the crosstalk are
#: within the range's headroom (app.procedure.ranging.PREDICTED_HEADROOM, 2.5x).
TRANSVERSE_BOUND = 0.05


class TriaxialRun(BatchRun):
    """A triaxial DUT's three channels in one orientation (a BatchRun whose first member is
    the channel along the exciter): each channel's batch link names the orientation and
    whether it is a cross channel, and each channel's input range is its own."""

    def __init__(
        self,
        batch_id: str,
        folder: Path,
        fixture: Fixture,
        members: list[Member],
        identity: RunIdentity,
        backend: Backend,
        orientation: str,
    ):
        super().__init__(batch_id, folder, fixture, members[0], members[1:], identity, backend)
        self.orientation = orientation

    def link(self, member: Member) -> BatchLink:
        """The channel's config.json "batch" object: the batch's, with the orientation and
        whether this channel is a cross one (stored, so a later analysis knows it)."""
        return dataclasses.replace(
            super().link(member), orientation=self.orientation, transverse=member.transverse
        )

    def member_ranges(self, procedure: Procedure, ranges: RangePlan) -> dict[str, float]:
        """Each channel's +-range (V): the smallest offered that holds its own predicted
        peak (app.procedure.ranging.member_ranges), the main axis's from the DUT's nominal
        sensitivity, a cross channel's from TRANSVERSE_BOUND of it; logged. Without a
        nominal every channel takes the run's DUT range."""
        nominal = self.lead.spec.nominal_mv_per_ms2
        predicted = {
            m.channel: None
            if nominal is None
            else nominal * (TRANSVERSE_BOUND if m.transverse else 1.0)
            for m in self.members
        }
        chosen = member_ranges(ranges, procedure.plan, predicted, procedure.stand.chain.dut_gain)
        for m in self.members:
            why = (
                f"its predicted transverse peak, {100 * TRANSVERSE_BOUND:g} % of the nominal"
                if m.transverse
                else "its DUT's nominal"
            )
            procedure.ctx.log(f"input range {m.channel}: +-{chosen[m.channel]:g} V ({why})")
        return {**chosen, "dut": chosen[self.lead.channel]}


def triaxial_position(config: StandConfig, choice: MemberChoice) -> FixturePosition:
    """The stand's triaxial position `choice` names (RequestError naming --dut otherwise)."""
    fixture = config.fixture
    where = f"--dut {choice.position}={choice.serial}"
    if fixture is None:
        raise RequestError(f"{where}: the stand file {config.source} has no [fixture] table")
    try:
        position = fixture.position(choice.position)
    except KeyError as exc:
        raise RequestError(f"{where}: {exc.args[0]}") from None
    if not position.axes:
        raise RequestError(
            f"{where} --orientation: position {position.name!r} is a single-axis position "
            "(physical); a triaxial DUT needs a position with axes = {{ x, y, z }}"
        )
    return position


def next_orientation(orientation: str) -> str | None:
    """The orientation after `orientation` (x -> y -> z), None after z."""
    i = AXES.index(orientation)
    return AXES[i + 1] if i + 1 < len(AXES) else None


def next_message(position: str, orientation: str) -> str:
    """What the operator does after the run in `orientation`."""
    after = next_orientation(orientation)
    if after is None:
        return (
            f"all three orientations of {position} measured: accelcal certificate --triaxial "
            "BATCH_X BATCH_Y BATCH_Z"
        )
    return f"next: mount {position} with its {after} axis along the exciter (--orientation {after})"


def open_triaxial(
    request: RunRequest,
    choice: MemberChoice,
    orientation: str,
    listener: Listener | None = None,
    *,
    config: StandConfig,
) -> OpenedBatch:
    """Open the triaxial DUT `choice` in `orientation` (x, y or z along the exciter) as
    app.procedure.batch.open_batch opens a batch (a face runs its procedure, closes the
    stand, then `end`): refused before anything moves (RequestError, PreflightError naming
    the option or key), else the stand open and its three channels' run folders and the
    orientation's batch folder made."""
    from app.procedure.run import prepare, request_plan, with_stand_plan

    if orientation not in AXES:
        raise RequestError(f"--orientation: must be x, y or z, got {orientation!r}")
    refuse_mode(request)
    position = triaxial_position(config, choice)
    fixture = config.fixture
    assert fixture is not None
    request = with_stand_plan(request, config.plan)
    frequencies = [float(f) for f in request_plan(request).frequencies_hz]
    if config.backend == Backend.SIM:  # the simulated triaxial sensor's own data sheet
        spec = triaxial_spec().with_options(
            serial=choice.serial,
            nominal_mv_per_ms2=request.nominal_mv_per_ms2,
            tolerance_percent=request.tolerance_percent,
        )
    else:
        spec = _member_spec(request, dataclasses.replace(choice, model=None), config.backend)
    problems = fixture.mass_problems({position.name: (spec.mass_g or 0.0) / 1000.0})
    if problems:
        raise PreflightError("; ".join(problems))
    refusal, warnings = position.limit_check(frequencies)
    if refusal is not None:
        raise PreflightError(refusal)
    table = config.reference.sensitivity_mv_per_ms2
    reference_mv = 0.0
    if table:
        reference_mv = float(np.median(table)) * config.reference.gain
    elif config.backend == Backend.SIM:
        reference_mv = reference_sensitivity_mv_per_ms2() * config.reference.gain
    own = spec.nominal_mv_per_ms2 or 1.0
    terms = position.budget(fixture.crosstalk_db, max(reference_mv, own) / own)  # one for all
    axes = [orientation, *(a for a in AXES if a != orientation)]  # the main axis first
    duts = {f"dut.{position.name}.{a}": f"{TRIAXIAL_SIM_MODEL}{orientation}" for a in axes}
    lead_request = dataclasses.replace(
        request,
        dut_id=choice.serial,
        dut_mass_g=1000 * fixture.mass_kg + (spec.mass_g or 0.0),
    )
    procedure, stand = prepare(
        lead_request,
        listener_for(listener, position.name),
        config=config,
        duts=duts,
        extra_budget=terms,
    )
    # the main axis's verdict against the sensor's data sheet (the request's is its --dut's)
    procedure.tolerances = spec.tolerances(procedure.plan.reference_frequency_hz)
    stated = procedure.identity.dut
    if stated is not None:  # not the catalogue model the stand's checks used: no such model
        procedure.identity = dataclasses.replace(
            procedure.identity, dut=dataclasses.replace(stated, catalogue=None)
        )
    try:
        batch_id, folder = new_batch_folder(Path(request.out), 3)
        members = [
            Member(
                position,
                choice.serial,
                None,  # the simulated sensor is sim/triaxial.py's, not a catalogue model
                spec,
                RunFolder.create(request.out, f"{choice.serial}-{orientation}{a}"),
                terms,
                warnings,
                axis=a,
                transverse=a != orientation,
            )
            for a in axes
        ]
        for member in members:
            member.folder.records_chain_head = request.records_chain_head
        run = TriaxialRun(
            batch_id, folder, fixture, members, procedure.identity, config.backend, orientation
        )
        procedure.folder = members[0].folder
        procedure.batch_link = run.link(members[0])
        procedure.batch = run
        for text in warnings:
            procedure.ctx.warn(text)
    except BaseException:
        stand.close()
        raise
    member_choices = tuple(
        MemberChoice(f"{position.name}.{a}", choice.serial, choice.model) for a in axes
    )
    log.info("triaxial %s orientation %s: batch %s", choice.serial, orientation, batch_id)
    return OpenedBatch(procedure, stand, run, member_choices)


def execute_triaxial(
    request: RunRequest,
    choice: MemberChoice,
    orientation: str,
    listener: Listener | None = None,
    *,
    config: StandConfig,
) -> BatchFinished:
    """Run the triaxial DUT `choice` in `orientation` (`open_triaxial`, the run with the
    signals handled on the main thread, `OpenedBatch.end`): its three channels' run folders
    and the orientation's batch folder written, whatever the end."""
    from app.procedure.run import _graceful_signals

    opened = open_triaxial(request, choice, orientation, listener, config=config)
    try:
        with _graceful_signals(opened.procedure):
            finished = opened.procedure.run()
    finally:
        opened.stand.close()
    return opened.end(finished, listener)


def run_triaxial(
    service: RunService,
    prepared: PreparedRun,
    choice: MemberChoice,
    orientation: str,
    listener: Listener | None = None,
) -> BatchOutcome:
    """`execute_triaxial` through the run service: each channel's outcome (indexed into the
    records when they are in use) and the worst exit status."""
    from app.procedure.outcome import ExitStatus
    from app.procedure.service import BatchOutcome

    finished = execute_triaxial(
        prepared.request, choice, orientation, listener, config=prepared.config
    )
    outcomes = tuple((m, service.finish(prepared, one)) for m, one in finished.members)
    status = max((o.exit_status for _, o in outcomes), default=ExitStatus.OK)
    return BatchOutcome(finished.batch_id, finished.folder, outcomes, status)
