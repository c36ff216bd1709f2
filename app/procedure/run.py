"""One calibration run from a request (app.procedure.request): the code path shared by the CLI
and the GUI, from the stand opened to the run folder written."""

from __future__ import annotations

import dataclasses
import signal
import threading
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from app.io.vocabulary import Backend
from app.procedure import Finished, Listener, Procedure
from app.procedure.capacity import check_capacity
from app.procedure.phase_store import stored_phases
from app.procedure.planning import PlanRequest, build_plan
from app.procedure.reference import reference_budget, table_phases
from app.procedure.request import (
    DutChoice,
    RequestError,
    RunIdentity,
    RunRequest,
    build_request,
    check_request,
)
from app.records.run_folder import RunFolder
from app.stand import config as stand_config
from app.stand.config import StandConfig, StandPlan
from app.stand.exciters import with_exciter_budget
from app.stand.open import open_stand
from app.stand.response import ResponseStore
from app.stand.simulated import EXCITERS, exciter_stroke_m, plan_preset_for
from dsp.multisine import PRESETS, Plan, preset_plan
from dsp.profiles import Profile
from dsp.uncertainty import Budget

if TYPE_CHECKING:
    from app.records.db.references import ReferenceTable

__all__ = [
    "DutChoice",
    "RunIdentity",
    "RunRequest",
    "build_request",
    "check_request",
    "execute",
    "plan_request",
    "prepare",
    "request_plan",
    "response_store",
    "start",
    "with_reference",
]


def prepare(
    request: RunRequest,
    listener: Listener | None = None,
    *,
    config: StandConfig | None = None,
    duts: Mapping[str, str] | None = None,
    extra_budget: Budget | None = None,
) -> tuple[Procedure, Any]:
    """Open the stand, build the plan and check it before anything moves (PreflightError,
    ConfigError, PlanError on refusal; nothing is created then). `config`: the stand file as
    the run service loaded it (None: loaded here from `request.stand_file`). `duts`: several
    DUTs on the stand file's fixture (input "dut.<position>" -> simulated catalogue DUT;
    app.procedure.batch), the first the run's own; `extra_budget`: components added to the
    run's budget (its position's terms). Returns the procedure and the stand (to close)."""
    check_request(request)
    if config is None:
        config = stand_config.load(request.stand_file)
    # the stand file, with the reference standard's table from the records when they hold it
    config = with_exciter(with_reference(config, request.reference), request.exciter)
    request = with_stand_plan(request, config.plan)
    plan = request_plan(  # a custom plan is clipped and checked by the stroke before it opens
        request, config.limits.displacement_peak_to_peak_m if request.custom_plan else None
    )
    chain, budget = None, None
    if request.reference is not None:  # the records' table, not the simulator's own
        chain = config.reference_chain()
        budget = reference_budget(config.budget, request.reference)  # and its uncertainty
    if extra_budget is not None:
        budget = Budget((*(budget or config.budget).components, *extra_budget.components))
    if duts:  # every DUT's input on the fixture, [daq.dut]'s settings: one acquisition
        config = with_dut_inputs(config, list(duts))
    stand = open_stand(
        config,
        dut=request.dut,
        seed=request.seed,
        paced=request.paced,
        faults=request.faults,
        dut_mass_g=request.dut_mass_g,
        exciter=request.exciter,
        chain=chain,
        budget=budget,
        driven_hum=request.sim_hum,
        duts=duts,
        systematic=request.sim_systematic,
    )
    try:
        procedure = Procedure(
            stand,
            plan,
            request.settings(config.backend, plan.period_s),
            None,
            listener,
            identity=request.identity(config.backend),
            response_store=response_store(request),
            tolerances=request.tolerances(config.backend, plan.reference_frequency_hz),
        )
        procedure.preflight()
    except BaseException:
        stand.close()
        raise
    return procedure, stand


