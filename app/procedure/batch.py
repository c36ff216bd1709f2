"""Several DUTs in one run (issue 36): one excitation, every channel acquired, an estimate
per DUT.

The run is the single-DUT procedure on the first DUT (its channel "dut.<position>": the
equalisation and the plan's level hold at the reference as always, the live estimate is that
DUT's), with every other DUT's channel recorded beside it into its own run folder. When the
run ends, each other DUT is estimated from its own recording by the same estimator code
(app.procedure.analysis, the pair reference and dut.<position>), its budget the run's with
its own position's terms (stated relative motion, crosstalk) in place of the first's. Each
member is a complete run folder (config.json with its `batch` link, recording, results,
manifest, seal); the batch folder holds the all-channel recording and batch.json naming each
member's seal (app.records.batch).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from app.io.hdf5 import (
    Recording,
    RecordingError,
    RecordingWriter,
    read_recording,
    software_version,
)
from app.io.vocabulary import Backend, Mode, RunStatus
from app.procedure import Finished, Listener, Procedure
from app.procedure.batch_files import (
    copy_log,
    copy_marks,
    own_budget,
    stored_budget,
    write_batch_recording,
    write_member_truth,
)
from app.procedure.batch_skew import member_skews, skew_tolerance_s
from app.procedure.errors import PreflightError
from app.procedure.events import Event, PeriodEstimate
from app.procedure.ranging import RangePlan, member_ranges
from app.procedure.request import RequestError, RunIdentity, RunRequest
from app.records.batch import Batch, BatchMember, seal_batch
from app.records.run_folder import RunFolder, new_run_id
from app.records.run_record import DutIdentity
from app.records.run_start import CONFIG_NAME, BatchLink, BatchMemberLink, RunStart
from app.records.seal import SealError, named_seal
from app.stand.config import StandConfig
from app.stand.dut import DutSpec
from app.stand.fixture import Fixture, FixturePosition
from app.stand.simulated import catalogue_spec, reference_sensitivity_mv_per_ms2
from dsp.calibration import AnalysisError, ReferenceChain, Results
from dsp.spectral import Estimate
from dsp.uncertainty import Budget
from hardware.interfaces import DaqStatus

if TYPE_CHECKING:
    from app.stand.open import Stand

log = logging.getLogger(__name__)

MAX_DUTS = 8  # the simulated stand's DAQ inputs beside the reference and the drive


@dataclass(frozen=True)
class MemberChoice:
    """One DUT of a batch as the operator names it: position, serial, and on the simulated
    stand its catalogue model (None: the run's --dut)."""

    position: str
    serial: str
    model: str | None = None


@dataclass
class Member:
    """A DUT of a batch being run: where it is, what it is, its run folder."""

    position: FixturePosition
    serial: str
    model: str | None
    spec: DutSpec
    folder: RunFolder
    terms: Budget  # its position's type B components
    warnings: tuple[str, ...] = ()
    writer: RecordingWriter | None = None
    skew_s: float | None = None  # its channel's sampling delay (s), once the DAQ is configured
    axis: str | None = None  # a triaxial DUT's channel (x, y, z; app.procedure.triaxial)
    transverse: bool = False  # that channel is not along the exciter: its signal is small

    @property
    def channel(self) -> str:
        if self.axis is not None:
            return f"dut.{self.position.name}.{self.axis}"
        return self.position.channel


@dataclass(frozen=True)
class BatchFinished:
    """How a batch ended: its folder, and each member's Finished in the fixture's order."""

    batch_id: str
    folder: Path
    members: tuple[tuple[MemberChoice, Finished], ...]


def check_members(config: StandConfig, choices: Sequence[MemberChoice]) -> Fixture:
    """The stand's fixture, the choices checked against it (RequestError naming --dut: no
    fixture, an unknown position, a position or serial twice, more DUTs than positions or
    than the simulated DAQ's inputs, a triaxial position)."""
    fixture = config.fixture
    if fixture is None:
        raise RequestError(
            f"--dut POSITION=SERIAL: the stand file {config.source} has no [fixture] table"
        )
    if len(choices) > len(fixture.positions):
        raise RequestError(
            f"--dut: {len(choices)} DUTs for the fixture's {len(fixture.positions)} positions"
        )
    if config.backend == Backend.SIM and len(choices) > MAX_DUTS:
        raise RequestError(f"--dut: the simulated stand takes at most {MAX_DUTS} DUTs")
    positions: set[str] = set()
    serials: set[str] = set()
    for choice in choices:
        try:
            position = fixture.position(choice.position)
        except KeyError as exc:
            raise RequestError(f"--dut {choice.position}={choice.serial}: {exc.args[0]}") from None
        if position.axes:
            raise RequestError(
                f"--dut {choice.position}={choice.serial}: a triaxial position (three inputs); "
                "run it once per orientation with --orientation x|y|z"
            )
        if choice.position in positions:
            raise RequestError(f"--dut: position {choice.position!r} given twice")
        if choice.serial in serials:
            raise RequestError(f"--dut: serial {choice.serial!r} given twice")
        positions.add(choice.position)
        serials.add(choice.serial)
    return fixture


def _mass_kg(spec: DutSpec) -> float:
    return (spec.mass_g or 0.0) / 1000.0


def ordered(fixture: Fixture, choices: Sequence[MemberChoice]) -> list[MemberChoice]:
    """The choices in the fixture's order of positions (the first is the run's own DUT)."""
    rank = {p.name: i for i, p in enumerate(fixture.positions)}
    return sorted(choices, key=lambda c: rank[c.position])


def _member_spec(request: RunRequest, choice: MemberChoice, backend: Backend) -> DutSpec:
    """The DUT's specification: its catalogue model on the simulated stand (else the
    request's), with its serial and the request's nominal and tolerance over it."""
    if backend == Backend.SIM:
        base = catalogue_spec(choice.model or request.dut)
    else:
        base = request.dut_spec or DutSpec()
    return base.with_options(
        serial=choice.serial,
        nominal_mv_per_ms2=request.nominal_mv_per_ms2,
        tolerance_percent=request.tolerance_percent,
    )


def _crosstalk_ratio(specs: dict[str, DutSpec], channel: str, reference_v_per_ms2: float) -> float:
    """The largest other channel's voltage over this one's (nominal sensitivities; the
    reference's `reference_v_per_ms2` mV/(m/s^2) at its amplifier's output)."""
    own = specs[channel].nominal_mv_per_ms2 or 1.0
    others = [s.nominal_mv_per_ms2 or 1.0 for name, s in specs.items() if name != channel]
    return max([reference_v_per_ms2, *others]) / own


def plan_members(
    request: RunRequest,
    config: StandConfig,
    choices: Sequence[MemberChoice],
    frequencies_hz: Sequence[float],
    reference_mv_per_ms2: float,
) -> list[tuple[MemberChoice, DutSpec, Budget, tuple[str, ...]]]:
    """Each member's spec, its position's budget terms and its warnings, in the fixture's
    order. PreflightError naming the key when the DUTs and the fixture weigh more than the
    fixture's limits, or when a position's stated relative motion exceeds the ISO 16063-21
    limit at every line of the plan."""
    fixture = check_members(config, choices)
    members = ordered(fixture, choices)
    specs = {
        fixture.position(c.position).channel: _member_spec(request, c, config.backend)
        for c in members
    }
    masses = {c.position: _mass_kg(specs[fixture.position(c.position).channel]) for c in members}
    problems = fixture.mass_problems(masses)
    if problems:
        raise PreflightError("; ".join(problems))
    out: list[tuple[MemberChoice, DutSpec, Budget, tuple[str, ...]]] = []
    for choice in members:
        position = fixture.position(choice.position)
        refusal, warnings = position.limit_check(frequencies_hz)
        if refusal is not None:
            raise PreflightError(refusal)
        ratio = _crosstalk_ratio(specs, position.channel, reference_mv_per_ms2)
        terms = position.budget(fixture.crosstalk_db, ratio)
        out.append((choice, specs[position.channel], terms, warnings))
    return out


def member_budget(budget: Budget, lead: FixturePosition, terms: Budget) -> Budget:
    """`budget` (the run's, with the first DUT's position terms) with a member's own
    position terms in their place."""
    kept = tuple(c for c in budget.components if not lead.owns(c.name))
    return Budget((*kept, *terms.components))


class BatchRun:
    """The other members of a run of several DUTs: their configs, recordings, results and the
    batch folder (app.procedure.procedure.BatchHooks)."""

    def __init__(
        self,
        batch_id: str,
        folder: Path,
        fixture: Fixture,
        lead: Member,
        others: list[Member],
        identity: RunIdentity,
        backend: Backend,
    ):
        self.batch_id = batch_id
        self.backend = backend
        self.folder = folder
        self.fixture = fixture
        self.lead = lead
        self.others = others
        self.identity = identity
        self.started_utc = datetime.now(UTC).isoformat(timespec="seconds")
        # a member's recording as own_budget left it, by channel, until _results takes it
        self._budgeted: dict[str, Recording] = {}

    @property
    def members(self) -> list[Member]:
        return [self.lead, *self.others]

    def link(self, member: Member) -> BatchLink:
        """The member's config.json "batch" object."""
        return BatchLink(
            self.batch_id,
            member.position.name,
            member.channel,
            member.position.distance_mm,
            tuple(
                BatchMemberLink(m.position.name, m.channel, m.serial, m.folder.run_id)
                for m in self.members
            ),
        )

    def member_identity(self, member: Member) -> RunIdentity:
        """The run's identity with this member's DUT: its catalogue model (simulated stand),
        its serial, and the nominal the run states (the request's, as a single run's)."""
        stated = self.identity.dut.nominal_sensitivity_mv_per_ms2 if self.identity.dut else None
        dut = DutIdentity(
            member.model if self.backend == Backend.SIM else None, member.serial, stated
        )
        return dataclasses.replace(self.identity, dut=dut)

    def member_chain(self, procedure: Procedure, member: Member) -> ReferenceChain:
        """The run's reference chain with this member's own channel delay (its phase's skew
        correction; the run's when not known yet)."""
        chain = procedure.stand.chain
        if member.skew_s is None:
            return chain
        return dataclasses.replace(chain, skew_s=member.skew_s)

    # --- BatchHooks -----------------------------------------------------------------------

    def member_ranges(self, procedure: Procedure, ranges: RangePlan) -> dict[str, float]:
        """Each member's DUT channel's +-range (V) from its own nominal sensitivity's
        predicted peak (app.procedure.ranging.member_ranges), as a single run picks its DUT's
        ("dut": the first member's, the run's own phases read it); logged."""
        chosen = member_ranges(
            ranges,
            procedure.plan,
            {m.channel: m.spec.nominal_mv_per_ms2 for m in self.members},
            procedure.stand.chain.dut_gain,
        )
        for channel, value in chosen.items():
            procedure.ctx.log(f"input range {channel}: +-{value:g} V (its own DUT's nominal)")
        return {**chosen, "dut": chosen[self.lead.channel]}

    def configured(self, procedure: Procedure, status: DaqStatus) -> None:
        """Each member's own channel delay (app.procedure.batch_skew: the driver's, checked
        against the stand file's; PreflightError naming the position), logged; the run's own
        chain (its first DUT's) takes the first member's."""
        config = procedure.stand.config
        skews = member_skews(
            [m.position for m in self.members],
            status.skews_s,
            config.skew_s,
            skew_tolerance_s(config),
        )
        for member in self.members:
            member.skew_s = skews[member.channel].skew_s
            procedure.ctx.log(skews[member.channel].line())
        procedure.use_chain(self.member_chain(procedure, self.lead))

    def config_stored(self, start: RunStart) -> None:
        """Each other member's config.json (its identity and batch link) and stand.toml."""
        stand_text = self.lead.folder.path / "stand.toml"
        for member in self.others:
            own = dataclasses.replace(
                start,
                identity=self.member_identity(member).to_dict(),
                batch=self.link(member),
            )
            member.folder.write_text(CONFIG_NAME, own.to_json())
            if stand_text.exists():
                member.folder.write_text("stand.toml", stand_text.read_text(encoding="utf-8"))

    def open_writers(self, procedure: Procedure) -> None:
        """Each other member's recording, beside the run's own: the same plan, chain and
        ranges, its own position's budget terms and (simulated stand) its own truth."""
        io = procedure.io
        stand = procedure.stand
        for member in self.others:
            writer = RecordingWriter(
                member.folder.recording,
                procedure.plan,
                self.member_chain(procedure, member),
                member_budget(stand.budget, self.lead.position, member.terms),
                with_drive=True,
                ranges_v={**io.ranges, "dut": io.ranges[member.channel]},
                cmc=stand.config.cmc,
            )
            member.writer = writer
            io.member_writers[member.channel] = writer
            truth_of = getattr(stand.daq, "truth_of", None)
            if truth_of is not None:
                write_member_truth(procedure, writer, truth_of(member.channel), member.model)

    # --- the end --------------------------------------------------------------------------

    def finish(
        self, procedure: Procedure, finished: Finished, listener: Listener | None
    ) -> list[Finished]:
        """Every other member's results (its own recording, the run's estimator), its run
        folder finished and sealed; then the batch folder. Each member's Finished."""
        out = []
        lead_recording = self.lead.folder.recording
        for member in self.others:
            results = None
            status, reason = finished.status, finished.abort_reason
            if status == RunStatus.COMPLETE:
                try:
                    copy_marks(lead_recording, member.folder.recording)
                    # as stored, its own budget in it: the analysis need not read it again
                    self._budgeted[member.channel] = own_budget(procedure, member.folder.recording)
                    estimate, results = self._results(procedure, member)
                except (RecordingError, AnalysisError, ValueError) as exc:  # this DUT only
                    log.warning("batch %s: %s not analysed: %s", self.batch_id, member.channel, exc)
                    status, reason = RunStatus.ABORTED, f"{member.channel}: not analysed: {exc}"
                if results is not None and listener is not None:
                    listener(
                        PeriodEstimate(
                            procedure.io.periods_read, estimate, results, member.position.name
                        )
                    )
            budget = stored_budget(member.folder.recording)  # its own, as its results use
            record = dataclasses.replace(
                finished.record,
                run_id=member.folder.run_id,
                status=status,
                abort_reason=reason,
                dut=self.member_identity(member).dut,
                budget=tuple(budget.to_list()) if budget is not None else finished.record.budget,
                reference_chain=self.member_chain(procedure, member).to_dict(),
            )
            copy_log(self.lead.folder.path, member.folder)
            record = member.folder.finish(record, results)
            out.append(Finished(status, reason, results, record))
        self._seal(finished.status)
        return out

    def _results(self, procedure: Procedure, member: Member) -> tuple[Estimate, Results]:
        """(estimate, results) of a member's recording (own_budget's, else read from its file)
        with the run's estimator and rules, the verdict against its own specification, its
        position's warnings added."""
        recording = self._budgeted.pop(member.channel, None)
        if recording is None:
            recording = read_recording(member.folder.recording)
        from app.procedure.analysis import analyze

        settings = procedure.settings
        analysis = analyze(
            recording,
            estimator=str(settings.estimator),
            probability=settings.probability,
            rule=str(settings.rule),
            # the characteristic's tolerance as the lead's results have it (the DCC's limits
            # and per-point conformity): the same setting for every DUT of the run
            tolerance_percent=settings.tolerance_percent,
            tolerances=member.spec.tolerances(procedure.plan.reference_frequency_hz),
            transverse=member.transverse,
            resonance=settings.resonance,  # --resonance: every member's, as the first's
        )
        results = analysis.results
        if member.warnings:
            results = dataclasses.replace(results, warnings=(*results.warnings, *member.warnings))
        return analysis.estimate, results

    def _seal(self, status: RunStatus) -> None:
        """The batch folder: the all-channel recording, batch.json naming each member's seal,
        manifest and seal."""
        write_batch_recording(
            self.folder / "recording.h5",
            (self.lead.channel, self.lead.folder.recording),
            [(m.channel, m.folder.recording) for m in self.others],
        )
        members = []
        for m in self.members:
            try:
                seal = named_seal(m.folder.path) or ""
            except SealError as exc:  # a member whose seal does not check: named without it
                log.warning("batch %s: member %s seal not read: %s", self.batch_id, m.serial, exc)
                seal = ""
            members.append(BatchMember(m.position.name, m.channel, m.serial, m.folder.run_id, seal))
        batch = Batch(
            self.batch_id, self.fixture.name, self.started_utc, str(status), tuple(members)
        )
        seal_batch(self.folder, batch, software_version())


def listener_for(listener: Listener | None, position: str) -> Listener | None:
    """The run's listener, its live estimates marked as the first DUT's (`position`)."""
    if listener is None:
        return None

    def tell(event: Event) -> None:
        if isinstance(event, PeriodEstimate) and not event.member:
            event = dataclasses.replace(event, member=position)
        listener(event)

    return tell


def new_batch_folder(out: Path, count: int) -> tuple[str, Path]:
    """A new batch folder under the runs root `out`: its id and path."""
    out.mkdir(parents=True, exist_ok=True)
    batch_id = new_run_id(f"batch-{count}")
    path = out / batch_id
    path.mkdir()
    return batch_id, path


def refuse_mode(request: RunRequest) -> None:
    """A batch runs the multisine (RequestError naming --mode for the stepped sine)."""
    if request.mode != Mode.MULTISINE:
        raise RequestError("--mode: several DUTs in one run take the multisine only")


@dataclass
class OpenedBatch:
    """A batch opened and not run yet (`open_batch`): the first DUT's procedure (to `run()`,
    on any thread: a face's worker), the stand (to close after the run), and the rest of the
    batch for `end`."""

    procedure: Procedure
    stand: Stand
    run: BatchRun
    choices: tuple[MemberChoice, ...]  # in the fixture's order: the first is the procedure's

    def end(self, finished: Finished, listener: Listener | None = None) -> BatchFinished:
        """The run has ended (`finished`, the stand closed): every other member estimated,
        its folder finished and sealed, then the batch folder (BatchRun.finish)."""
        others = self.run.finish(self.procedure, finished, listener)
        return BatchFinished(
            self.run.batch_id,
            self.run.folder,
            tuple(zip(self.choices, (finished, *others), strict=True)),
        )


def open_batch(
    request: RunRequest,
    choices: Sequence[MemberChoice],
    listener: Listener | None = None,
    *,
    config: StandConfig,
) -> OpenedBatch:
    """Open the DUTs `choices` on the stand's fixture for one excitation (`request`: the run's
    settings; its DUT the simulated default model): refused before anything moves
    (RequestError, PreflightError naming the option or key) as a single run is, else the
    stand open and every member's run folder and the batch folder made."""
    from app.procedure.run import prepare, request_plan, with_stand_plan

    refuse_mode(request)
    fixture = check_members(config, choices)
    request = with_stand_plan(request, config.plan)
    frequencies = [float(f) for f in request_plan(request).frequencies_hz]
    # the reference channel's volts per m/s^2 (the crosstalk term's ratio): its stated
    # table, else the simulated reference's nominal; a real stand without a table: left out
    table = config.reference.sensitivity_mv_per_ms2
    reference_mv = 0.0
    if table:
        reference_mv = float(np.median(table)) * config.reference.gain
    elif config.backend == Backend.SIM:
        reference_mv = reference_sensitivity_mv_per_ms2() * config.reference.gain
    planned = plan_members(request, config, choices, frequencies, reference_mv)
    first_choice, _, first_terms, first_warnings = planned[0]
    total_g = 1000 * fixture.mass_kg + sum((spec.mass_g or 0.0) for _, spec, _, _ in planned)
    lead_request = dataclasses.replace(
        request,
        dut=first_choice.model or request.dut,
        dut_id=first_choice.serial,
        dut_mass_g=total_g,  # what the exciter carries: the stored response's mass class
    )
    duts = {
        fixture.position(c.position).channel: (c.model or request.dut) for c, _, _, _ in planned
    }
    lead_position = fixture.position(first_choice.position)
    procedure, stand = prepare(
        lead_request,
        listener_for(listener, lead_position.name),
        config=config,
        duts=duts,
        extra_budget=first_terms,
    )
    try:
        batch_id, folder = new_batch_folder(Path(request.out), len(planned))
        members = []
        for choice, spec, terms, warnings in planned:
            members.append(
                Member(
                    fixture.position(choice.position),
                    choice.serial,
                    (choice.model or request.dut) if config.backend == Backend.SIM else None,
                    spec,
                    RunFolder.create(request.out, choice.serial),
                    terms,
                    warnings,
                )
            )
        for member in members:
            member.folder.records_chain_head = request.records_chain_head
        run = BatchRun(
            batch_id, folder, fixture, members[0], members[1:], procedure.identity, config.backend
        )
        procedure.folder = members[0].folder
        procedure.batch_link = run.link(members[0])
        procedure.batch = run
        for text in first_warnings:
            procedure.ctx.warn(text)
    except BaseException:
        stand.close()
        raise
    return OpenedBatch(procedure, stand, run, tuple(c for c, _, _, _ in planned))


def execute_batch(
    request: RunRequest,
    choices: Sequence[MemberChoice],
    listener: Listener | None = None,
    *,
    config: StandConfig,
) -> BatchFinished:
    """Run the DUTs `choices` on the stand's fixture in one excitation (`open_batch`, then the
    run with the signals handled on the main thread, then `OpenedBatch.end`): every member's
    run folder and the batch folder written, whatever the end."""
    from app.procedure.run import _graceful_signals

    opened = open_batch(request, choices, listener, config=config)
    try:
        with _graceful_signals(opened.procedure):
            finished = opened.procedure.run()
    finally:
        opened.stand.close()
    return opened.end(finished, listener)