def with_dut_inputs(config: StandConfig, channels: list[str]) -> StandConfig:
    """The stand with the fixture's DUT inputs `channels` ("dut.<position>") in place of its
    "dut" input (reference first, drive last)."""
    assert config.fixture is not None
    dut = next(c for c in config.inputs if c.name == "dut")
    positions = [name.split(".")[1] for name in channels]
    fixture_inputs = {c.name: c for c in config.fixture.inputs(dut, positions)}
    inputs = [c for c in config.inputs if c.name == "reference"]
    inputs += [fixture_inputs[name] for name in channels]
    inputs += [c for c in config.inputs if c.name == "drive"]
    return dataclasses.replace(config, inputs=tuple(inputs))


def with_reference(config: StandConfig, reference: ReferenceTable | None) -> StandConfig:
    """The stand configuration with the reference standard's certificate and table from the
    records when the run takes them from there (`reference`), else `config` itself."""
    if reference is None:
        return config
    return config.with_reference_certificate(
        reference.certificate_number,
        reference.calibration_date.isoformat(),
        reference.frequencies_hz,
        reference.sensitivity_mv_per_ms2,
        table_phases(reference),
        due_date=reference.due_date.isoformat(),
        dcc=(
            ("", "", "")
            if reference.dcc is None
            else (reference.dcc.unique_identifier, reference.dcc.laboratory, reference.dcc.sha256)
        ),
    )


def response_store(request: RunRequest) -> ResponseStore | None:
    """The stored-response store the run reads and refreshes, or None (--fresh-response)."""
    if not request.stored_response:
        return None
    if request.response_store is not None:
        return ResponseStore(request.response_store)
    return ResponseStore.default()


def plan_request(request: RunRequest, level_ms2: float | None = None) -> PlanRequest:
    """What the request's plan is: the preset asked for, else the DUT's, with any custom lines
    (Hz), rate, period, profile and corner; at `level_ms2` (None: the request's level)."""
    spec_preset = request.dut_spec.preset if request.dut_spec is not None else None
    return PlanRequest(
        preset=request.preset or spec_preset or plan_preset_for(request.dut),
        frequencies_hz=request.frequencies_hz,
        sample_rate_hz=request.sample_rate_hz,
        period_samples=request.period_samples,
        level_ms2=request.level_ms2 if level_ms2 is None else level_ms2,
        reference_frequency_hz=request.reference_frequency_hz,
        profile=request.profile,
        corner_hz=request.corner_hz,
        shift_mains_lines=not request.exact_mains_bins,
    )


def request_plan(request: RunRequest, stroke_peak_to_peak_m: float | None = None) -> Plan:
    """The request's plan (`plan_request`; app.procedure.planning), clipped and checked by the
    stroke (m), with the request's phases (rad) when it carries them for these lines."""
    wanted = plan_request(request)
    phases = request.phases_rad
    custom = (
        request.frequencies_hz,
        request.sample_rate_hz,
        request.period_samples,
        request.reference_frequency_hz,
        request.corner_hz,
    )
    if (
        all(v is None for v in custom)
        and phases is None
        and request.profile == Profile.ACCELERATION
        and stroke_peak_to_peak_m is None
    ):
        preset = PRESETS[wanted.preset]
        check_capacity(  # the plan is small; a run of many periods may not be
            preset.period_samples,
            preset.sample_rate_hz,
            periods=request.periods,
            top_bin=round(preset.max_frequency_hz * preset.period_samples / preset.sample_rate_hz),
        )
        return preset_plan(
            wanted.preset,
            level_ms2=request.level_ms2,
            shift_mains_lines=wanted.shift_mains_lines,
            optimiser=stored_phases,
        )
    return build_plan(
        wanted,
        stroke_peak_to_peak_m=stroke_peak_to_peak_m,
        phases_rad=phases,
        periods=request.periods,
    )


def with_stand_plan(request: RunRequest, plan: StandPlan) -> RunRequest:
    """The request with the stand file's [plan] where the request states nothing (its own
    options win; the profile when the request keeps the default, acceleration)."""
    changes: dict[str, Any] = {}
    for name in ("frequencies_hz", "sample_rate_hz", "period_samples", "reference_frequency_hz"):
        if getattr(request, name) is None and getattr(plan, name) is not None:
            changes[name] = getattr(plan, name)
    if request.profile == Profile.ACCELERATION and plan.profile is not None:
        changes["profile"] = plan.profile
    if request.corner_hz is None and plan.corner_hz is not None:
        changes["corner_hz"] = plan.corner_hz
    return dataclasses.replace(request, **changes) if changes else request


def with_exciter(config: StandConfig, exciter: str | None) -> StandConfig:
    """The stand configuration with the simulated exciter `exciter`'s stroke as its travel
    limit and its own budget terms (app.stand.exciters; RequestError: unknown,
    or not a simulated stand)."""
    if exciter is None:
        return config
    if config.backend != Backend.SIM:
        raise RequestError("--exciter: only the simulated stand has an exciter catalogue")
    if exciter not in EXCITERS:
        raise RequestError(f"--exciter: {exciter!r} is not one of {', '.join(EXCITERS)}")
    limits = dataclasses.replace(
        config.limits, displacement_peak_to_peak_m=exciter_stroke_m(exciter)
    )
    return dataclasses.replace(with_exciter_budget(config, exciter), limits=limits)


def start(
    request: RunRequest, listener: Listener | None = None, *, config: StandConfig | None = None
) -> tuple[Procedure, Any]:
    """Prepare a run and give it its folder: the procedure (to `run()` on any thread, to
    `abort()` or `emergency_stop()` from another) and the stand (to close afterwards)."""
    procedure, stand = prepare(request, listener, config=config)
    try:
        procedure.folder = RunFolder.create(request.out, request.dut_id or request.dut)
        procedure.folder.records_chain_head = request.records_chain_head
    except BaseException:
        stand.close()
        raise
    return procedure, stand


def execute(
    request: RunRequest, listener: Listener | None = None, *, config: StandConfig | None = None
) -> Finished:
    """Run a calibration to its end (complete or aborted) in a new run folder.

    SIGTERM, SIGHUP (terminal closed) and a first Ctrl-C ask for a fade-out; a second Ctrl-C
    stops at once. The drive ends at 0 V in every case (the procedure's own `finally`).
    """
    procedure, stand = prepare(request, listener, config=config)
    try:
        procedure.folder = RunFolder.create(request.out, request.dut_id or request.dut)
        procedure.folder.records_chain_head = request.records_chain_head
        with _graceful_signals(procedure):
            return procedure.run()
    finally:
        stand.close()


class _graceful_signals:
    """Route SIGTERM, SIGHUP and SIGINT to `procedure.abort` while a run is going (main thread
    only)."""

    def __init__(self, procedure: Procedure):
        self.procedure = procedure
        self.previous: dict[int, Any] = {}

    def __enter__(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        interrupted = {"count": 0}

        def on_term(signum: int, frame: Any) -> None:
            name = "SIGHUP" if signum == getattr(signal, "SIGHUP", None) else "SIGTERM"
            self.procedure.abort(f"terminated ({name})")

        def on_int(signum: int, frame: Any) -> None:
            interrupted["count"] += 1
            if interrupted["count"] > 1:
                raise KeyboardInterrupt
            self.procedure.abort("interrupted (Ctrl-C)")

        handlers = [(signal.SIGTERM, on_term), (signal.SIGINT, on_int)]
        if hasattr(signal, "SIGHUP"):  # POSIX: the terminal was closed
            handlers.append((signal.SIGHUP, on_term))
        for signum, handler in handlers:
            self.previous[signum] = signal.signal(signum, handler)

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self.previous.items():
            signal.signal(signum, handler)
